//! `advance_together` (several plants stepped in packed arithmetic, the batched Gymnasium environment's
//! step) against each plant's own `advance`: every state, every control period, to the bit, with the
//! plants differing where an episode's domain randomisation makes them differ (mass, friction, the valve's
//! switching delay) and in command and load, through PWM edges, the laminar tail and the end stops.

use std::path::Path;

use pneuflex_pneumatics::{
    ActuatorSheet, ChamberState, Friction, OneDofModel, OneDofState, PACK, Together, ValveKind,
    advance_together,
};

const N: usize = PACK;

fn sheet(name: &str) -> OneDofModel {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../pneumatics")
        .join(name);
    ActuatorSheet::load(path)
        .expect("shipped actuator sheet")
        .model()
}

/// Eight plants of `base`, each with its own mass, friction and switching delay (plant 5 with stick-slip
/// friction).
fn plants(base: OneDofModel) -> [OneDofModel; N] {
    let mut models = smooth_plants(base);
    models[5].mechanics.friction = Friction::StickSlip {
        coulomb_n: 0.6,
        static_n: 1.0,
        stribeck_velocity_m_per_s: 0.005,
        stick_velocity_m_per_s: 1e-4,
    };
    models
}

/// Eight plants of `base` as [`plants`], all with the sheet's smooth friction, scaled per plant (plant 0
/// without Coulomb friction): their friction is computed packed too.
fn smooth_plants(base: OneDofModel) -> [OneDofModel; N] {
    std::array::from_fn(|i| {
        let mut m = base;
        m.mechanics.moving_mass_kg *= 0.6 + 0.2 * i as f64;
        m.mechanics.friction = m
            .mechanics
            .friction
            .scaled(0.25 * i as f64 + 0.25 * f64::from(i > 0));
        if let ValveKind::OnOffPwm {
            switching_delay_s, ..
        } = &mut m.actuator.valve.kind
        {
            *switching_delay_s *= 0.5 + 0.15 * i as f64;
        }
        m
    })
}

/// A state written out in full: `{:?}` prints each f64 in the shortest form that reads back to the same
/// bits, so two equal texts are two equal states to the bit (the valve's PWM clock included).
fn bits(s: &OneDofState) -> String {
    format!("{s:?}")
}

/// Runs `periods` control periods of 1 ms (10 substeps) of the plants alone and together, each plant on
/// a spring of its own stiffness, under commands from `command(k, i)`; asserts they agree to the bit after
/// every period; returns how often a plant sat on an end stop.
fn agree(models: &[OneDofModel; N], periods: u64, command: impl Fn(u64, usize) -> f64) -> usize {
    let start = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 2.8e5), 0.0);
    let spring = |i: usize, x: f64| -(400.0 + 300.0 * i as f64) * (x - 0.03).max(0.0);
    let gravity: [f64; N] = std::array::from_fn(|i| models[i].mechanics.gravity_force());
    let mut alone = [start; N];
    let mut together = [start; N];
    let mut on_stop = 0;
    for k in 0..periods {
        let u: [f64; N] = std::array::from_fn(|i| command(k, i));
        for (i, (m, s)) in models.iter().zip(alone.iter_mut()).enumerate() {
            m.advance(s, u[i], gravity[i], 1e-3, 10, |x| spring(i, x));
        }
        let plants = Together {
            models: std::array::from_fn(|i| &models[i]),
            states: together.each_mut(),
            u,
            gravity_n: gravity,
        };
        advance_together(plants, 1e-3, 10, &mut |i, x| spring(i, x));
        for i in 0..N {
            assert_eq!(
                bits(&alone[i]),
                bits(&together[i]),
                "plant {i} after period {k}"
            );
            let x = alone[i].x;
            on_stop += usize::from(x <= 0.0 || x >= models[i].actuator.cylinder.stroke_m);
        }
    }
    on_stop
}

#[test]
fn plants_stepped_together_are_each_plant_stepped_alone() {
    let models = plants(sheet("paper-actuator.toml"));
    // Commands that switch sign every 40 ms and differ per plant, with spells at full stroke.
    let on_stop = agree(&models, 3000, |k, i| {
        let phase = (k / 40 + i as u64) % 4;
        match phase {
            0 => 0.25 + 0.05 * i as f64,
            1 => -0.3,
            2 => 1.0,
            _ => -1.0,
        }
    });
    assert!(
        on_stop > 100,
        "the run should reach the end stops ({on_stop} plant-periods there)"
    );
}

#[test]
fn plants_with_smooth_friction_are_packed_to_the_bit_too() {
    // All smooth: the friction's tanh is computed for the eight at once.
    let models = smooth_plants(sheet("paper-actuator.toml"));
    agree(&models, 2000, |k, i| {
        0.3 * ((k as f64) * 0.004 + i as f64).sin() + 0.05 * (k % 7) as f64 - 0.15
    });
}

#[test]
fn the_proportional_valve_too() {
    let models = smooth_plants(sheet("paper-actuator-proportional.toml"));
    agree(&models, 1500, |k, i| {
        0.4 * ((k as f64) * 0.01 + i as f64).sin()
    });
}

#[test]
fn plants_of_different_actuators_are_stepped_one_by_one_alike() {
    let mut models = plants(sheet("paper-actuator.toml"));
    // Another supply pressure: the chamber constants differ, so the plants are not packed.
    models[3].actuator.supply.supply_pressure_pa *= 0.8;
    agree(&models, 500, |k, i| {
        if (k / 25 + i as u64).is_multiple_of(2) {
            0.3
        } else {
            -0.3
        }
    });
}
