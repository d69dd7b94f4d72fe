//! `pneuflex tune`: gains that minimise the worst case, over a list of environments, of a weighted sum of a
//! run's metrics, found by CMA-ES (the `cmaes` crate) in a box, with a budget and a seed.
//!
//! The objective of a candidate is `J = max over environments e of J_e`, with
//! `J_e = Σ_terms weight · |metric|` of the tuned run in environment e (default terms: every sine window's RMS
//! force error (1 /N) and phase lag (0.1 /deg), every event window's recovery overshoot (0.05 /%)), and
//! `J_e = ∞` when the run diverged or an event window did not settle. For the optimiser's ranking an infinite
//! candidate is ordered after every finite one, by the number of environments that failed, then by the finite
//! part that could be measured: CMA-ES needs an order, not a value.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use cmaes::{CMAESOptions, DVector};
use pneuflex_scene::any_scene::MetricColumn;
use pneuflex_scene::{AnyScene, WindowKind};
use rayon::prelude::*;

use crate::engine::SweepError;
use crate::key::{Base, KeyPath, Value};
use crate::points::{Points, SetArg, Spec};

/// The largest magnitude of a `--free` box's bound: beyond any gain, stiffness or pressure of a scene.
pub const MAX_FREE_BOUND: f64 = 1e12;

/// A `--free KEY=[LO,HI]`: a key the optimiser moves within a box.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeArg {
    /// The key.
    pub key: KeyPath,
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
    /// Searched in the logarithm (`KEY=log[LO,HI]`, both > 0): for a gain whose scale is unknown.
    pub log: bool,
    /// An integer key (a count, such as `substeps`): searched over the integers of the box, written as an
    /// integer. Found by [`Tuner::new`] from what the scene accepts.
    pub integer: bool,
}

impl FreeArg {
    /// Parses `KEY=[LO,HI]` (or `KEY=LO:HI`), or `KEY=log[LO,HI]` to search in the logarithm.
    pub fn parse(arg: &str) -> Result<FreeArg, SweepError> {
        let bad = |m: &str| SweepError::Other(format!("--free {arg}: {m}"));
        let (key, range) = arg
            .split_once('=')
            .ok_or_else(|| bad("expected KEY=[LO,HI]"))?;
        let key = KeyPath::parse(key).map_err(|e| bad(&e.message))?;
        let r = range.trim();
        let (log, r) = match r.strip_prefix("log") {
            Some(rest) => (true, rest.trim_start_matches(':')),
            None => (false, r),
        };
        let inner = r
            .strip_prefix('[')
            .and_then(|r| r.strip_suffix(']'))
            .unwrap_or(r);
        let parts: Vec<&str> = inner.split([',', ':']).collect();
        if parts.len() != 2 {
            return Err(bad("expected KEY=[LO,HI]"));
        }
        let num = |s: &str| -> Result<f64, SweepError> {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(&format!("`{s}` is not a finite number")))
        };
        let (lo, hi) = (num(parts[0])?, num(parts[1])?);
        // CMA-ES steps a share of the box: a box of 1e300 puts every candidate where no run stays finite,
        // and the tune ends with an infinite J and a "best" value no one could use.
        if let Some(v) = [lo, hi].into_iter().find(|v| v.abs() > MAX_FREE_BOUND) {
            return Err(bad(&format!(
                "a bound of {v:e}: no setting of a rig is beyond {MAX_FREE_BOUND:e} in magnitude; give the range \
                 the key can take (KEY=log[LO,HI] when its scale is unknown by decades)"
            )));
        }
        if hi <= lo {
            return Err(bad(&format!("needs LO < HI, got {lo} and {hi}")));
        }
        if log && lo <= 0.0 {
            return Err(bad(&format!("a log box needs LO > 0, got {lo}")));
        }
        Ok(FreeArg {
            key,
            lo,
            hi,
            log,
            integer: false,
        })
    }
}

/// One term of the objective: `weight · |WINDOW.METRIC|`.
#[derive(Clone, Debug, PartialEq)]
pub struct Term {
    /// Metric window name.
    pub window: String,
    /// Metric name (summary.json's).
    pub metric: String,
    /// Weight, per unit of the metric.
    pub weight: f64,
}

