//! What a `--set KEY=SPEC` sweeps over, and the points of a sweep.
//!
//! SPEC is `@KEY*F` (not an axis: another swept key's value times F at every point), a list `a,b,c`, a range `lin:LO:HI:N` or `log:LO:HI:N` (N values, both ends included), or a
//! sample `rand:LO:HI`, `rand-log:LO:HI`, `lhs:LO:HI`, `lhs-log:LO:HI` (uniform random, or a Latin
//! hypercube, in the value or in its logarithm). The lists and ranges make a grid; the sampled keys share
//! `samples` points (one Latin hypercube over all of them), crossed with the grid. Points are numbered in
//! grid order, the first `--set` varying slowest; the samples are one more axis, at the place of the first
//! sampled key.

use crate::key::{KeyPath, Value};

/// The values of one grid axis: given one by one, or a range worked out from its index (a range of a
/// hundred million values costs nothing until its values are asked for).
#[derive(Clone, Debug, PartialEq)]
pub enum AxisValues {
    /// These values, in this order.
    Given(Vec<Value>),
    /// `n` values from `lo` to `hi`, both included, evenly in the value or its logarithm.
    Range {
        /// First value.
        lo: f64,
        /// Last value.
        hi: f64,
        /// Number of values.
        n: usize,
        /// Evenly in the logarithm.
        log: bool,
    },
}

impl AxisValues {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            AxisValues::Given(v) => v.len(),
            AxisValues::Range { n, .. } => *n,
        }
    }

    /// Whether the axis has no value (never, once parsed).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `i`-th value.
    pub fn get(&self, i: usize) -> Value {
        match self {
            AxisValues::Given(v) => v[i].clone(),
            AxisValues::Range { lo, hi, n, log } => {
                Value::Float(range_value(*lo, *hi, *n, *log, i))
            }
        }
    }

    /// Every value (for a heatmap's ticks: a small axis).
    pub fn values(&self) -> Vec<Value> {
        (0..self.len()).map(|i| self.get(i)).collect()
    }

    /// The first value that is not a number, if any.
    fn first_non_number(&self) -> Option<Value> {
        match self {
            AxisValues::Given(v) => v.iter().find(|v| v.as_f64().is_none()).cloned(),
            AxisValues::Range { .. } => None,
        }
    }
}

/// How one key is swept.
#[derive(Clone, Debug, PartialEq)]
pub enum Spec {
    /// These values, in this order (a list, or a `lin:`/`log:` range).
    List(AxisValues),
    /// Sampled between `lo` and `hi`.
    Sample {
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
        /// Uniform in the logarithm (both bounds > 0).
        log: bool,
        /// Latin hypercube (else independent uniform draws).
        lhs: bool,
    },
    /// Not an axis: at every point, another swept key's value times a factor (`@KEY*F`, e.g. the stiffness
    /// after an event at twice the initial one).
    Follow {
        /// The key followed, as written.
        key: String,
        /// The factor.
        factor: f64,
    },
}

/// A `--set`: the key and its spec.
#[derive(Clone, Debug, PartialEq)]
pub struct SetArg {
    /// The key path.
    pub key: KeyPath,
    /// As written after `=`.
    pub spec_text: String,
    /// The parsed spec.
    pub spec: Spec,
}

/// A `--set` that cannot be read: `--set KEY=SPEC: message`, or `--samples: message` for another option.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}: {message}", if arg.starts_with("--") { arg.clone() } else if arg.is_empty() { "--set".to_string() } else { format!("--set {arg}") })]
pub struct SpecError {
    /// The argument as written.
    pub arg: String,
    /// What is wrong.
    pub message: String,
}

fn number(arg: &str, what: &str, s: &str) -> Result<f64, SpecError> {
    let x: f64 = s.trim().replace('_', "").parse().map_err(|_| SpecError {
        arg: arg.into(),
        message: format!("{what} `{s}` is not a number"),
    })?;
    if !x.is_finite() {
        return Err(SpecError {
            arg: arg.into(),
            message: format!("{what} must be finite, got {s}"),
        });
    }
    Ok(x)
}

