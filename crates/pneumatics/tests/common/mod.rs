//! Shared test fixtures: a 16 mm cylinder on a 0.5 MPa supply (numbers independent of the TOML files).
#![allow(dead_code)]

use pneuflex_pneumatics::*;

pub const P_S: f64 = 601_325.0;

pub fn cylinder() -> Cylinder {
    Cylinder {
        bore_m: 0.016,
        rod_m: 0.005,
        stroke_m: 0.05,
        dead_volume_a_m3: 3.5e-6,
        dead_volume_b_m3: 3.5e-6,
    }
}

pub fn supply() -> Supply {
    Supply {
        supply_pressure_pa: P_S,
        supply_temperature_k: 293.15,
        atmosphere_pressure_pa: 101_325.0,
        atmosphere_temperature_k: 293.15,
    }
}

pub fn orifice() -> Orifice {
    Orifice {
        sonic_conductance_m3_per_s_pa: 5e-9,
        critical_pressure_ratio: 0.3,
    }
}

pub fn proportional(underlap: f64, tau: f64) -> ValveModel {
    ValveModel {
        orifice: orifice(),
        paths: [None; 4],
        underlap,
        kind: ValveKind::Proportional {
            response_time_s: tau,
        },
    }
}

pub fn pwm(freq: f64, delay: f64) -> ValveModel {
    ValveModel {
        orifice: orifice(),
        paths: [None; 4],
        underlap: 0.0,
        kind: ValveKind::OnOffPwm {
            pwm_frequency_hz: freq,
            switching_delay_s: delay,
        },
    }
}

pub fn actuator(valve: ValveModel, n: f64) -> Actuator {
    Actuator {
        cylinder: cylinder(),
        gas: Gas {
            gas_constant_j_per_kg_k: 287.05,
            polytropic_exponent: n,
        },
        valve,
        supply: supply(),
    }
}

pub fn model(valve: ValveModel, friction: Friction, alpha_deg: f64) -> OneDofModel {
    OneDofModel {
        actuator: actuator(valve, 1.4),
        mechanics: Mechanics {
            moving_mass_kg: 0.6,
            viscous_n_s_per_m: 20.0,
            friction,
            alpha_rad: alpha_deg.to_radians(),
            gravity_m_per_s2: 9.80665,
        },
        effects: Effects::default(),
    }
}

pub fn no_coulomb() -> Friction {
    Friction::Smooth {
        coulomb_n: 0.0,
        smooth_velocity_m_per_s: 1e-3,
    }
}