impl Term {
    /// Parses `WINDOW.METRIC=WEIGHT`.
    pub fn parse(arg: &str) -> Result<Term, SweepError> {
        let bad = |m: &str| SweepError::Other(format!("--term {arg}: {m}"));
        let (name, w) = arg
            .split_once('=')
            .ok_or_else(|| bad("expected WINDOW.METRIC=WEIGHT"))?;
        let (window, metric) = name
            .trim()
            .split_once('.')
            .ok_or_else(|| bad("expected WINDOW.METRIC=WEIGHT"))?;
        let weight: f64 = w
            .trim()
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite() && *x >= 0.0)
            .ok_or_else(|| bad("the weight must be a number >= 0"))?;
        Ok(Term {
            window: window.into(),
            metric: metric.into(),
            weight,
        })
    }

    /// `WINDOW.METRIC`.
    pub fn name(&self) -> String {
        format!("{}.{}", self.window, self.metric)
    }
}

/// The default terms for a scene: every sine window's RMS error (1 /N) and phase lag (0.1 /deg), every
/// event window's recovery overshoot (0.05 /%); in a mechanism, every window's RMS error of every actuator
/// (1 /N).
pub fn default_terms(scene: &AnyScene) -> Vec<Term> {
    let scene = match scene {
        AnyScene::One(s) => s,
        AnyScene::Mechanism(m) => {
            return m
                .metrics
                .iter()
                .flat_map(|w| {
                    m.actuators.iter().map(move |a| Term {
                        window: w.name.clone(),
                        metric: format!("{}.rms_force_error_n", a.name),
                        weight: 1.0,
                    })
                })
                .collect();
        }
    };
    let mut out = Vec::new();
    for w in &scene.metrics {
        let mut add = |m: &str, weight: f64| {
            out.push(Term {
                window: w.name.clone(),
                metric: m.into(),
                weight,
            })
        };
        match w.kind {
            WindowKind::Sine => {
                add("rms_force_error_n", 1.0);
                add("phase_lag_deg", 0.1);
            }
            WindowKind::Event => add("recovery_overshoot_pct", 0.05),
            WindowKind::Step => {}
        }
    }
    out
}

/// How the search runs (the run, the terms, the keys and the environments are the [`Tuner`]'s).
#[derive(Clone, Debug)]
pub struct TuneOptions {
    /// Largest number of candidates evaluated (each over every environment).
    pub budget: usize,
    /// Seed of CMA-ES.
    pub seed: u64,
    /// CMA-ES population (default 4 + 3 ln n).
    pub population: Option<usize>,
    /// Initial step, as a fraction of each box (default 0.3).
    pub sigma0: f64,
    /// Worker threads (0: one per core).
    pub threads: usize,
    /// Largest number of scene runs (candidates × environments) the search may take (`--max-runs`).
    pub max_runs: u64,
}

impl Default for TuneOptions {
    fn default() -> Self {
        Self {
            budget: 200,
            seed: 0,
            population: None,
            sigma0: 0.3,
            threads: 0,
            max_runs: crate::points::DEFAULT_MAX_POINTS,
        }
    }
}

/// Checks a tune's size from its arguments alone, before any scene is built: the environments' grid of
/// `over` (refused past `--max-runs` before it is expanded) and the options for `n_free` free keys over it.
pub fn check_plan(n_free: usize, over: &[SetArg], opts: &TuneOptions) -> Result<(), SweepError> {
    if let Some(s) = over.iter().find(|s| matches!(s.spec, Spec::Sample { .. })) {
        return Err(SweepError::Other(format!(
            "--over {}={}: a list or a range (the environments), not a sample",
            s.key.text, s.spec_text
        )));
    }
    let environments = if over.is_empty() {
        1
    } else {
        crate::points::points(over, None, 0, opts.max_runs, "--max-runs")?.len()
    };
    opts.check(n_free, environments)
}

impl TuneOptions {
    /// CMA-ES's population for `n` free keys: the one given, else 4 + 3 ln n (the cmaes crate's default).
    pub fn population_for(&self, n: usize) -> usize {
        self.population
            .unwrap_or(4 + (3.0 * (n.max(1) as f64).ln()).floor() as usize)
    }