/// A range's values: `n` points from `lo` to `hi`, evenly in the value or its logarithm.
pub fn range(lo: f64, hi: f64, n: usize, log: bool) -> Vec<f64> {
    (0..n).map(|i| range_value(lo, hi, n, log, i)).collect()
}

/// The `i`-th of `n` values from `lo` to `hi` (both ends exact).
pub fn range_value(lo: f64, hi: f64, n: usize, log: bool, i: usize) -> f64 {
    if i == 0 || n == 1 {
        return lo;
    }
    if i == n - 1 {
        return hi;
    }
    let f = i as f64 / (n - 1) as f64;
    if log {
        (lo.ln() + f * (hi.ln() - lo.ln())).exp()
    } else {
        lo + f * (hi - lo)
    }
}

impl SetArg {
    /// Parses `KEY=SPEC`.
    pub fn parse(arg: &str) -> Result<SetArg, SpecError> {
        let bad = |m: String| SpecError {
            arg: arg.into(),
            message: m,
        };
        let (key, spec_text) = arg.split_once('=').ok_or_else(|| {
            bad("expected KEY=SPEC (SPEC: a,b,c | lin:LO:HI:N | log:LO:HI:N | rand:LO:HI | lhs:LO:HI | rand-log:LO:HI | lhs-log:LO:HI)".into())
        })?;
        let key = KeyPath::parse(key).map_err(|e| bad(e.message))?;
        let spec_text = spec_text.trim().to_string();
        if spec_text.is_empty() {
            return Err(bad("empty SPEC".into()));
        }
        if let Some(rest) = spec_text.strip_prefix('@') {
            let (k, f) = match rest.rsplit_once('*') {
                Some((k, f)) => (k.trim(), Some(f.trim())),
                None => (rest.trim(), None),
            };
            let factor = match f {
                Some(f) => number(arg, "the factor", f)?,
                None => 1.0,
            };
            KeyPath::parse(k).map_err(|e| bad(e.message))?;
            let spec = Spec::Follow {
                key: k.to_string(),
                factor,
            };
            return Ok(SetArg {
                key,
                spec_text,
                spec,
            });
        }
        let words: Vec<&str> = spec_text.split(':').collect();
        let spec = match words[0] {
            w @ ("lin" | "log") => {
                if words.len() != 4 {
                    return Err(bad(format!("`{w}:LO:HI:N` takes three numbers")));
                }
                let lo = number(arg, "LO", words[1])?;
                let hi = number(arg, "HI", words[2])?;
                let n: usize = words[3]
                    .trim()
                    .parse()
                    .map_err(|_| bad(format!("N `{}` is not a whole number", words[3])))?;
                if n == 0 || n as u64 > HARD_MAX_POINTS {
                    return Err(bad(format!(
                        "N must be in 1 ..= {HARD_MAX_POINTS} (the points of all keys together are bounded by \
                         --max-points), got {n}"
                    )));
                }
                if n > 1 && lo == hi {
                    return Err(bad(format!(
                        "LO = HI = {lo} with N = {n}: the same value {n} times"
                    )));
                }
                let log = w == "log";
                if log && (lo <= 0.0 || hi <= 0.0) {
                    return Err(bad(format!(
                        "a log range needs LO > 0 and HI > 0, got {lo} and {hi}"
                    )));
                }
                Spec::List(AxisValues::Range { lo, hi, n, log })
            }
            w @ ("rand" | "rand-log" | "lhs" | "lhs-log") => {
                if words.len() != 3 {
                    return Err(bad(format!(
                        "`{w}:LO:HI` takes two numbers (the count is --samples)"
                    )));
                }
                let lo = number(arg, "LO", words[1])?;
                let hi = number(arg, "HI", words[2])?;
                if hi <= lo {
                    return Err(bad(format!("needs LO < HI, got {lo} and {hi}")));
                }
                let log = w.ends_with("-log");
                if log && lo <= 0.0 {
                    return Err(bad(format!("a log sample needs LO > 0, got {lo}")));
                }
                Spec::Sample {
                    lo,
                    hi,
                    log,
                    lhs: w.starts_with("lhs"),
                }
            }
            _ if words.len() > 1 => {
                return Err(bad(format!(
                    "unknown SPEC kind `{}:`, expected lin:, log:, rand:, rand-log:, lhs: or lhs-log: (or a list a,b,c)",
                    words[0]
                )));
            }
            _ => {
                let vals: Vec<Value> = spec_text.split(',').map(Value::parse).collect();
                if vals
                    .iter()
                    .any(|v| matches!(v, Value::Str(s) if s.is_empty()))
                {
                    return Err(bad("empty value in the list".into()));
                }
                if let Some(v) = vals
                    .iter()
                    .find(|v| matches!(v, Value::Float(x) if !x.is_finite()))
                {
                    return Err(bad(format!("every value must be finite, got {v}")));
                }
                Spec::List(AxisValues::Given(vals))
            }
        };
        Ok(SetArg {
            key,
            spec_text,
            spec,
        })
    }
}

