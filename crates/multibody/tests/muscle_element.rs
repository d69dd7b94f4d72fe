//! The muscle's force element as the engine steps it (docs/multibody.md "Actuator families"): a closed
//! muscle stretched through physics steps keeps p V^n (its chamber follows the length the engine gives it,
//! substep by substep), it pulls (its force is -T), and its travel admits slack but not a braid pulled past
//! straight fibres.

use core::f64::consts::PI;

use pneuflex_multibody::actuator::pneuflex_muscle::{
    Braid, BraidFriction, ChamberState, Feed, Muscle, MuscleChamber,
};
use pneuflex_multibody::{ActuatorFamily, AxialActuator, actuator::MuscleForceElement};
use pneuflex_pneumatics::{Gas, Supply};

/// D_rest = 10 mm, L0 = 200 mm, alpha0 = 30 deg, k = 1.25, 3 cm^3 dead volume, no friction.
fn element(n: f64, substeps: u32) -> MuscleForceElement {
    let chamber = MuscleChamber {
        muscle: Muscle {
            braid: Braid {
                rest_diameter_m: 0.010,
                rest_length_m: 0.200,
                rest_braid_angle_rad: 30f64.to_radians(),
                end_effect_factor: 1.25,
            },
            friction: BraidFriction::NONE,
            stretch_stiffness_n_per_m: 2.0e4,
            dead_volume_m3: 3.0e-6,
        },
        gas: Gas {
            gas_constant_j_per_kg_k: 287.05,
            polytropic_exponent: n,
        },
        supply: Supply {
            supply_pressure_pa: 601_325.0,
            supply_temperature_k: 293.15,
            atmosphere_pressure_pa: 101_325.0,
            atmosphere_temperature_k: 293.15,
        },
    };
    MuscleForceElement::new(
        chamber,
        Feed::Closed,
        ChamberState {
            pressure_pa: 3.0e5,
            temperature_k: 293.15,
        },
        substeps,
    )
}

/// (M1), (M2) by hand: b = L0 / cos(alpha0), n pi D_rest = b sin(alpha0), V = b^3 sin^2 cos / (4 pi n^2).
fn volume(length_m: f64) -> f64 {
    let a0 = 30f64.to_radians();
    let b = 0.2 / a0.cos();
    let turns = b * a0.sin() / (PI * 0.010);
    let c = length_m / b;
    3.0e-6 + b.powi(3) * (1.0 - c * c) * c / (4.0 * PI * turns * turns)
}

#[test]
fn a_closed_muscle_stretched_through_physics_steps_keeps_p_v_to_the_n() {
    // From eps = 0.20 to eps = 0.02 in 0.05 s: mount strokes from L_min = L0 (1 - eps_max).
    let (l1, l2, duration) = (0.16, 0.196, 0.05);
    for n in [1.4, 1.0] {
        let want = 3.0e5 * (volume(l1) / volume(l2)).powf(n);
        for (steps, substeps) in [(50, 10), (100, 10), (50, 20)] {
            let mut el = element(n, substeps);
            let l_min = el.contracted_length_m();
            let (dt, rate) = (duration / steps as f64, (l2 - l1) / duration);
            for i in 0..steps {
                let x = l1 + rate * dt * i as f64 - l_min;
                let f = el.force(x, rate, dt);
                assert!(f < 0.0, "a muscle pulls: {f} N at step {i}");
            }
            let mut p = [0.0];
            el.read_sensors(&mut p);
            let rel = (p[0] - want).abs() / want;
            assert!(
                rel < 1e-9,
                "n {n}, {steps} steps of {substeps}: {} vs {want} Pa",
                p[0]
            );
        }
    }
}

#[test]
fn a_muscle_admits_slack_but_not_fibres_pulled_past_straight() {
    let el = element(1.4, 10);
    let (l_min, stroke) = (el.contracted_length_m(), el.stroke_m());
    // L0 = L_min + stroke; eps_max = (1 - 1/(sqrt(3) cos 30 deg)) / 1.25 = (1/3) / 1.25 (M6).
    assert!((stroke - 0.2 * (1.0 / 3.0) / 1.25).abs() < 1e-12);
    assert!(
        el.admits_stroke(-0.5 * l_min, stroke),
        "slack: anchors closer than L_min"
    );
    let straight = 0.2 / 30f64.to_radians().cos();
    assert!(el.admits_stroke(straight - l_min - 1e-6, stroke));
    assert!(!el.admits_stroke(straight - l_min + 1e-6, stroke));
    assert!(!el.admits_stroke(-l_min, stroke), "the anchors met");
    assert_eq!(el.state().len(), MuscleForceElement::STATE_LEN);
    let mut restored = element(1.4, 10);
    assert!(restored.set_state(&el.state()));
    assert!(!restored.set_state(&[f64::NAN; MuscleForceElement::STATE_LEN]));
    assert!(el.check_invariants(0.01, stroke).is_ok());
}