    /// Checks the options against a problem of `n` free keys over `environments`, before anything runs:
    /// each refusal names the option and the value that would work.
    pub fn check(&self, n: usize, environments: usize) -> Result<(), SweepError> {
        if self.threads > crate::engine::MAX_THREADS {
            return Err(SweepError::Other(format!(
                "--threads {}: at most {} (0: one per core)",
                self.threads,
                crate::engine::MAX_THREADS
            )));
        }
        if !(self.sigma0.is_finite() && self.sigma0 > 0.0 && self.sigma0 <= 1.0) {
            return Err(SweepError::Other(format!(
                "--sigma0: the initial step is a fraction of each box, in (0, 1]; got {}",
                self.sigma0
            )));
        }
        let pop = self.population_for(n);
        if let Some(p) = self.population
            && p < 2
        {
            return Err(SweepError::Other(format!(
                "--population: CMA-ES needs at least 2 candidates per generation, got {p}"
            )));
        }
        if let Some(p) = self.population
            && p > self.budget
        {
            return Err(SweepError::Other(format!(
                "--population {p}: more candidates in one generation than --budget {} allows; give a \
                 population of at most the budget (default 4 + 3 ln n)",
                self.budget
            )));
        }
        if self.budget < pop {
            return Err(SweepError::Other(format!(
                "--budget {}: below one generation of {pop} candidates (the population{}); give --budget {pop} \
                 or more",
                self.budget,
                if self.population.is_some() {
                    ", --population"
                } else {
                    " for this many free keys"
                }
            )));
        }
        let runs = (self.budget as u64).checked_mul(environments as u64);
        let max = self.max_runs.min(crate::points::HARD_MAX_POINTS);
        if runs.is_none_or(|r| r > max) {
            return Err(SweepError::Other(format!(
                "--budget {} over {environments} environment(s): {} scene runs, more than the limit of {max}; \
                 lower --budget or the --over grid, or raise --max-runs (up to {})",
                self.budget,
                runs.map_or("more than 2^64".into(), |r| r.to_string()),
                crate::points::HARD_MAX_POINTS
            )));
        }
        Ok(())
    }
}

/// One environment's evaluation of one run: J_e and its terms.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvEval {
    /// J_e (∞ when diverged or not settled).
    pub j: f64,
    /// Each term's metric value (before weighting; None when not measured).
    pub terms: Vec<Option<f64>>,
    /// `ok`, `not_settled: ...` or `diverged: ...`.
    pub status: String,
}

/// A candidate's evaluation.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// The free keys' values.
    pub x: Vec<f64>,
    /// The worst case over the environments (∞ when any is).
    pub j: f64,
    /// The value the optimiser ranks (finite).
    pub rank: f64,
    /// Per environment.
    pub envs: Vec<EnvEval>,
}

/// One evaluated candidate of the search.
#[derive(Clone, Debug, PartialEq)]
pub struct HistoryRow {
    /// Generation (from 1).
    pub generation: usize,
    /// The evaluation.
    pub eval: Evaluation,
}

/// A tuning problem: the scene, the free keys, the environments, the objective.
#[derive(Debug)]
pub struct Tuner {
    /// The scene file.
    pub scene_path: PathBuf,
    /// The scene as written, of either kind.
    pub base_scene: AnyScene,
    /// The free keys and their boxes.
    pub free: Vec<FreeArg>,
    /// The environments (the `--over` keys' grid).
    pub envs: Points,
    /// The `--over` arguments as written.
    pub over_specs: Vec<String>,
    /// The tuned run's index in the scene.
    pub run: usize,
    /// The objective's terms.
    pub terms: Vec<Term>,
    /// Each term's metric column, in the order of `terms`.
    term_columns: Vec<MetricColumn>,
    /// The free keys' values in the scene as written (the box's middle where the file has none), clamped
    /// into the box: where the search starts.
    pub initial: Vec<f64>,
    /// The free keys' numbers as the file writes them (None: the file leaves the key to its default).
    pub as_written: Vec<Option<f64>>,
    /// What one run may cost (`--max-steps`, `--max-trace-mb`): a candidate beyond is refused, and so is a box
    /// whose corner is.
    pub limits: pneuflex_scene::Limits,
    base: Base,
}

fn fold(y: f64) -> f64 {
    // A triangle wave: R -> [0, 1], continuous, the identity on [0, 1] (reflection at the bounds).
    let t = y.rem_euclid(2.0);
    if t > 1.0 { 2.0 - t } else { t }
}

impl Tuner {
    /// Reads the scene, the free keys, the environments and the terms, and checks the scene at the box's
    /// corners and at the initial values in every environment before anything runs.
    /// `max_runs` bounds the environments (`--over`'s grid) before they are expanded.
    pub fn new(
        scene_path: &Path,
        free: Vec<FreeArg>,
        over: &[SetArg],
        run: Option<&str>,
        terms: Vec<Term>,
        max_runs: u64,
    ) -> Result<Tuner, SweepError> {
        Self::with_limits(
            scene_path,
            free,
            over,
            run,
            terms,
            max_runs,
            pneuflex_scene::Limits::default(),
        )
    }

