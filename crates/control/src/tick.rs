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

/// What a loop host tells the loop after a step of a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// Go on.
    Continue,
    /// End the loop here.
    Stop,
}

/// What surrounds the controller in a loop: a simulated plant (scene runner, MuJoCo through the Python
/// bindings), the real rig under its supervisor, a plant on the host with the controller on a
/// microcontroller. [`run_loop`] calls these in the order `begin_tick → sense → update → record →
/// actuate → end_tick → advance`; a host implements only what surrounds the controller.
pub trait LoopHost {
    /// What ends the loop with an error (a bad event, a trace that cannot be written).
    type Error;
    /// Tick `k` (time `t`) starts. A simulation applies the events due; the rig waits for the tick's
    /// deadline and turns a stop request into a fault. `Stop` ends the loop before the tick.
    fn begin_tick(&mut self, k: u64, t: f64) -> Result<Flow, Self::Error>;
    /// The tick's sensors, or `None` when none arrived (the loop holds the last; the controller does not
    /// run before the first).
    fn sense(&mut self, k: u64, t: f64) -> Option<Sensors>;
    /// Whether the controller may run this tick (false once the host has latched a fault: the command is
    /// then the default, and the host's actuator puts the valve in its safe state).
    fn may_control(&self) -> bool {
        true
    }
    /// Runs the controller's update (`update` is `control_tick`). A host that must survive a faulty
    /// controller (the rig: a panic, a NaN command) guards it here and returns `None` after latching its
    /// fault; the default runs it as is.
    fn guard_update(
        &mut self,
        _k: u64,
        _t: f64,
        update: &mut dyn FnMut() -> (ValveCommand, Telemetry),
    ) -> Option<(ValveCommand, Telemetry)> {
        Some(update())
    }
    /// The host's own signals of the tick (after the loop's and the controller's in the row), recorded
    /// before the command is applied.
    fn record(&mut self, _row: &mut [f64]) {}
    /// Applies the command; returns `u` as applied (what the row records).
    fn actuate(&mut self, k: u64, t: f64, command: &ValveCommand, telemetry: &Telemetry) -> f64;
    /// The tick's row is complete: the host stores it (trace), shows it (observers) and checks it
    /// (divergence, invariants, the end of the run). `Stop` ends the loop after this tick.
    fn end_tick(&mut self, k: u64, t: f64, row: &mut [f64]) -> Result<Flow, Self::Error>;
    /// Moves the plant on by one tick (a simulation integrates; the rig's time passes in `begin_tick`).
    fn advance(&mut self, _dt: f64) {}
}

/// The one control loop (sense → update → record → actuate → advance): every loop of the project runs
/// here, and differs only in its [`LoopHost`]. `row` holds `LOOP_SIGNALS`, then the controller's own
/// signals, then the host's. The row's loop part carries the sensors held from the last sample (zero
/// before the first), the command as applied, and the controller's own signals read 0 on a tick it
/// did not run. Returns the number of ticks that ran to their end.
pub fn run_loop<H, C>(
    host: &mut H,
    controller: &mut C,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    dt: f64,
    row: &mut [f64],
) -> Result<u64, H::Error>
where
    H: LoopHost + ?Sized,
    C: Controller + ?Sized,
{
    let n_ctl = LOOP_SIGNALS.len() + controller.signals().len();
    debug_assert!(row.len() >= n_ctl);
    let mut last: Option<Sensors> = None;
    let mut k: u64 = 0;
    loop {
        // Tick times are k·dt, not a running sum, so a long run does not drift.
        let t = k as f64 * dt;
        if host.begin_tick(k, t)? == Flow::Stop {
            break;
        }
        if let Some(s) = host.sense(k, t) {
            last = Some(Sensors { t, ..s });
        }
        let setpoint = reference(t);
        let (ctl_row, host_row) = row.split_at_mut(n_ctl);
        ctl_row[LOOP_SIGNALS.len()..].fill(0.0);
        let mut result = None;
        if host.may_control()
            && let Some(s) = last
        {
            result = host.guard_update(k, t, &mut || {
                control_tick(&mut *controller, &s, &setpoint, dt, ctl_row)
            });
        }
        let (command, telemetry) = result.unwrap_or_default();
        host.record(host_row);
        let u = host.actuate(k, t, &command, &telemetry);
        let sensors = last.map(|s| Sensors { t, ..s }).unwrap_or(Sensors {
            t,
            ..Sensors::default()
        });
        write_loop_row(row, &sensors, &setpoint, &telemetry, u);
        let flow = host.end_tick(k, t, row)?;
        k += 1;
        if flow == Flow::Stop {
            break;
        }
        host.advance(dt);
    }
    Ok(k)
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
        // The adaptive law's g, p, d in SI (default units: mm and N).
        let a = AdaptiveParams::default();
        let law = c.law();
        assert_eq!(
            &row[8..],
            &[
                law.g() * a.position_unit_m,
                law.p() * a.position_unit_m / a.force_unit_n,
                law.d()
            ]
        );
        assert_eq!(c.signals().len(), 3);
    }
}

