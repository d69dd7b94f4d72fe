//! What the multibody tests share: a cylinder with a zero-lap proportional valve (u = 0 closes both
//! chambers), sized by the test.

use pneuflex_pneumatics::{
    Actuator, Cylinder, Gas, Orifice, P_ATM, Supply, T_DEFAULT, ValveKind, ValveModel,
};

/// A cylinder of `bore_m`, `rod_m` and `stroke_m` with `dead_volume_m3` on each side, fed at `supply_pa`
/// (absolute) through a 1e-8 m³/(s Pa), b = 0.3 valve that responds at once.
pub fn cylinder(
    bore_m: f64,
    rod_m: f64,
    stroke_m: f64,
    dead_volume_m3: f64,
    supply_pa: f64,
) -> Actuator {
    Actuator {
        cylinder: Cylinder {
            bore_m,
            rod_m,
            stroke_m,
            dead_volume_a_m3: dead_volume_m3,
            dead_volume_b_m3: dead_volume_m3,
        },
        gas: Gas::default(),
        valve: ValveModel {
            orifice: Orifice {
                sonic_conductance_m3_per_s_pa: 1.0e-8,
                critical_pressure_ratio: 0.3,
            },
            paths: [None; 4],
            underlap: 0.0,
            kind: ValveKind::Proportional {
                response_time_s: 0.0,
            },
        },
        supply: Supply {
            supply_pressure_pa: supply_pa,
            supply_temperature_k: T_DEFAULT,
            atmosphere_pressure_pa: P_ATM,
            atmosphere_temperature_k: T_DEFAULT,
        },
    }
}