    /// [`Tuner::new`] with the limits of one run (`--max-steps`, `--max-trace-mb`).
    pub fn with_limits(
        scene_path: &Path,
        free: Vec<FreeArg>,
        over: &[SetArg],
        run: Option<&str>,
        terms: Vec<Term>,
        max_runs: u64,
        limits: pneuflex_scene::Limits,
    ) -> Result<Tuner, SweepError> {
        let base_scene = AnyScene::load(scene_path)?;
        let base = Base::load(scene_path).map_err(|e| SweepError::Other(e.to_string()))?;
        let mut keys: Vec<(&str, &KeyPath)> = free.iter().map(|f| ("--free", &f.key)).collect();
        keys.extend(over.iter().map(|s| ("--over", &s.key)));
        base.check_distinct(&keys).map_err(|e| {
            let option = if free.iter().any(|f| f.key.text == e.key) {
                "--free"
            } else {
                "--over"
            };
            SweepError::key(&base, option, e)
        })?;
        if free.is_empty() {
            return Err(SweepError::Other(
                "nothing to tune: give at least one --free KEY=[LO,HI]".into(),
            ));
        }
        // The tuned values are written into a copy of the scene: a sheet's value has nowhere to go.
        if let Some(f) = free.iter().find(|f| !f.key.in_scene()) {
            return Err(SweepError::Other(format!(
                "--free {}: an actuator-sheet value; the tuned values are written into a copy of the scene, so \
                 tune scene keys (copy the sheet and point the scene at it to tune the sheet's values), or \
                 sweep the sheet key with `pneuflex sweep --set`",
                f.key.text
            )));
        }
        for s in over {
            if matches!(s.spec, Spec::Sample { .. }) {
                return Err(SweepError::Other(format!(
                    "--over {}={}: a list or a range (the environments), not a sample",
                    s.key.text, s.spec_text
                )));
            }
        }
        let envs = if over.is_empty() {
            Points::none()
        } else {
            crate::points::points(over, None, 0, max_runs, "--max-runs")?
        };
        let run = match run {
            Some(name) => base_scene.run_index(name)?,
            None => base_scene
                .runs()
                .iter()
                .position(|r| r.controller == pneuflex_scene::ControllerKind::Adaptive)
                .unwrap_or(0),
        };
        let terms = if terms.is_empty() {
            default_terms(&base_scene)
        } else {
            terms
        };
        if terms.is_empty() {
            return Err(SweepError::Other(
                "the scene has no sine or event window: give the objective's terms with --term WINDOW.METRIC=WEIGHT"
                    .into(),
            ));
        }
        let mut term_columns = Vec::with_capacity(terms.len());
        for t in &terms {
            if let AnyScene::One(scene) = &base_scene {
                let Some(w) = scene.metrics.iter().find(|w| w.name == t.window) else {
                    let names: Vec<&str> = scene.metrics.iter().map(|w| w.name.as_str()).collect();
                    return Err(SweepError::Other(format!(
                        "--term {}: no metric window {:?}, the scene has {names:?}",
                        t.name(),
                        t.window
                    )));
                };
                let known = crate::engine::window_metrics(w.kind);
                if !known.contains(&t.metric.as_str()) {
                    return Err(SweepError::Other(format!(
                        "--term {}: a {:?} window has {known:?}",
                        t.name(),
                        w.kind
                    )));
                }
            }
            term_columns.push(
                base_scene
                    .metric_column(&t.name())
                    .map_err(|e| SweepError::Other(format!("--term {}: {e}", t.name())))?,
            );
        }
        let as_written: Vec<Option<f64>> = free.iter().map(|f| base.number(&f.key)).collect();
        let initial = free
            .iter()
            .zip(&as_written)
            .map(|(f, w)| w.unwrap_or(0.5 * (f.lo + f.hi)).clamp(f.lo, f.hi))
            .collect();
        let mut tuner = Tuner {
            scene_path: scene_path.to_path_buf(),
            base_scene,
            free,
            envs,
            over_specs: over
                .iter()
                .map(|s| format!("{}={}", s.key.text, s.spec_text))
                .collect(),
            run,
            terms,
            term_columns,
            initial,
            as_written,
            limits,
            base,
        };
        tuner.find_integer_keys()?;
        let lo: Vec<f64> = tuner.free.iter().map(|f| f.lo).collect();
        let hi: Vec<f64> = tuner.free.iter().map(|f| f.hi).collect();
        // A corner the scene refuses is named as the --free box's, the option to change.
        for (x, which) in [
            (&tuner.initial, "start"),
            (&lo, "lower corner"),
            (&hi, "upper corner"),
        ] {
            for e in 0..tuner.envs.len() {
                tuner.scene(x, e, true).map_err(|err| match err {
                    SweepError::Point { point, error } => SweepError::Point {
                        point: format!("the --free box's {which}: {point}"),
                        error,
                    },
                    other => other,
                })?;
            }
        }
        Ok(tuner)
    }

