//! The body of every control loop — simulation, real rig, processor-in-the-loop: the controller updated on
//! one tick's sensors and setpoint, and the tick's row written in the order the signals are declared
//! (`LOOP_SIGNALS`, then the controller's own). Loops differ only in what surrounds it: a simulated plant
//! integrates, the rig waits for the next tick under its supervisor.

use crate::io::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};
use crate::signal::{LOOP_SIGNALS, index};

/// Writes the loop's signals of a tick into `row[..LOOP_SIGNALS.len()]`; `u` is the command as applied.
pub fn write_loop_row(row: &mut [f64], s: &Sensors, sp: &Setpoint, tel: &Telemetry, u: f64) {
    let r = &mut row[..LOOP_SIGNALS.len()];
    r[index::T] = s.t;
    r[index::F_REF] = sp.f_ref;
    r[index::F_E] = s.f_e;
    r[index::X] = s.x;
    r[index::X_R] = tel.x_r;
    r[index::P_A] = s.p_a;
    r[index::P_B] = s.p_b;
    r[index::U] = u;
}

/// One tick: `controller.update`, then the row (`row.len()` = `LOOP_SIGNALS.len()` + the controller's own
/// signals). Returns the command and the telemetry for the plant.
pub fn control_tick<C: Controller + ?Sized>(
    controller: &mut C,
    sensors: &Sensors,
    setpoint: &Setpoint,
    dt: f64,
    row: &mut [f64],
) -> (ValveCommand, Telemetry) {
    let cmd = controller.update(sensors, setpoint, dt);
    let tel = controller.telemetry();
    write_loop_row(row, sensors, setpoint, &tel, cmd.u);
    controller.record(&mut row[LOOP_SIGNALS.len()..]);
    (cmd, tel)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{AdaptiveImpedanceController, AdaptiveParams, ImpedanceParams, PidParams};

    #[test]
    fn the_row_holds_the_loop_signals_then_the_controllers_own_in_declared_order() {
        let mut c = AdaptiveImpedanceController::new(
            ImpedanceParams::default(),
            AdaptiveParams::default(),
            PidParams::default(),
        )
        .unwrap();
        let s = Sensors {
            t: 0.5,
            x: 0.01,
            x_dot: 0.0,
            f_e: 3.0,
            p_a: 4e5,
            p_b: 3e5,
        };
        let sp = Setpoint {
            f_ref: 10.0,
            x_d: 0.0,
        };
        let mut row = [f64::NAN; 11];
        let (cmd, tel) = control_tick(&mut c, &s, &sp, 1e-3, &mut row);
        assert_eq!(&row[..8], &[0.5, 10.0, 3.0, 0.01, tel.x_r, 4e5, 3e5, cmd.u]);
        assert_eq!(&row[8..], &[tel.g, tel.p, tel.d]);
        assert_eq!(c.signals().len(), 3);
    }
}
