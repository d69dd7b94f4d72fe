//! What a `--set KEY=SPEC` sweeps over, and the points of a sweep.
//!
//! SPEC is `@KEY*F` (not an axis: another swept key's value times F at every point), a list `a,b,c`, a range `lin:LO:HI:N` or `log:LO:HI:N` (N values, both ends included), or a
//! sample `rand:LO:HI`, `rand-log:LO:HI`, `lhs:LO:HI`, `lhs-log:LO:HI` (uniform random, or a Latin
//! hypercube, in the value or in its logarithm). The lists and ranges make a grid; the sampled keys share
//! `samples` points (one Latin hypercube over all of them), crossed with the grid. Points are numbered in
//! grid order, the first `--set` varying slowest; the samples are one more axis, at the place of the first
//! sampled key.

use crate::key::{KeyPath, Value};

/// How one key is swept.
#[derive(Clone, Debug, PartialEq)]
pub enum Spec {
    /// These values, in this order.
    List(Vec<Value>),
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

/// A `--set` that cannot be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("--set {arg}: {message}")]
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
    if n == 1 {
        return vec![lo];
    }
    (0..n)
        .map(|i| {
            if i == 0 {
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
        })
        .collect()
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
                if n == 0 || n > 100_000 {
                    return Err(bad(format!("N must be in 1 ..= 100000, got {n}")));
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
                Spec::List(
                    range(lo, hi, n, log)
                        .into_iter()
                        .map(Value::Float)
                        .collect(),
                )
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
                Spec::List(vals)
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

/// The points of a sweep: every key's value at every point.
#[derive(Clone, Debug, PartialEq)]
pub struct Points {
    /// The swept keys, in `--set` order.
    pub keys: Vec<KeyPath>,
    /// One row per point: the value of each key.
    pub values: Vec<Vec<Value>>,
    /// The grid's axes (the key's index among `keys`, its values), first varying slowest, when no key is
    /// sampled; keys that follow another (`@KEY`) are not axes.
    pub grid: Option<Vec<(usize, Vec<Value>)>>,
}

/// Expands the `--set`s into points; `samples` and `seed` serve the sampled keys.
pub fn points(sets: &[SetArg], samples: Option<usize>, seed: u64) -> Result<Points, SpecError> {
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
    let n_samples = match (sampled.is_empty(), samples) {
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
    };
    // The samples: one value per sampled key per sample, drawn key by key in --set order.
    let mut rng = SplitMix64::new(seed);
    let mut sample_values: Vec<Vec<f64>> = Vec::new(); // [key][sample]
    for &i in &sampled {
        let Spec::Sample { lo, hi, log, lhs } = sets[i].spec else {
            unreachable!()
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
    // Axes: each list key, and the samples as one axis at the first sampled key.
    enum Axis {
        List(usize),
        Samples,
    }
    let mut axes = Vec::new();
    for (i, s) in sets.iter().enumerate() {
        match s.spec {
            Spec::List(_) => axes.push(Axis::List(i)),
            Spec::Sample { .. } if sampled.first() == Some(&i) => axes.push(Axis::Samples),
            Spec::Sample { .. } | Spec::Follow { .. } => {}
        }
    }
    // Followers: the key they follow (an axis key, listed or sampled) and the factor.
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
            follows.push((i, j, *factor));
        }
    }
    if axes.is_empty() {
        return Err(SpecError {
            arg: String::new(),
            message: "every --set follows another key: nothing to sweep".into(),
        });
    }
    let len = |a: &Axis| match a {
        Axis::List(i) => match &sets[*i].spec {
            Spec::List(v) => v.len(),
            _ => unreachable!(),
        },
        Axis::Samples => n_samples,
    };
    let total: usize = axes.iter().map(len).product();
    if total > 10_000_000 {
        return Err(SpecError {
            arg: String::new(),
            message: format!("{total} points: more than the limit of 10,000,000"),
        });
    }
    let mut values = Vec::with_capacity(total);
    let mut idx = vec![0usize; axes.len()];
    for _ in 0..total {
        let mut row = vec![Value::Int(0); sets.len()];
        for (a, axis) in axes.iter().enumerate() {
            match axis {
                Axis::List(i) => {
                    let Spec::List(v) = &sets[*i].spec else {
                        unreachable!()
                    };
                    row[*i] = v[idx[a]].clone();
                }
                Axis::Samples => {
                    for (k, &i) in sampled.iter().enumerate() {
                        row[i] = Value::Float(sample_values[k][idx[a]]);
                    }
                }
            }
        }
        for &(i, j, factor) in &follows {
            row[i] = match &row[j] {
                Value::Int(v) if factor == 1.0 => Value::Int(*v),
                v => match v.as_f64() {
                    Some(x) => Value::Float(x * factor),
                    None if factor == 1.0 => v.clone(),
                    None => {
                        return Err(SpecError {
                            arg: format!("{}={}", sets[i].key.text, sets[i].spec_text),
                            message: format!(
                                "`{}` = {v} is not a number to multiply",
                                sets[j].key.text
                            ),
                        });
                    }
                },
            };
        }
        values.push(row);
        // Odometer: the last axis varies fastest.
        for a in (0..axes.len()).rev() {
            idx[a] += 1;
            if idx[a] < len(&axes[a]) {
                break;
            }
            idx[a] = 0;
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
        values,
        grid,
    })
}