    /// Marks the free keys the scene reads as integers (a fractional value is refused where an integral
    /// one in the box loads), and narrows their boxes to the integers inside: such a key is searched over
    /// integers and written as one, so the tuned scene loads.
    fn find_integer_keys(&mut self) -> Result<(), SweepError> {
        for k in 0..self.free.len() {
            let f = &self.free[k];
            let (lo, hi) = (f.lo.ceil(), f.hi.floor());
            // A value with a fraction, inside the box, at the other keys' initial values.
            let mut x = self.initial.clone();
            x[k] = f.lo + 0.382 * (f.hi - f.lo);
            if x[k].fract() == 0.0 {
                x[k] += 0.25 * (f.hi - f.lo).min(1.0);
            }
            let fractional_refused = self.scene(&x, 0, true).is_err();
            x[k] = x[k].round().clamp(lo, hi.max(lo));
            if !(fractional_refused && self.scene(&x, 0, true).is_ok()) {
                continue;
            }
            let f = &mut self.free[k];
            if hi - lo < 1.0 {
                return Err(SweepError::Other(format!(
                    "--free {}=[{}, {}]: an integer key (the scene takes whole numbers only); the box holds {} \
                     integer(s): give a box with at least two",
                    f.key.text,
                    f.lo,
                    f.hi,
                    (hi - lo + 1.0).max(0.0)
                )));
            }
            if f.log {
                return Err(SweepError::Other(format!(
                    "--free {}: an integer key is searched over its integers, not in the logarithm: give \
                     KEY=[LO,HI]",
                    f.key.text
                )));
            }
            f.integer = true;
            f.lo = lo;
            f.hi = hi;
            self.initial[k] = self.initial[k].round().clamp(lo, hi);
        }
        Ok(())
    }