/// SplitMix64: a small, fixed, portable generator (the same numbers on every machine and thread count).
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    /// A uniformly random permutation of 0..n (Fisher–Yates).
    pub fn permutation(&mut self, n: usize) -> Vec<usize> {
        let mut p: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            let j = (self.next_u64() % (i as u64 + 1)) as usize;
            p.swap(i, j);
        }
        p
    }
}

/// The largest number of points (sweep) or scene runs (tune) a command takes unless raised with
/// `--max-points` / `--max-runs`: a million scene runs are hours on two cores.
pub const DEFAULT_MAX_POINTS: u64 = 1_000_000;
/// The hard ceiling of `--max-points` and `--max-runs` (the sample values alone are 8 bytes per key and point).
pub const HARD_MAX_POINTS: u64 = 100_000_000;

/// One axis of the grid: a listed key's values, or the samples shared by every sampled key.
#[derive(Clone, Debug, PartialEq)]
enum Axis {
    /// The key's index among the keys, and its values.
    List(usize, AxisValues),
    /// The sampled keys' indices and each one's values, `[key][sample]`.
    Samples(Vec<usize>, Vec<Vec<f64>>),
}

impl Axis {
    fn len(&self) -> usize {
        match self {
            Axis::List(_, v) => v.len(),
            Axis::Samples(_, v) => v.first().map_or(0, Vec::len),
        }
    }
}

/// The points of a sweep: every key's value at every point, worked out from the point's number when asked
/// ([`Points::row`]), so that memory does not grow with the number of points.
#[derive(Clone, Debug, PartialEq)]
pub struct Points {
    /// The swept keys, in `--set` order.
    pub keys: Vec<KeyPath>,
    /// The grid's axes (the key's index among `keys`, its values), first varying slowest, when no key is
    /// sampled; keys that follow another (`@KEY`) are not axes.
    pub grid: Option<Vec<(usize, AxisValues)>>,
    axes: Vec<Axis>,
    /// Followers: (key, the key it follows, factor).
    follows: Vec<(usize, usize, f64)>,
    len: usize,
}