#[cfg(test)]
mod loop_tests {
    use super::*;
    use crate::signal::index;

    /// A proportional "controller" u = f_ref − f_e with one signal of its own (its error).
    struct Proportional {
        e: f64,
    }
    impl Controller for Proportional {
        fn update(&mut self, s: &Sensors, sp: &Setpoint, _dt: f64) -> ValveCommand {
            self.e = sp.f_ref - s.f_e;
            ValveCommand { u: self.e }
        }
        fn telemetry(&self) -> Telemetry {
            Telemetry::default()
        }
        fn reset(&mut self) {
            self.e = 0.0;
        }
        fn signals(&self) -> &'static [crate::signal::Signal] {
            &[crate::signal::Signal {
                name: "e",
                unit: "N",
                group: "force",
                description: "force error",
            }]
        }
        fn record(&self, out: &mut [f64]) {
            out[0] = self.e;
        }
    }

    /// A first-order force plant f_e' = (u − f_e)/τ integrated by explicit Euler, whose sensor misses
    /// tick 0 and tick 3, whose actuator clamps u to ±1, and which stops after tick 5.
    struct Host {
        f_e: f64,
        u: f64,
        rows: [[f64; 10]; 8],
        n: usize,
    }
    impl LoopHost for Host {
        type Error = ();
        fn begin_tick(&mut self, _k: u64, _t: f64) -> Result<Flow, ()> {
            Ok(Flow::Continue)
        }
        fn sense(&mut self, k: u64, _t: f64) -> Option<Sensors> {
            (k != 0 && k != 3).then_some(Sensors {
                f_e: self.f_e,
                ..Sensors::default()
            })
        }
        fn record(&mut self, row: &mut [f64]) {
            row[0] = self.u;
        }
        fn actuate(&mut self, _k: u64, _t: f64, c: &ValveCommand, _tel: &Telemetry) -> f64 {
            self.u = c.u.clamp(-1.0, 1.0);
            self.u
        }
        fn end_tick(&mut self, k: u64, _t: f64, row: &mut [f64]) -> Result<Flow, ()> {
            self.rows[self.n].copy_from_slice(row);
            self.n += 1;
            Ok(if k == 5 { Flow::Stop } else { Flow::Continue })
        }
        fn advance(&mut self, dt: f64) {
            self.f_e += dt / 0.5 * (self.u - self.f_e);
        }
    }

    #[test]
    fn the_loop_holds_the_last_sample_records_the_command_as_applied_and_stops_when_told() {
        let mut host = Host {
            f_e: 0.0,
            u: 0.0,
            rows: [[f64::NAN; 10]; 8],
            n: 0,
        };
        let mut c = Proportional { e: 0.0 };
        let mut reference = |_t: f64| Setpoint {
            f_ref: 3.0,
            x_d: 0.0,
        };
        let mut row = [f64::NAN; 10];
        let ticks = run_loop(&mut host, &mut c, &mut reference, 0.1, &mut row).unwrap();
        assert_eq!(ticks, 6);
        // Independent replay of the same sequence.
        let (mut f, mut u, mut held) = (0.0f64, 0.0f64, None::<f64>);
        for k in 0..6 {
            let r = host.rows[k];
            if k != 0 && k != 3 {
                held = Some(f);
            }
            let ran = held.is_some();
            let e = held.map(|h| 3.0 - h).unwrap_or(0.0);
            let u_before = u;
            u = if ran { e.clamp(-1.0, 1.0) } else { 0.0 };
            assert_eq!(r[index::T], k as f64 * 0.1, "tick {k}");
            assert_eq!(
                r[index::F_E],
                held.unwrap_or(0.0),
                "tick {k}: the held sample"
            );
            assert_eq!(r[index::U], u, "tick {k}: u as applied (clamped)");
            assert_eq!(
                r[LOOP_SIGNALS.len()],
                e,
                "tick {k}: the controller's own signal"
            );
            assert_eq!(
                r[LOOP_SIGNALS.len() + 1],
                u_before,
                "tick {k}: host record before actuate"
            );
            f += 0.1 / 0.5 * (u - f);
        }
    }
}