    /// `key = value, ...` of environment `e`.
    pub fn describe_env(&self, e: usize) -> String {
        if self.envs.keys.is_empty() {
            return "the scene's environment".into();
        }
        self.envs
            .keys
            .iter()
            .zip(&self.envs.row(e))
            .map(|(k, v)| format!("{} = {v}", k.text))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The scene with the free keys at `x` in environment `e`; `only_run` keeps just the tuned run.
    pub fn scene(&self, x: &[f64], e: usize, only_run: bool) -> Result<AnyScene, SweepError> {
        self.scene_with(Some(x), e, only_run)
    }

    /// [`Tuner::scene`], or with `x` None the scene as written (its own values at the free keys).
    fn scene_with(
        &self,
        x: Option<&[f64]>,
        e: usize,
        only_run: bool,
    ) -> Result<AnyScene, SweepError> {
        let xv = x.map(|x| self.values(x)).unwrap_or_default();
        let env = self.envs.row(e);
        let mut edits: Vec<(&KeyPath, &Value)> =
            self.free.iter().map(|f| &f.key).zip(&xv).collect();
        edits.extend(self.envs.keys.iter().zip(&env));
        let edited = self
            .base
            .edit(&edits)
            .map_err(|err| SweepError::key(&self.base, "--free/--over", err))?;
        let point = || {
            let kv: Vec<String> = match x {
                Some(x) => self
                    .free
                    .iter()
                    .zip(x)
                    .map(|(f, v)| format!("{} = {v}", f.key.text))
                    .collect(),
                None => vec!["the scene's own values".into()],
            };
            format!("{} in {}", kv.join(", "), self.describe_env(e))
        };
        let mut scene =
            AnyScene::from_toml_str(&edited.scene_text, &self.scene_path, &self.base.base_dir)
                .map_err(|err| SweepError::Point {
                    point: point(),
                    error: Box::new(err),
                })?;
        scene.set_text(self.base.scene.text.clone());
        if !edited.overlay.is_empty() {
            crate::engine::with_overlay(&mut scene, edited.overlay, &point())?;
        }
        if only_run {
            scene.keep_only_run(self.run);
        }
        scene
            .check_budget(&self.limits)
            .map_err(|err| SweepError::Point {
                point: point(),
                error: Box::new(err),
            })?;
        Ok(scene)
    }

    /// The scene keys that name files, with each file's path as seen from `dir`.
    fn named_files(&self, dir: &Path) -> Vec<(KeyPath, Value)> {
        self.base_scene
            .named_files()
            .into_iter()
            .filter_map(|(key, p)| {
                let rel = pneuflex_files::path::relative_to(&p, dir);
                Some((
                    KeyPath::parse(&key).ok()?,
                    Value::Str(rel.to_string_lossy().replace('\\', "/")),
                ))
            })
            .collect()
    }

    /// The values written at the free keys for `x`: integers for integer keys.
    fn values(&self, x: &[f64]) -> Vec<Value> {
        self.free
            .iter()
            .zip(x)
            .map(|(f, v)| {
                if f.integer {
                    Value::Int(v.round() as i64)
                } else {
                    Value::Float(*v)
                }
            })
            .collect()
    }

    /// J_e and its terms for one run's result.
    fn env_eval(&self, r: &pneuflex_scene::RunResult) -> EnvEval {
        let terms = self.base_scene.values(r, &self.term_columns);
        let unsettled = self.base_scene.unsettled(r);
        let finite: f64 = self
            .terms
            .iter()
            .zip(&terms)
            .map(|(t, v)| match v {
                Some(v) if v.is_finite() => t.weight * v.abs(),
                _ => 0.0,
            })
            .sum();
        let (j, status) = match (&r.diverged, unsettled.is_empty()) {
            (Some(why), _) => (f64::INFINITY, format!("diverged: {why}")),
            (None, false) => (
                f64::INFINITY,
                format!("not_settled: {}", unsettled.join("; ")),
            ),
            (None, true) => {
                let missing = terms.iter().any(|v| v.is_none_or(|v| !v.is_finite()));
                if missing {
                    (f64::INFINITY, "a term could not be measured".into())
                } else {
                    (finite, "ok".into())
                }
            }
        };
        EnvEval { j, terms, status }
    }

    /// Evaluates the tuned run at `x` in every environment (in parallel).
    pub fn evaluate(&self, x: &[f64]) -> Evaluation {
        let envs: Vec<EnvEval> = (0..self.envs.len())
            .into_par_iter()
            .map(|e| {
                let fail = |why: String| EnvEval {
                    j: f64::INFINITY,
                    terms: vec![None; self.terms.len()],
                    status: format!("error: {why}"),
                };
                let scene = match self.scene(x, e, true) {
                    Ok(s) => s,
                    Err(err) => return fail(err.to_string()),
                };
                match scene.run(&mut |_| {}) {
                    Ok(r) => self.env_eval(&r[0]),
                    Err(err) => fail(err.to_string()),
                }
            })
            .collect();
        let j = envs.iter().map(|e| e.j).fold(f64::NEG_INFINITY, f64::max);
        let failed = envs.iter().filter(|e| !e.j.is_finite()).count();
        let rank = if failed == 0 {
            j
        } else {
            // After every finite candidate: by the number of failed environments, then by what was measured.
            let part: f64 = envs
                .iter()
                .map(|e| {
                    self.terms
                        .iter()
                        .zip(&e.terms)
                        .map(|(t, v)| match v {
                            Some(v) if v.is_finite() => t.weight * v.abs(),
                            _ => 0.0,
                        })
                        .sum::<f64>()
                })
                .fold(0.0, f64::max);
            1e12 * failed as f64 + part.min(1e11)
        };
        Evaluation {
            x: x.to_vec(),
            j,
            rank,
            envs,
        }
    }

    /// Every run of the scene at `x` in every environment: `[env][run]` evaluations (for the report).
    /// `x` None: the scene as written (the start a tuned scene must not be worse than).
    pub fn evaluate_all_runs(&self, x: Option<&[f64]>) -> Vec<Vec<EnvEval>> {
        (0..self.envs.len())
            .into_par_iter()
            .map(|e| {
                let n = self.base_scene.runs().len();
                let fail = |why: String| {
                    vec![
                        EnvEval {
                            j: f64::INFINITY,
                            terms: vec![None; self.terms.len()],
                            status: format!("error: {why}"),
                        };
                        n
                    ]
                };
                let scene = match self.scene_with(x, e, false) {
                    Ok(s) => s,
                    Err(err) => return fail(err.to_string()),
                };
                match scene.run(&mut |_| {}) {
                    Ok(r) => r.iter().map(|r| self.env_eval(r)).collect(),
                    Err(err) => fail(err.to_string()),
                }
            })
            .collect()
    }

    /// Box coordinates in [0, 1] of the free keys' values.
    fn to_unit(&self, x: &[f64]) -> Vec<f64> {
        self.free
            .iter()
            .zip(x)
            .map(|(f, v)| {
                if f.integer {
                    (v - f.lo + 0.5) / (f.hi - f.lo + 1.0)
                } else if f.log {
                    (v.ln() - f.lo.ln()) / (f.hi.ln() - f.lo.ln())
                } else {
                    (v - f.lo) / (f.hi - f.lo)
                }
            })
            .collect()
    }

    /// The free keys' values of an optimiser point (folded into the box).
    pub fn from_search(&self, y: &[f64]) -> Vec<f64> {
        self.free
            .iter()
            .zip(y)
            .map(|(f, v)| {
                if f.integer {
                    // Each integer owns an equal share of the box: [lo - 0.5, hi + 0.5] folded, rounded.
                    let span = f.hi - f.lo + 1.0;
                    (f.lo - 0.5 + fold(*v) * span).round().clamp(f.lo, f.hi)
                } else if f.log {
                    (f.lo.ln() + fold(*v) * (f.hi.ln() - f.lo.ln())).exp()
                } else {
                    f.lo + fold(*v) * (f.hi - f.lo)
                }
            })
            .collect()
    }

    /// Runs CMA-ES: every candidate evaluated (in parallel) over every environment; `tick` after each
    /// candidate. Returns every evaluation in generation order (within a generation, ordered by rank and
    /// values: the same whatever the thread count).
    ///
    /// `stop` (a signal's number, 0 while none came) ends the search at the end of the generation under
    /// way: candidates not yet started are not evaluated, and the history holds those that were.
    pub fn search(
        &self,
        opts: &TuneOptions,
        stop: Option<&AtomicUsize>,
        tick: &(dyn Fn() + Sync),
    ) -> Result<Vec<HistoryRow>, SweepError> {
        self.search_with(opts, stop, tick, &|x| self.evaluate(x))
    }

    /// [`Tuner::search`] with the candidates evaluated by `evaluate` (e.g. on a Ray cluster: it must return
    /// what [`Tuner::evaluate`] would).
    pub fn search_with(
        &self,
        opts: &TuneOptions,
        stop: Option<&AtomicUsize>,
        tick: &(dyn Fn() + Sync),
        evaluate: &(dyn Fn(&[f64]) -> Evaluation + Sync),
    ) -> Result<Vec<HistoryRow>, SweepError> {
        opts.check(self.free.len(), self.envs.len())?;
        let stopped = || stop.is_some_and(|s| s.load(Ordering::Relaxed) != 0);
        let pool = crate::engine::thread_pool(opts.threads)?;
        let generation_rows: Mutex<Vec<Evaluation>> = Mutex::new(Vec::new());
        let objective = |y: &DVector<f64>| -> f64 {
            if stopped() {
                return f64::MAX;
            }
            let x = self.from_search(y.as_slice());
            let ev = evaluate(&x);
            let rank = ev.rank;
            generation_rows
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(ev);
            tick();
            rank
        };
        let mut options = CMAESOptions::new(self.to_unit(&self.initial), opts.sigma0)
            .max_function_evals(opts.budget)
            .seed(opts.seed)
            // A flat objective (every candidate failing alike) must not end the search before the budget.
            .tol_fun(0.0)
            .tol_fun_hist(0.0);
        if let Some(p) = opts.population {
            options = options.population_size(p);
        }
        let mut cma = options
            .build(objective)
            .map_err(|e| SweepError::Other(format!("CMA-ES: {e:?}")))?;
        let mut history = Vec::new();
        let mut generation = 0;
        loop {
            generation += 1;
            let done = pool.install(|| cma.next_parallel());
            let mut rows =
                std::mem::take(&mut *generation_rows.lock().unwrap_or_else(|e| e.into_inner()));
            rows.sort_by(|a, b| {
                a.rank.total_cmp(&b.rank).then_with(|| {
                    a.x.iter()
                        .zip(&b.x)
                        .map(|(p, q)| p.total_cmp(q))
                        .find(|o| o.is_ne())
                        .unwrap_or(std::cmp::Ordering::Equal)
                })
            });
            history.extend(rows.into_iter().map(|eval| HistoryRow { generation, eval }));
            if done.is_some() || history.len() >= opts.budget || stopped() {
                break;
            }
        }
        Ok(history)
    }

    /// The scene's text with the free keys at `x` (the environments as the file has them) and a comment at
    /// the top saying how they were found, to be written into the folder `dir`: the files the scene names
    /// (its actuator sheet, its URDF) are named relative to `dir`, so the copy loads where it is written.
    pub fn tuned_text(&self, x: &[f64], comment: &str, dir: &Path) -> Result<String, SweepError> {
        let xv = self.values(x);
        let mut edits: Vec<(&KeyPath, &Value)> =
            self.free.iter().map(|f| &f.key).zip(&xv).collect();
        let named = self.named_files(dir);
        edits.extend(named.iter().map(|(k, v)| (k, v)));
        if self.free.iter().any(|f| !f.key.in_scene()) {
            return Err(SweepError::Other(
                "a tuned actuator-sheet value cannot be written into the scene: tune scene keys, or copy the sheet"
                    .into(),
            ));
        }
        let edited = self
            .base
            .edit(&edits)
            .map_err(|e| SweepError::key(&self.base, "--free", e))?;
        let mut head = String::new();
        for line in comment.lines() {
            head.push_str("# ");
            head.push_str(line);
            head.push('\n');
        }
        Ok(head + &edited.scene_text)
    }
}

impl Evaluation {
    /// A text form that reads back exactly ([`Evaluation::decode`]): numbers as their shortest round-trip
    /// text (`inf` included), one line per environment. For evaluations made elsewhere (a Ray worker).
    pub fn encode(&self) -> String {
        let num = |x: f64| format!("{x}");
        let mut s = format!(
            "{}\t{}\t{}\n",
            self.x.iter().map(|v| num(*v)).collect::<Vec<_>>().join(","),
            num(self.j),
            num(self.rank)
        );
        for e in &self.envs {
            let terms: Vec<String> = e.terms.iter().map(|t| t.map_or("-".into(), num)).collect();
            s.push_str(&format!(
                "{}\t{}\t{}\n",
                num(e.j),
                terms.join(","),
                e.status.replace(['\t', '\n'], " ")
            ));
        }
        s
    }