impl Points {
    /// The single point of no keys (a tune over the scene's own environment).
    pub fn none() -> Self {
        Points {
            keys: Vec::new(),
            grid: None,
            axes: Vec::new(),
            follows: Vec::new(),
            len: 1,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are no points (never: a sweep has at least one).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Every key's value at point `i` (the last axis varies fastest).
    pub fn row(&self, i: usize) -> Vec<Value> {
        let mut row = vec![Value::Int(0); self.keys.len()];
        let mut rest = i;
        for axis in self.axes.iter().rev() {
            let n = axis.len();
            let k = rest % n;
            rest /= n;
            match axis {
                Axis::List(key, v) => row[*key] = v.get(k),
                Axis::Samples(keys, v) => {
                    for (j, &key) in keys.iter().enumerate() {
                        row[key] = Value::Float(v[j][k]);
                    }
                }
            }
        }
        for &(key, of, factor) in &self.follows {
            row[key] = follow(&row[of], factor);
        }
        row
    }
}

/// A follower's value: the followed value times the factor (checked to be a number beforehand).
fn follow(v: &Value, factor: f64) -> Value {
    match v {
        Value::Int(i) if factor == 1.0 => Value::Int(*i),
        v => match v.as_f64() {
            Some(x) => Value::Float(x * factor),
            None => v.clone(),
        },
    }
}

/// `a × b × ...` as the user reads it, for a refused count.
fn product_text(lens: &[usize]) -> String {
    lens.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(" × ")
}

/// Expands the `--set`s into points; `samples` and `seed` serve the sampled keys. The number of points is
/// worked out first, with checked arithmetic, and refused above `max_points` (the flag that raises it is
/// `limit_flag`) before anything is allocated.
pub fn points(
    sets: &[SetArg],
    samples: Option<usize>,
    seed: u64,
    max_points: u64,
    limit_flag: &str,
) -> Result<Points, SpecError> {
    if sets.is_empty() {
        return Err(SpecError {
            arg: String::new(),
            message: "nothing to sweep: give at least one --set KEY=SPEC".into(),
        });
    }
    for (i, s) in sets.iter().enumerate() {
        if sets[..i].iter().any(|o| o.key.text == s.key.text) {
            return Err(SpecError {
                arg: format!("{}={}", s.key.text, s.spec_text),
                message: format!("`{}` is set twice", s.key.text),
            });
        }
    }
    let sampled: Vec<usize> = (0..sets.len())
        .filter(|&i| matches!(sets[i].spec, Spec::Sample { .. }))
        .collect();
    let n_samples = sample_count(sets, &sampled, samples)?;
    let follows = followers(sets)?;
    // The axes' lengths, and their product, before anything is drawn or allocated.
    let mut lens = Vec::new();
    for (i, s) in sets.iter().enumerate() {
        match &s.spec {
            Spec::List(v) => lens.push(v.len()),
            Spec::Sample { .. } if sampled.first() == Some(&i) => lens.push(n_samples),
            Spec::Sample { .. } | Spec::Follow { .. } => {}
        }
    }
    if lens.is_empty() {
        return Err(SpecError {
            arg: String::new(),
            message: "every --set follows another key: nothing to sweep".into(),
        });
    }
    let total = checked_total(&lens, !sampled.is_empty(), max_points, limit_flag)?;
    let sample_values = draw_samples(sets, &sampled, n_samples, seed);
    let mut axes = Vec::new();
    let mut sample_values = Some(sample_values);
    for (i, s) in sets.iter().enumerate() {
        match &s.spec {
            Spec::List(v) => axes.push(Axis::List(i, v.clone())),
            Spec::Sample { .. } if sampled.first() == Some(&i) => axes.push(Axis::Samples(
                sampled.clone(),
                sample_values.take().unwrap_or_default(),
            )),
            Spec::Sample { .. } | Spec::Follow { .. } => {}
        }
    }
    let grid = sampled.is_empty().then(|| {
        sets.iter()
            .enumerate()
            .filter_map(|(i, s)| match &s.spec {
                Spec::List(v) => Some((i, v.clone())),
                _ => None,
            })
            .collect()
    });
    Ok(Points {
        keys: sets.iter().map(|s| s.key.clone()).collect(),
        grid,
        axes,
        follows,
        len: total,
    })
}

/// The number of samples of the sampled keys (`sampled`: their indices in `sets`): `--samples`, required
/// with them and refused without.
fn sample_count(
    sets: &[SetArg],
    sampled: &[usize],
    samples: Option<usize>,
) -> Result<usize, SpecError> {
    Ok(match (sampled.is_empty(), samples) {
        (true, None) => 0,
        (true, Some(_)) => {
            return Err(SpecError {
                arg: "--samples".into(),
                message: "applies to sampled keys (rand:, lhs:, ...); no --set samples".into(),
            });
        }
        (false, None) => {
            let s = &sets[sampled[0]];
            return Err(SpecError {
                arg: format!("{}={}", s.key.text, s.spec_text),
                message: "a sampled key needs --samples N (and --seed S, default 0)".into(),
            });
        }
        (false, Some(0)) => {
            return Err(SpecError {
                arg: "--samples".into(),
                message: "must be at least 1".into(),
            });
        }
        (false, Some(n)) => n,
    })
}

/// Followers: the key they follow (an axis key, listed or sampled) and the factor; every value they
/// would multiply is checked to be a number here, once. Returns (follower, followed, factor) by index in `sets`.
fn followers(sets: &[SetArg]) -> Result<Vec<(usize, usize, f64)>, SpecError> {
    let mut follows: Vec<(usize, usize, f64)> = Vec::new();
    for (i, s) in sets.iter().enumerate() {
        if let Spec::Follow { key, factor } = &s.spec {
            let arg = format!("{}={}", s.key.text, s.spec_text);
            let Some(j) = sets.iter().position(|o| &o.key.text == key) else {
                return Err(SpecError {
                    arg,
                    message: format!("follows `{key}`, which is not swept (give it its own --set)"),
                });
            };
            if matches!(sets[j].spec, Spec::Follow { .. }) {
                return Err(SpecError {
                    arg,
                    message: format!("follows `{key}`, which follows another key itself"),
                });
            }
            if *factor != 1.0
                && let Spec::List(v) = &sets[j].spec
                && let Some(bad) = v.first_non_number()
            {
                return Err(SpecError {
                    arg,
                    message: format!("`{key}` = {bad} is not a number to multiply"),
                });
            }
            follows.push((i, j, *factor));
        }
    }
    Ok(follows)
}

/// The number of points, the product of the axes' lengths `lens` in checked arithmetic, refused above
/// `max_points` (and the hard ceiling) with the flag that raises it; `sampled`: some keys are sampled.
fn checked_total(
    lens: &[usize],
    sampled: bool,
    max_points: u64,
    limit_flag: &str,
) -> Result<usize, SpecError> {
    let max = max_points.min(HARD_MAX_POINTS);
    lens.iter()
        .try_fold(1u64, |acc, &n| acc.checked_mul(n as u64))
        .filter(|&t| t <= max)
        .ok_or_else(|| {
            let exact = lens
                .iter()
                .try_fold(1u128, |acc, &n| acc.checked_mul(n as u128));
            let count = exact.map_or("more than 2^128".into(), |t| format!("{t}"));
            let flag = if max_points >= HARD_MAX_POINTS {
                format!("the ceiling of {limit_flag} is {HARD_MAX_POINTS}")
            } else {
                format!("{limit_flag} N raises the limit, up to {HARD_MAX_POINTS}")
            };
            SpecError {
                arg: if sampled {
                    "--set/--samples".into()
                } else {
                    String::new()
                },
                message: format!(
                    "{count} points ({}) is more than the limit of {max}; {flag}",
                    product_text(lens)
                ),
            }
        })
        .map(|t| t as usize)
}

/// The samples: one value per sampled key per sample, drawn key by key in --set order ([key][sample]).
fn draw_samples(sets: &[SetArg], sampled: &[usize], n_samples: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = SplitMix64::new(seed);
    let mut sample_values: Vec<Vec<f64>> = Vec::new();
    for &i in sampled {
        let Spec::Sample { lo, hi, log, lhs } = sets[i].spec else {
            unreachable!("sampled keys are Spec::Sample")
        };
        let perm = if lhs {
            rng.permutation(n_samples)
        } else {
            Vec::new()
        };
        let (a, b) = if log { (lo.ln(), hi.ln()) } else { (lo, hi) };
        let vals = (0..n_samples)
            .map(|k| {
                let u = rng.uniform();
                let f = if lhs {
                    (perm[k] as f64 + u) / n_samples as f64
                } else {
                    u
                };
                let x = a + f * (b - a);
                if log { x.exp() } else { x }
            })
            .collect();
        sample_values.push(vals);
    }
    sample_values
}
