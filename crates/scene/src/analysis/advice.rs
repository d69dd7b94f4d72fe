//! Warnings before a run: legal parameters the integrator cannot resolve. Each names the key to change and
//! a value that would work; the run still goes ahead (and stops as diverged if the state becomes impossible).

use pneuflex_pneumatics::{ChamberState, OneDofModel};

use crate::schema::{EventSpec, Scene};

/// RK4's stability limit on the negative real axis (|λh| below ≈ 2.785) and on the imaginary axis
/// (|ωh| below 2√2 ≈ 2.83); a step is resolved, not just stable, well inside: these are the warning lines.
const REAL_AXIS_RESOLVED: f64 = 1.0;
const OSCILLATION_RESOLVED: f64 = 0.5;

/// One warning: the key it is about and what to do.
#[derive(Clone, Debug, PartialEq)]
pub struct Warning {
    /// Dotted key path in the scene file.
    pub key: String,
    /// The message, with the numbers.
    pub message: String,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.key, self.message)
    }
}

/// The fastest chamber pressure pole |∂ṗ/∂p|, 1/s, over full valve openings both ways and the piston
/// at both ends and mid stroke (the smallest chamber volume is the fastest).
pub fn fastest_chamber_pole(model: &OneDofModel) -> f64 {
    let a = &model.actuator;
    let p_mid = 0.5 * (a.supply.supply_pressure_pa + a.supply.atmosphere_pressure_pa);
    let stroke = a.cylinder.stroke_m;
    let mut fastest: f64 = 0.0;
    for x in [0.0, 0.5 * stroke, stroke] {
        for spool in [-1.0, 1.0] {
            let s = ChamberState::with_temperature(p_mid, p_mid, a.supply.supply_temperature_k);
            let r0 = a.chamber_rates(&s, x, 0.0, spool);
            let d = 1e-3 * p_mid;
            let ra = a.chamber_rates(
                &ChamberState {
                    p_a: s.p_a + d,
                    ..s
                },
                x,
                0.0,
                spool,
            );
            let rb = a.chamber_rates(
                &ChamberState {
                    p_b: s.p_b + d,
                    ..s
                },
                x,
                0.0,
                spool,
            );
            fastest = fastest
                .max(((ra.p_a - r0.p_a) / d).abs())
                .max(((rb.p_b - r0.p_b) / d).abs());
        }
    }
    fastest
}

/// Smallest small-signal gain margin of the inner loop, and of the outer force loop around it, without a
/// warning, dB (Coulomb friction left out, so conservative: the proportional-valve Fig. 3 plant
/// limit-cycles from kp = 10.7 /m, where it reads −4 dB).
pub const MIN_GAIN_MARGIN_DB: f64 = 3.0;

