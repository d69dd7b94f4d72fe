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
    values.extend(s.edits.iter().filter_map(|e| match e {
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

/// Fits every structure of `structures` to the logs of `req` (their sheets written into `work`, one folder
/// each) and returns the chosen one's fit, its report carrying the selection. `stop` as for
/// [`identify_stoppable`]: a signal stops at the fit in progress.
pub fn select(
    req: &Request,
    structures: &[Structure],
    work: &Path,
    stop: Option<&std::sync::atomic::AtomicUsize>,
    progress: &dyn Fn(&str),
) -> Result<Identified, IdentifyError> {
    let sheet_model = ActuatorSheet::load(&req.actuator)?.model();
    let mut candidates = Vec::new();
    let mut fits: Vec<Option<Identified>> = Vec::new();
    // Each effect starts where the sheet as given ended: a nested model starts at least as well as the
    // simpler one (from the sheet's own values a leak's fit once ended worse than no leak at all).
    let mut warm: Vec<(Key, f64)> = Vec::new();
    for s in structures {
        progress(s.name);
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
            fit_seconds: 0.0,
        };
        let actuator = if s.edits.is_empty() {
            Ok(req.actuator.clone())
        } else {
            structure_sheet(req, s, &warm, 1.0, &work.join(s.name))?
        };
        let actuator = match actuator {
            Ok(a) => a,
            Err(why) => {
                c.skipped = Some(why);
                candidates.push(c);
                fits.push(None);
                continue;
            }
        };
        let bounds = structure_bounds(req, s, &warm, &sheet_model);
        let r = Request {
            actuator,
            free: keys.clone(),
            bounds: bounds.clone(),
            ..req.clone()
        };
        let mut fitted = identify_stoppable(&r, stop);
        // One start can end in a local minimum worse than the sheet as given, which the structure contains
        // (its effect at zero): then once more from a tenth of the effect's start, and the better fit is kept.
        let base_fit = candidates
            .first()
            .filter(|b: &&Candidate| b.structure == "as_given")
            .map(|b| b.fit_over_floor_sq);
        if let (Ok(id), Some(base)) = (&fitted, base_fit)
            && normalised(id).0 > base
            && let Some(better) = from_a_tenth(req, s, &warm, work, &r, normalised(id).0, stop)?
        {
            fitted = Ok(better);
        }
        if let Ok(id) = &fitted
            && !s.edits.is_empty()
            && let Some(e) = invalid_fitted_sheet(work, s, id)?
        {
            fitted = Err(IdentifyError::Fit(format!(
                "its fitted values do not make a valid sheet: {e}"
            )));
        }
        match fitted {
            Ok(id) => {
                if s.edits.is_empty() {
                    warm = id
                        .keys
                        .iter()
                        .zip(&id.report.fit.estimates)
                        .filter(|(k, _)| k.file().is_some())
                        .map(|(k, e)| (*k, e.value))
                        .collect();
                }
                score(&mut c, s, &id, sheet_model.actuator.gas.polytropic_exponent);
                candidates.push(c);
                fits.push(Some(id));
            }
            Err(e @ IdentifyError::Interrupted { .. }) => return Err(e),
            Err(e) if s.edits.is_empty() => return Err(e),
            Err(e) => {
                c.skipped = Some(format!("the fit failed: {e}"));
                candidates.push(c);
                fits.push(None);
            }
        }
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

/// The fit of structure `s` once more from a tenth of its effect's start (`r`: the request of its first
/// fit, which reached `current`, fit RMS over floor squared); the new fit if it is better.
fn from_a_tenth(
    req: &Request,
    s: &Structure,
    warm: &[(Key, f64)],
    work: &Path,
    r: &Request,
    current: f64,
    stop: Option<&std::sync::atomic::AtomicUsize>,
) -> Result<Option<Identified>, IdentifyError> {
    let Ok(small) = structure_sheet(req, s, warm, 0.1, &work.join(format!("{}-small", s.name)))?
    else {
        return Ok(None);
    };
    let again = identify_stoppable(
        &Request {
            actuator: small,
            ..r.clone()
        },
        stop,
    );
    match again {
        Ok(b) if normalised(&b).0 < current => Ok(Some(b)),
        Err(e @ IdentifyError::Interrupted { .. }) => Err(e),
        _ => Ok(None),
    }
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

/// The chosen structure: among those fitted, significant, with a finite BIC and held-out residuals within
/// `HELD_OUT_SLACK` of the sheet as given's, the lowest BIC; with the verdict in words.
fn choose(candidates: &[Candidate]) -> Result<(usize, String), IdentifyError> {
    let base_val = candidates
        .iter()
        .find(|c| c.structure == "as_given" && c.skipped.is_none())
        .map_or(f64::INFINITY, |c| c.validation_over_floor_sq);
    let chosen = (0..candidates.len())
        .filter(|&i| {
            let c = &candidates[i];
            c.skipped.is_none()
                && c.significant
                && c.bic.is_finite()
                && c.validation_over_floor_sq <= HELD_OUT_SLACK * base_val
        })
        .min_by(|&a, &b| candidates[a].bic.total_cmp(&candidates[b].bic))
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