    /// Reads [`Evaluation::encode`]'s text.
    pub fn decode(text: &str) -> Option<Evaluation> {
        let mut lines = text.lines();
        let head: Vec<&str> = lines.next()?.split('\t').collect();
        let nums = |s: &str| -> Option<Vec<f64>> {
            if s.is_empty() {
                return Some(Vec::new());
            }
            s.split(',').map(|v| v.parse().ok()).collect()
        };
        let (x, j, rank) = (
            nums(head.first()?)?,
            head.get(1)?.parse().ok()?,
            head.get(2)?.parse().ok()?,
        );
        let mut envs = Vec::new();
        for line in lines {
            let f: Vec<&str> = line.splitn(3, '\t').collect();
            let terms = if f.get(1)?.is_empty() {
                Vec::new()
            } else {
                f[1].split(',')
                    .map(|t| {
                        if t == "-" {
                            Some(None)
                        } else {
                            t.parse().ok().map(Some)
                        }
                    })
                    .collect::<Option<Vec<_>>>()?
            };
            envs.push(EnvEval {
                j: f.first()?.parse().ok()?,
                terms,
                status: f.get(2)?.to_string(),
            });
        }
        Some(Evaluation { x, j, rank, envs })
    }
}

/// Four significant digits (the tuned scene's values: readable, and the report evaluates them as written).
pub fn round4(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    format!("{x:.3e}").parse().unwrap_or(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_beyond_any_setting_is_refused_by_free() {
        for arg in [
            "k=[0,1e300]",
            "k=[-1e300,1e300]",
            "k=log[1e-3,1e13]",
            "k=[-2e12,0]",
        ] {
            let e = FreeArg::parse(arg).unwrap_err().to_string();
            assert!(
                e.contains("--free") && e.contains(arg) && e.contains("1e12"),
                "{e}"
            );
        }
        assert!(FreeArg::parse("k=[0,1e12]").is_ok());
    }
}
