//! Structure selection (issue 26): which effects the model needs to explain the logs. Each candidate
//! structure is the sheet with one effect switched on at a modest start (leaks, wall heat, a polytropic
//! chamber process, another friction law, a pressure-dependent seal, spool travel) and that effect's keys freed beside the user's; each is fitted
//! to the same logs. The choice is the lowest BIC on the fit rows, with the residuals measured in units of
//! each channel's noise floor (the model check's), among the structures whose held-out residual is not worse
//! than the sheet's own: an effect that only fits the noise pays its keys' ln n and loses.

use std::path::Path;

use pneuflex_pneumatics::ActuatorSheet;

use crate::IdentifyError;
use crate::params::Key;
use crate::request::{Identified, Request, identify_stoppable};

/// A sheet edit that switches an effect on: a key and its start (from the sheet's model), or a word of the
/// actuator sheet (`mechanics.friction = "lugre"`).
#[derive(Clone, Copy, Debug)]
enum Edit {
    /// A key at a start computed from the sheet's model (the valve's C, the seal's F_c, ...).
    Value(Key, fn(&pneuflex_pneumatics::OneDofModel) -> f64),
    /// A word or number of the actuator sheet's `[mechanics]` table, or its removal (None).
    Mechanics(&'static str, Option<Word>),
}

/// A TOML scalar of an [`Edit::Mechanics`].
#[derive(Clone, Copy, Debug)]
enum Word {
    Text(&'static str),
    Number(f64),
}

/// One candidate structure.
#[derive(Clone, Copy, Debug)]
pub struct Structure {
    /// Its name in the report (`leakage`, ...; `as_given` for the sheet itself).
    pub name: &'static str,
    /// What the structure adds, in words.
    pub adds: &'static str,
    edits: &'static [Edit],
    /// The keys freed beside the user's.
    pub keys: &'static [Key],
}

fn valve_c(m: &pneuflex_pneumatics::OneDofModel) -> f64 {
    m.actuator.valve.orifice.sonic_conductance_m3_per_s_pa
}
fn coulomb(m: &pneuflex_pneumatics::OneDofModel) -> f64 {
    m.mechanics.friction.coulomb_n()
}

/// The structures `identify --select` compares, the sheet as given first.
pub const STRUCTURES: [Structure; 8] = [
    Structure {
        name: "as_given",
        adds: "nothing: the sheet's own model",
        edits: &[],
        keys: &[],
    },
    Structure {
        name: "leakage",
        adds: "leaks across the piston and from each chamber to atmosphere (ISO 6358, C from 1 % of the valve's)",
        edits: &[
            Edit::Value(Key::LeakConductance(0), |m| 0.01 * valve_c(m)),
            Edit::Value(Key::LeakConductance(1), |m| 0.01 * valve_c(m)),
            Edit::Value(Key::LeakConductance(2), |m| 0.01 * valve_c(m)),
        ],
        keys: &[
            Key::LeakConductance(0),
            Key::LeakConductance(1),
            Key::LeakConductance(2),
        ],
    },
    Structure {
        name: "heat_transfer",
        adds: "wall heat transfer (Newton cooling, h from 20 W/(m^2 K))",
        edits: &[Edit::Value(Key::WallHeat, |_| 20.0)],
        keys: &[Key::WallHeat],
    },
    Structure {
        name: "polytropic",
        adds: "a polytropic chamber process (the exponent n free, from 1.25: between isothermal 1 and the sheet's)",
        edits: &[Edit::Value(Key::PolytropicExponent, |_| 1.25)],
        keys: &[Key::PolytropicExponent],
    },
    Structure {
        name: "stick_slip",
        adds: "Karnopp stick-slip friction with a Stribeck drop (F_s from 1.5 F_c)",
        edits: &[
            Edit::Mechanics("friction", Some(Word::Text("stick_slip"))),
            Edit::Mechanics("smooth_velocity_m_per_s", None),
            Edit::Value(Key::Static, |m| 1.5 * coulomb(m)),
            Edit::Mechanics("stribeck_velocity_m_per_s", Some(Word::Number(0.005))),
            Edit::Mechanics("stick_velocity_m_per_s", Some(Word::Number(1e-4))),
        ],
        keys: &[Key::Static],
    },
    Structure {
        name: "lugre",
        adds: "LuGre dynamic friction (F_s from 1.5 F_c, sigma0 from 1e4 N/m)",
        edits: &[
            Edit::Mechanics("friction", Some(Word::Text("lugre"))),
            Edit::Mechanics("smooth_velocity_m_per_s", None),
            Edit::Value(Key::Static, |m| 1.5 * coulomb(m)),
            Edit::Mechanics("stribeck_velocity_m_per_s", Some(Word::Number(0.005))),
            Edit::Value(Key::BristleStiffness, |_| 1e4),
            Edit::Value(Key::BristleDamping, |_| 100.0),
        ],
        keys: &[Key::Static, Key::BristleStiffness],
    },
    Structure {
        name: "seal_pressure",
        adds: "a Coulomb friction that rises with |p_a - p_b| (from 2e-6 N/Pa)",
        edits: &[Edit::Value(Key::CoulombPressure, |_| 2e-6)],
        keys: &[Key::CoulombPressure],
    },
    Structure {
        name: "valve_dynamics",
        adds: "first-order spool travel of the on/off valve (from 0.5 ms)",
        edits: &[Edit::Value(Key::SpoolTimeConstant, |_| 5e-4)],
        keys: &[Key::SpoolTimeConstant],
    },
];

pub use crate::report::{Candidate, Selection};

/// The criterion, as the report states it.
pub const CRITERION: &str = "lowest BIC = n ln(mean (residual / noise floor)^2) + k ln n on the fit rows (n = rows x 3 \
     channels, k = free keys), among the structures whose effect is significant (a key's 95 % interval excludes \
     its absence) and whose held-out (residual / floor)^2 is at most 1.05 x the sheet's own";

/// A held-out residual this much worse than the sheet's own disqualifies a structure (overfitted).
const HELD_OUT_SLACK: f64 = 1.05;

/// Mean squared residual over floor^2 on the fit rows and on the held-out rows, from the model check's
/// per-channel figures.
fn normalised(id: &Identified) -> (f64, f64, usize) {
    let mc = &id.report.model_check;
    let fit: Vec<f64> = mc
        .channels
        .iter()
        .map(|c| (c.rms_fit / c.floor).powi(2))
        .collect();
    let val: Vec<f64> = mc
        .channels
        .iter()
        .zip(&id.report.fit.rms_validation)
        .map(|(c, v)| (v / c.floor).powi(2))
        .collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    (mean(&fit), mean(&val), mc.rows * mc.channels.len())
}

/// Whether one of the structure's keys is told from the effect's absence by its 95 % interval (for the
/// exponent, the sheet's own value `n0`). Another friction law has no "absent" value (LuGre's bristles act
/// at any F_s): it is judged by the BIC and the held-out rows alone.
fn effect_seen(s: &Structure, id: &Identified, n0: f64) -> bool {
    if s.edits
        .iter()
        .any(|e| matches!(e, Edit::Mechanics("friction", _)))
    {
        return true;
    }
    let estimate = |k: Key| {
        (id.keys.iter().zip(&id.report.fit.estimates))
            .find(|(q, _)| **q == k)
            .map(|(_, e)| e)
    };
    let f_c = estimate(Key::Coulomb).map_or_else(|| coulomb(&id.model), |e| e.value);
    s.keys.iter().any(|&k| {
        let Some(e) = estimate(k) else { return false };
        match k {
            Key::Static => e.ci95[0] > f_c,
            // The bristles have no "absent" value: LuGre is judged by its break-away force.
            Key::BristleStiffness | Key::BristleDamping => false,
            Key::PolytropicExponent => e.ci95[1] < n0 || e.ci95[0] > n0,
            _ => e.ci95[0] > 0.0,
        }
    })
}

/// Writes the sheet set of `structure` (the sheet of `req` with its edits, and `warm`: the user's keys at
/// the sheet-as-given fit's values) into `dir`; Err(reason) when the sheet has the effect already (one of the
/// structure's keys is free or set).
fn structure_sheet(
    req: &Request,
    s: &Structure,
    warm: &[(Key, f64)],
    scale: f64,
    dir: &Path,
) -> Result<Result<std::path::PathBuf, String>, IdentifyError> {
    let sheet = ActuatorSheet::load(&req.actuator)?;
    let model = sheet.model();
    let mut offsets = Default::default();
    // The starts of the effect's keys follow the warm values (F_s from the fitted F_c).
    let mut warmed = model;
    for &(k, v) in warm {
        k.set(&mut warmed, &mut offsets, v);
    }
    for k in s.keys {
        if req
            .free
            .iter()
            .any(|f| f.split(',').any(|f| f.trim() == k.name()))
        {
            return Ok(Err(format!("{} is free already", k.name())));
        }
        // An absent effect reads NaN (leaks, wall heat, the seal term) or 0 (spool travel); F_s and the
        // exponent are always there.
        let v = k.get(&model, &offsets);
        if v.is_finite() && v != 0.0 && !matches!(k, Key::Static | Key::PolytropicExponent) {
            return Ok(Err(format!("the sheet has {} already", k.name())));
        }
    }
    // With wall heat the energy balance takes n as the heat-capacity ratio (docs/pneumatics.md): an exponent
    // fitted beside it would count the heat twice.
    if s.keys.contains(&Key::PolytropicExponent) && model.effects.wall_heat.is_some() {
        return Ok(Err(
            "the sheet has wall heat transfer, whose balance takes n as the heat-capacity ratio"
                .into(),
        ));
    }
    if s.keys.contains(&Key::SpoolTimeConstant)
        && !matches!(
            model.actuator.valve.kind,
            pneuflex_pneumatics::ValveKind::OnOffPwm { .. }
        )
    {
        return Ok(Err(
            "the valve is proportional: no on/off spool to move".into()
        ));
    }
    if s.keys.contains(&Key::Static)
        && !matches!(
            model.mechanics.friction,
            pneuflex_pneumatics::Friction::Smooth { .. }
        )
    {
        return Ok(Err("the sheet's friction law is not the smooth one".into()));
    }
    std::fs::create_dir_all(dir).map_err(|e| IdentifyError::Output {
        file: dir.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut values: Vec<(Key, f64)> = warm.to_vec();
    // A key `warm` holds (a screening fit's value) starts there, not at the edit's start.
    let warmed_key = |k: &Key| warm.iter().any(|(w, _)| w == k);
    values.extend(s.edits.iter().filter_map(|e| match e {
        Edit::Value(k, _) if warmed_key(k) => None,
        // `scale` shrinks the effect's start (not F_s, which must stay above F_c; for the exponent, its
        // departure from the sheet's).
        Edit::Value(Key::Static, start) => Some((Key::Static, start(&warmed))),
        Edit::Value(Key::PolytropicExponent, start) => {
            let n0 = model.actuator.gas.polytropic_exponent;
            Some((Key::PolytropicExponent, n0 - scale * (n0 - start(&warmed))))
        }
        Edit::Value(k, start) => Some((*k, scale * start(&warmed))),
        Edit::Mechanics(..) => None,
    }));
    let words: Vec<(&str, Option<toml_edit::Value>)> = s
        .edits
        .iter()
        .filter_map(|e| match *e {
            Edit::Mechanics(k, w) => Some((
                k,
                w.map(|w| match w {
                    Word::Text(t) => toml_edit::Value::from(t),
                    Word::Number(x) => toml_edit::Value::from(x),
                }),
            )),
            Edit::Value(..) => None,
        })
        .collect();
    let header = format!(
        "Structure `{}` of `pneuflex identify --select`: {}, started from {}",
        s.name,
        s.adds,
        req.actuator.display()
    );
    crate::sheet::write_sheets_with(&sheet, &values, &words, dir, &header).map(Ok)
}

/// A screening fit's figures (see [`select`]).
struct Screened {
    /// Every free key's value reached (the user's and the structure's).
    values: Vec<(Key, f64)>,
    /// Mean (residual / floor)^2 on the fit rows and on the held-out rows, over all of them.
    fit: f64,
    validation: f64,
    bic: f64,
    seconds: f64,
}

/// LM's residual evaluations of a screening fit: at most this many times (free keys + 1) (each LM
/// iteration adds a Jacobian of keys + 1 replays).
const SCREEN_PATIENCE: usize = 1;
/// A screening fit also stops once a step changes the cost or the scaled keys by less than this, relative.
const SCREEN_TOLERANCE: f64 = 1e-5;
/// A structure is fitted in full while its screening BIC is below the best accepted full fit's plus n ln of
/// this (2 % on the mean (residual / floor)^2): the full fit reweights the channels by its own residuals,
/// which moved the screened figures by 0.2-0.4 % on the measured logs (docs/identification.md), either way.
const SCREEN_MARGIN: f64 = 1.02;

/// Fits every structure of `structures` to the logs of `req` (their sheets written into `work`, one folder
/// each) and returns the chosen one's fit, its report carrying the selection. `stop` as for
/// [`identify_stoppable`]: a signal stops at the fit in progress.
///
/// In two stages (issue 44: a full fit of all eight took 13 min of CPU on two 12 s logs). The sheet as
/// given is fitted in full (its values are every other structure's start, its floors the unit of the
/// BIC). Every other structure is screened: a short Levenberg-Marquardt from those values with the effect
/// at its start ([`crate::fit::screen`]: the sheet as given's weights, no coarse pass, no intervals), its
/// BIC computed on all fit rows. Then, lowest screening BIC first, structures are fitted in full (from
/// their screened values, no coarse pass: the same fit, started near its end) while a screened BIC is below
/// the lowest BIC of a fully fitted structure that the rules accept, plus a margin ([`SCREEN_MARGIN`]): the
/// full fit goes on from the screened values, so a structure screened above that cannot be chosen. The
/// structures not fitted in full carry their screening figures (`screened`).
pub fn select(
    req: &Request,
    structures: &[Structure],
    work: &Path,
    stop: Option<&std::sync::atomic::AtomicUsize>,
    progress: &dyn Fn(&str),
) -> Result<Identified, IdentifyError> {
    let sheet_model = ActuatorSheet::load(&req.actuator)?.model();
    let n0 = sheet_model.actuator.gas.polytropic_exponent;
    let mut candidates = Vec::new();
    let mut fits: Vec<Option<Identified>> = Vec::new();
    let mut screens: Vec<Option<Screened>> = Vec::new();
    // Each effect starts where the sheet as given ended: a nested model starts at least as well as the
    // simpler one (from the sheet's own values a leak's fit once ended worse than no leak at all).
    let mut warm: Vec<(Key, f64)> = Vec::new();
    let mut base: Option<Identified> = None;
    for s in structures {
        let mut keys: Vec<String> = req.free.clone();
        keys.extend(s.keys.iter().map(|k| k.name().to_string()));
        let mut c = Candidate {
            structure: s.name,
            adds: s.adds,
            keys: keys.clone(),
            skipped: None,
            bic: f64::NAN,
            fit_over_floor_sq: f64::NAN,
            validation_over_floor_sq: f64::NAN,
            adequate: false,
            significant: s.edits.is_empty(),
            screened: false,
            fit_seconds: 0.0,
        };
        if s.edits.is_empty() {
            progress(s.name);
            let id = identify_stoppable(req, stop)?;
            warm = id
                .keys
                .iter()
                .zip(&id.report.fit.estimates)
                .filter(|(k, _)| k.file().is_some())
                .map(|(k, e)| (*k, e.value))
                .collect();
            score(&mut c, s, &id, n0);
            candidates.push(c);
            fits.push(None);
            screens.push(None);
            base = Some(id);
            continue;
        }
        let Some(b) = &base else {
            return Err(IdentifyError::Fit(
                "the selection needs the sheet as given (`as_given`) first".into(),
            ));
        };
        progress(&format!("{} (screen)", s.name));
        let mut screened = screen_structure(req, s, &warm, 1.0, work, b, &sheet_model, stop);
        // One start can end in a local minimum worse than the sheet as given, which the structure contains
        // (its effect at zero): then once more from a tenth of the effect's start, and the better kept.
        // (Not for stick-slip: F_s is not scaled, the second start would be the first.)
        let base_fit = candidates[0].fit_over_floor_sq;
        let scaled = (s.edits.iter()).any(|e| matches!(e, Edit::Value(k, _) if *k != Key::Static));
        if scaled
            && screened
                .as_ref()
                .is_ok_and(|r| r.as_ref().is_ok_and(|sc| sc.fit > base_fit))
        {
            match screen_structure(req, s, &warm, 0.1, work, b, &sheet_model, stop) {
                Ok(Ok(again))
                    if screened
                        .as_ref()
                        .is_ok_and(|r| r.as_ref().is_ok_and(|sc| again.fit < sc.fit)) =>
                {
                    screened = Ok(Ok(again));
                }
                Err(e @ IdentifyError::Interrupted { .. }) => return Err(e),
                _ => {}
            }
        }
        match screened {
            Ok(Ok(sc)) => {
                c.bic = sc.bic;
                c.fit_over_floor_sq = sc.fit;
                c.validation_over_floor_sq = sc.validation;
                c.fit_seconds = sc.seconds;
                c.screened = true;
                screens.push(Some(sc));
            }
            Ok(Err(why)) => {
                c.skipped = Some(why);
                screens.push(None);
            }
            Err(e @ IdentifyError::Interrupted { .. }) => return Err(e),
            Err(e) => {
                c.skipped = Some(format!("the fit failed: {e}"));
                screens.push(None);
            }
        }
        candidates.push(c);
        fits.push(None);
    }
    let Some(b) = base else {
        return Err(IdentifyError::Fit(
            "the selection needs the sheet as given (`as_given`) first".into(),
        ));
    };
    let base_index = candidates
        .iter()
        .position(|c| c.structure == "as_given")
        .expect("the sheet as given was fitted");
    fits[base_index] = Some(b);
    // The full fits, lowest screening BIC first, while one can still beat the best accepted.
    let mut order: Vec<usize> = (0..candidates.len())
        .filter(|&i| screens[i].is_some())
        .collect();
    order.sort_by(|&a, &b| candidates[a].bic.total_cmp(&candidates[b].bic));
    let n = fits[base_index].as_ref().map_or(0.0, |b| {
        let mc = &b.report.model_check;
        (mc.rows * mc.channels.len()) as f64
    });
    for i in order {
        let best = accepted(&candidates).map_or(f64::INFINITY, |j| candidates[j].bic);
        if candidates[i].bic >= best + n * SCREEN_MARGIN.ln() {
            break;
        }
        let s = structures
            .iter()
            .find(|s| s.name == candidates[i].structure)
            .expect("a candidate is a structure");
        progress(s.name);
        let sc = screens[i].take().expect("screened");
        let mut c = candidates[i].clone();
        c.screened = false;
        let fitted = match structure_sheet(req, s, &sc.values, 1.0, &work.join(s.name))? {
            Ok(actuator) => {
                let r = Request {
                    actuator,
                    free: c.keys.clone(),
                    bounds: structure_bounds(req, s, &warm, &sheet_model),
                    options: crate::fit::FitOptions {
                        coarse_segment_s: None,
                        ..req.options
                    },
                    ..req.clone()
                };
                identify_stoppable(&r, stop)
            }
            Err(why) => Err(IdentifyError::Fit(why)),
        };
        let fitted = match fitted {
            Ok(id) => match invalid_fitted_sheet(work, s, &id)? {
                Some(e) => Err(IdentifyError::Fit(format!(
                    "its fitted values do not make a valid sheet: {e}"
                ))),
                None => Ok(id),
            },
            e => e,
        };
        match fitted {
            Ok(id) => {
                score(&mut c, s, &id, n0);
                fits[i] = Some(id);
            }
            Err(e @ IdentifyError::Interrupted { .. }) => return Err(e),
            Err(e) => {
                c.skipped = Some(format!("the fit failed: {e}"));
            }
        }
        candidates[i] = c;
    }
    let (chosen, verdict) = choose(&candidates)?;
    let c = &candidates[chosen];
    let selection = Selection {
        criterion: CRITERION,
        chosen: c.structure,
        verdict,
        candidates,
    };
    let mut id = fits[chosen].take().expect("a chosen structure was fitted");
    id.report.structure_selection = Some(selection);
    Ok(id)
}

/// The screening fit of structure `s` (its sheet from `warm` with the effect at `scale` of its start,
/// written into `work`): Ok(Err(reason)) when the structure is not fitted (the sheet has the effect
/// already, ...); its figures in the units of the sheet as given's fit `base` (its weights, rows and
/// floors).
#[allow(clippy::too_many_arguments)]
fn screen_structure(
    req: &Request,
    s: &Structure,
    warm: &[(Key, f64)],
    scale: f64,
    work: &Path,
    base: &Identified,
    sheet_model: &pneuflex_pneumatics::OneDofModel,
    stop: Option<&std::sync::atomic::AtomicUsize>,
) -> Result<Result<Screened, String>, IdentifyError> {
    let t0 = std::time::Instant::now();
    let dir = if scale == 1.0 {
        work.join(s.name)
    } else {
        work.join(format!("{}-small", s.name))
    };
    let actuator = match structure_sheet(req, s, warm, scale, &dir)? {
        Ok(a) => a,
        Err(why) => return Ok(Err(why)),
    };
    let model = ActuatorSheet::load(&actuator)?.model();
    let mut free = req.free.clone();
    free.extend(s.keys.iter().map(|k| k.name().to_string()));
    let keys = crate::request::parse_free(&free, &model)?;
    let bounds = structure_bounds(req, s, warm, sheet_model);
    let free = crate::request::parse_bounds(&keys, &bounds, &model)?;
    let (values, _) = crate::fit::screen(
        &model,
        &free,
        &base.data,
        &base.options.replay,
        base.report.fit.sigma,
        SCREEN_PATIENCE,
        SCREEN_TOLERANCE,
        stop,
    )?;
    // The figures on every fit row and held-out row, in the sheet as given's floors.
    let pb = crate::fit::Problem::new(
        model,
        Default::default(),
        free.clone(),
        &base.data,
        base.options.replay,
        base.report.fit.sigma,
    );
    let mc = &base.report.model_check;
    let over = |rms: [f64; 3]| {
        mc.channels
            .iter()
            .zip(rms)
            .map(|(c, r)| (r / c.floor).powi(2))
            .sum::<f64>()
            / mc.channels.len().max(1) as f64
    };
    let fit = over(pb.rms_at(&values, false));
    let validation = over(pb.rms_at(&values, true));
    let n = (mc.rows * mc.channels.len()) as f64;
    let bic = n * fit.ln() + keys.len() as f64 * n.ln();
    if !bic.is_finite() {
        return Err(IdentifyError::Fit(
            "its screening fit does not stay finite".into(),
        ));
    }
    Ok(Ok(Screened {
        values: keys.iter().copied().zip(values).collect(),
        fit,
        validation,
        bic,
        seconds: t0.elapsed().as_secs_f64(),
    }))
}

/// The bounds of structure `s`'s fit: the request's, and F_s's for a friction structure; `warm`: the values
/// the sheet as given was fitted to.
fn structure_bounds(
    req: &Request,
    s: &Structure,
    warm: &[(Key, f64)],
    sheet_model: &pneuflex_pneumatics::OneDofModel,
) -> Vec<String> {
    // F_s must stay above F_c for the law (the sheet refuses less): the friction structures bound it.
    let mut bounds = req.bounds.clone();
    if s.keys.contains(&Key::Static) {
        let f_c = warm
            .iter()
            .find(|(k, _)| *k == Key::Coulomb)
            .map_or_else(|| coulomb(sheet_model), |w| w.1);
        bounds.push(format!("{}=[{},{}]", Key::Static.name(), f_c, 20.0 * f_c));
    }
    bounds
}

/// A fitted candidate's numbers: its fit and validation RMS over the noise floor, squared, its BIC, its
/// model check's verdict and whether its effect is seen (`n0`: the sheet's polytropic exponent).
fn score(c: &mut Candidate, s: &Structure, id: &Identified, n0: f64) {
    let (fit, val, n) = normalised(id);
    let k = id.keys.len() as f64;
    c.fit_over_floor_sq = fit;
    c.validation_over_floor_sq = val;
    c.bic = n as f64 * fit.ln() + k * (n as f64).ln();
    c.adequate = id.report.model_check.adequate;
    c.significant = s.edits.is_empty() || effect_seen(s, id, n0);
    c.fit_seconds = id.report.fit_seconds;
}

/// Why the fitted values of structure `s` do not make a sheet the tool can load again (the output's fitted
/// sheet), written into a scratch folder of `work` and removed; None when they do.
fn invalid_fitted_sheet(
    work: &Path,
    s: &Structure,
    id: &Identified,
) -> Result<Option<String>, IdentifyError> {
    let check = work.join(format!("{}-fitted", s.name));
    std::fs::create_dir_all(&check).map_err(|e| IdentifyError::Output {
        file: check.clone(),
        message: e.to_string(),
    })?;
    let values: Vec<(Key, f64)> = (id.keys.iter().zip(&id.report.fit.estimates))
        .map(|(k, e)| (*k, e.value))
        .collect();
    let written = crate::sheet::write_sheets(&id.sheet, &values, &check, "");
    let _ = std::fs::remove_dir_all(&check);
    Ok(written.err().map(|e| e.to_string()))
}

/// Among the structures fitted in full, significant, with a finite BIC and held-out residuals within
/// `HELD_OUT_SLACK` of the sheet as given's, the one of lowest BIC.
fn accepted(candidates: &[Candidate]) -> Option<usize> {
    let base_val = candidates
        .iter()
        .find(|c| c.structure == "as_given" && c.skipped.is_none())
        .map_or(f64::INFINITY, |c| c.validation_over_floor_sq);
    (0..candidates.len())
        .filter(|&i| {
            let c = &candidates[i];
            c.skipped.is_none()
                && !c.screened
                && c.significant
                && c.bic.is_finite()
                && c.validation_over_floor_sq <= HELD_OUT_SLACK * base_val
        })
        .min_by(|&a, &b| candidates[a].bic.total_cmp(&candidates[b].bic))
}

/// The chosen structure: among those fitted, significant, with a finite BIC and held-out residuals within
/// `HELD_OUT_SLACK` of the sheet as given's, the lowest BIC; with the verdict in words.
fn choose(candidates: &[Candidate]) -> Result<(usize, String), IdentifyError> {
    let chosen = accepted(candidates)
        .ok_or_else(|| IdentifyError::Fit("no structure could be fitted to the logs".into()))?;
    let c = &candidates[chosen];
    let verdict = if c.adequate {
        format!(
            "`{}` ({}): the lowest BIC, and the model check finds it explains the logs",
            c.structure, c.adds
        )
    } else {
        format!(
            "`{}` ({}): the lowest BIC, but the model check finds it does not explain the logs either: \
             the rig has more than one of these effects, or another; its intervals are not valid",
            c.structure, c.adds
        )
    };
    Ok((chosen, verdict))
}