/// Warnings about each run's inner-loop margins at every stiffness the scene meets, on plants the loop
/// analysis covers (a pneumatic plant — on a PWM valve from its sampled-data model — and the linear
/// plant); none on the others.
pub fn margin_warnings(scene: &Scene) -> Vec<Warning> {
    let mut out = Vec::new();
    // Runs with the same inner loop share one analysis (the margins depend on the plant and the PID only).
    let mut done: Vec<(
        pneuflex_control::PidParams,
        crate::analysis::loop_margins::LoopAnalysis,
    )> = Vec::new();
    // A frozen run runs its source's controller: its margins are the source's, warned about once.
    for (i, run) in scene
        .runs
        .iter()
        .enumerate()
        .filter(|(_, r)| r.frozen.is_none())
    {
        let a = match done.iter().find(|(pid, _)| *pid == run.inner) {
            Some((_, a)) => a.clone(),
            None => {
                let Ok(a) = crate::analysis::loop_margins::analyse(scene, i, MIN_GAIN_MARGIN_DB)
                else {
                    return out;
                };
                done.push((run.inner, a.clone()));
                a
            }
        };
        for m in &a.margins {
            // On a switching valve the sampled-data model of the PWM gives the margin (the period average
            // promises more: kp 49 against a simulated onset of 32 /m on paper-fig3).
            let pwm = crate::analysis::pwm_onset::pwm_onset_at(scene, i, m.stiffness_n_per_m)
                .ok()
                .flatten();
            if let Some(p) = pwm {
                let gm = 20.0 * (p.kp_per_m / run.inner.kp_per_m).log10();
                if gm < MIN_GAIN_MARGIN_DB {
                    out.push(Warning {
                        key: format!("runs[{i}].inner.kp_per_m"),
                        message: format!(
                            "run `{}`: the on/off valve's PWM limit-cycles from kp = {:.2} /m at k_e = {} N/m \
                             (sampled-data model, near {:.1} Hz): {gm:.1} dB of gain margin (below \
                             {MIN_GAIN_MARGIN_DB} dB); kp <= {:.2} /m keeps {MIN_GAIN_MARGIN_DB} dB (`pneuflex tf \
                             <scene> --loop`)",
                            run.name,
                            p.kp_per_m,
                            m.stiffness_n_per_m,
                            p.frequency_hz,
                            p.kp_per_m * 10f64.powf(-MIN_GAIN_MARGIN_DB / 20.0)
                        ),
                    });
                }
            } else if let Some(gm) = m.gain_margin_db.filter(|&g| g < MIN_GAIN_MARGIN_DB) {
                out.push(Warning {
                    key: format!("runs[{i}].inner.kp_per_m"),
                    message: format!(
                        "run `{}`: the inner loop's gain margin is {gm:.1} dB at k_e = {} N/m (below {MIN_GAIN_MARGIN_DB} dB): \
                         it may limit-cycle near {:.1} Hz; kp <= {:.2} /m keeps {MIN_GAIN_MARGIN_DB} dB \
                         (`pneuflex tf <scene> --loop` for the margins and the predicted onset)",
                        run.name,
                        m.stiffness_n_per_m,
                        m.phase_crossover_hz.unwrap_or(f64::NAN),
                        m.kp_max_per_m.unwrap_or(f64::NAN)
                    ),
                });
            }
            let o = &m.outer;
            if let Some(gm) = o.gain_margin_db.filter(|&g| g < MIN_GAIN_MARGIN_DB) {
                out.push(Warning {
                    key: format!("runs[{i}].impedance.b_d_ns_per_m"),
                    message: format!(
                        "run `{}`: the outer force loop (impedance filter, inner loop, environment) has {gm:.1} dB of \
                         gain margin at k_e = {} N/m (below {MIN_GAIN_MARGIN_DB} dB): the force may oscillate near \
                         {:.1} Hz after a change; b_d >= {} N s/m keeps {MIN_GAIN_MARGIN_DB} dB (`pneuflex tf \
                         <scene> --loop`)",
                        run.name,
                        m.stiffness_n_per_m,
                        o.phase_crossover_hz.unwrap_or(f64::NAN),
                        o.b_d_min_ns_per_m.map_or(f64::NAN, |b| (b * 10.0).ceil() / 10.0)
                    ),
                });
            }
        }
    }
    out
}

/// Warnings for a validated scene (Err only when its actuator sheet cannot be read; building the plant
/// reports that with its key anyway, so callers may ignore it).
pub fn warnings(scene: &Scene) -> Vec<Warning> {
    // The inner loop's margins where it can be analysed (empty on the ideal loop and the multibody rig).
    let mut out = margin_warnings(scene);
    if let Some(mb) = scene.plant.multibody() {
        out.extend(mount_damping_warnings(scene, mb));
    }
    let (Some(sheet), Some((h, steps_key, steps_now))) = (
        scene.actuator_sheet_path(),
        scene.plant.chamber_step(scene.dt_s),
    ) else {
        return out;
    };
    let Ok(sheet) = scene.load_sheet(&sheet) else {
        return out;
    };
    let model = sheet.model();
    let lambda = fastest_chamber_pole(&model);
    if lambda * h > REAL_AXIS_RESOLVED {
        out.push(Warning {
            key: steps_key.into(),
            message: format!(
                "the chamber pressures move with a time constant of {:.3e} s (fastest pole {lambda:.3e} 1/s), \
                 shorter than the integration step h = {h:.3e} s (lambda*h = {:.3}; RK4 is unstable beyond 2.78 \
                 and inaccurate beyond {REAL_AXIS_RESOLVED}): use {steps_key} >= {:.0}",
                1.0 / lambda,
                lambda * h,
                (steps_now * lambda * h / REAL_AXIS_RESOLVED).ceil()
            ),
        });
    }
    // The 1-DOF plant holds the spring force over a substep: the contact mode must be resolved by it.
    if scene.plant.contact_in_substeps() {
        let mut k_max = (
            scene.environment.stiffness_n_per_m,
            "environment.stiffness_n_per_m".to_string(),
        );
        for (i, ev) in scene.events.iter().enumerate() {
            if let EventSpec::Stiffness {
                stiffness_n_per_m, ..
            } = ev
                && *stiffness_n_per_m > k_max.0
            {
                k_max = (*stiffness_n_per_m, format!("events[{i}].stiffness_n_per_m"));
            }
        }
        let m = model.mechanics.moving_mass_kg;
        let omega = (k_max.0 / m).sqrt();
        if omega * h > OSCILLATION_RESOLVED {
            out.push(Warning {
                key: k_max.1,
                message: format!(
                    "the contact mode sqrt(k_e/m) = {omega:.3e} rad/s ({} N/m on {m} kg) is faster than the \
                     integration step h = {h:.3e} s resolves (omega*h = {}; RK4 is unstable beyond 2.83 and \
                     inaccurate beyond {OSCILLATION_RESOLVED}): use plant.substeps >= {}, or a stiffness \
                     below {:.3e} N/m",
                    crate::error::readable(k_max.0, 0),
                    crate::error::readable(omega * h, 3),
                    crate::error::readable((steps_now * omega * h / OSCILLATION_RESOLVED).ceil(), 0),
                    m * (OSCILLATION_RESOLVED / h).powi(2)
                ),
            });
        }
    }
    out
}

/// Where a material's mount cannot have its own damping at the scene's solver substep h = physics_dt_s /
/// solver_iterations: Rapier's implicit motor damps with c + k h, and pneuflex-multibody gives the motor
/// c - k h but never less than c / 10 (`pneuflex_multibody::spring::set_joint_spring`), so a mount with
/// k h > 0.9 c is damped with more than its material's c (by k h - 0.9 c): its impacts and ripple then
/// depend on the step.
pub fn mount_damping_warnings(scene: &Scene, mb: &crate::schema::MultibodySpec) -> Vec<Warning> {
    let h = mb.physics_dt_s / mb.solver_iterations.max(1) as f64;
    let mut mounts: Vec<(String, f64, f64)> = mb
        .materials
        .iter()
        .map(|m| (m.name.clone(), m.stiffness_n_per_m, m.damping_n_s_per_m))
        .collect();
    for ev in &scene.events {
        if let EventSpec::Stiffness {
            stiffness_n_per_m,
            material,
            damping_n_s_per_m,
            ..
        } = ev
        {
            // Absent: the material facing the flange (the initial one, as far as a check before the run knows).
            let Some(spec) = (match material {
                Some(n) => mb.materials.iter().find(|m| &m.name == n),
                None => mb.initial_material(),
            }) else {
                continue;
            };
            let c = damping_n_s_per_m.unwrap_or(spec.damping_n_s_per_m);
            mounts.push((spec.name.clone(), *stiffness_n_per_m, c));
        }
    }
    let mut out = Vec::new();
    for (name, k, c) in mounts {
        let numerical = k * h;
        if numerical <= 0.9 * c
            || out
                .iter()
                .any(|w: &Warning| w.message.contains(&format!("`{name}`")))
        {
            continue;
        }
        let damped = 0.1 * c + numerical;
        // Four significant digits, no exponent for the N s/m of a rig.
        let n = |x: f64| format!("{}", (x * 1e4).round() / 1e4);
        let h_max = 0.9 * c / k;
        out.push(Warning {
            key: "plant.physics_dt_s".into(),
            message: format!(
                "material `{name}` ({k:.3e} N/m, {c} N s/m): at the solver substep h = physics_dt_s / \
                 solver_iterations = {h:.3e} s its mount is damped with {} N s/m, not {c} (Rapier's implicit \
                 spring adds k h = {} N s/m and at most 0.9 c of it is taken back), so its impacts and ripple \
                 depend on the step; {}",
                n(damped),
                n(numerical),
                if c > 0.0 {
                    format!(
                        "for the material's damping use h <= 0.9 c / k = {h_max:.3e} s (physics_dt_s <= {:.3e} s at \
                         {} solver iterations)",
                        h_max * mb.solver_iterations as f64,
                        mb.solver_iterations
                    )
                } else {
                    "an undamped mount (damping_n_s_per_m = 0) is damped with k h at any step".into()
                }
            ),
        });
    }
    out
}
