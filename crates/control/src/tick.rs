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

/// The most actuators one loop drives (a scene with more is refused when it is read): the loop holds each
/// actuator's last sample without allocating.
pub const MAX_ACTUATORS: usize = 16;

/// Where actuator `i`'s block starts in a row of a loop whose controllers declare `own[j]` signals each:
/// after `t`, every earlier actuator's loop signals (`LOOP_SIGNALS` but `t`) and own signals. Actuator 0's
/// block starts at `index::F_REF`, so a one-actuator row is `LOOP_SIGNALS`, then the controller's own.
pub fn block_start(own: impl IntoIterator<Item = usize>, i: usize) -> usize {
    1 + own
        .into_iter()
        .take(i)
        .map(|n| LOOP_SIGNALS.len() - 1 + n)
        .sum::<usize>()
}

/// What surrounds the controllers in a loop: a simulated plant (scene runner, MuJoCo through the Python
/// bindings), the real rig under its supervisor, a plant on the host with the controller on a
/// microcontroller. [`run_loop`] calls these in the order `begin_tick → sense → update → record →
/// actuate → end_tick → advance`; a host implements only what surrounds the controllers. A host of
/// several actuators is asked for each one's sensors and given each one's command, by its index in the
/// loop's controllers.
pub trait LoopHost {
    /// What ends the loop with an error (a bad event, a trace that cannot be written).
    type Error;
    /// Tick `k` (time `t`) starts. A simulation applies the events due; the rig waits for the tick's
    /// deadline and turns a stop request into a fault. `Stop` ends the loop before the tick.
    fn begin_tick(&mut self, k: u64, t: f64) -> Result<Flow, Self::Error>;
    /// Actuator `actuator`'s sensors this tick, or `None` when none arrived (the loop holds the last; the
    /// controller does not run before the first).
    fn sense(&mut self, k: u64, t: f64, actuator: usize) -> Option<Sensors>;
    /// Whether the controllers may run this tick (false once the host has latched a fault: the commands are
    /// then the default, and the host's actuator puts the valves in their safe state).
    fn may_control(&self) -> bool {
        true
    }
    /// Runs actuator `actuator`'s controller update (`update` is `control_tick`). A host that must survive a
    /// faulty controller (the rig: a panic, a NaN command) guards it here and returns `None` after latching
    /// its fault; the default runs it as is.
    fn guard_update(
        &mut self,
        _k: u64,
        _t: f64,
        _actuator: usize,
        update: &mut dyn FnMut() -> (ValveCommand, Telemetry),
    ) -> Option<(ValveCommand, Telemetry)> {
        Some(update())
    }
    /// The host's own signals of the tick (after every actuator's block in the row), recorded before the
    /// commands are applied.
    fn record(&mut self, _row: &mut [f64]) {}
    /// Applies actuator `actuator`'s command; returns `u` as applied (what the row records).
    fn actuate(
        &mut self,
        k: u64,
        t: f64,
        actuator: usize,
        command: &ValveCommand,
        telemetry: &Telemetry,
    ) -> f64;
    /// The tick's row is complete: the host stores it (trace), shows it (observers) and checks it
    /// (divergence, invariants, the end of the run). `Stop` ends the loop after this tick.
    fn end_tick(&mut self, k: u64, t: f64, row: &mut [f64]) -> Result<Flow, Self::Error>;
    /// Moves the plant on by one tick (a simulation integrates; the rig's time passes in `begin_tick`).
    fn advance(&mut self, _dt: f64) {}
}

/// The one control loop of one actuator (sense → update → record → actuate → advance): [`run_loops`]
/// with one controller. `row` holds `LOOP_SIGNALS`, then the controller's own signals, then the host's.
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
    run_loops(host, &mut [controller], &mut |_, t| reference(t), dt, row)
}

/// The one control loop (sense → update → record → actuate → advance) of one or several actuators, each
/// with its controller and its setpoints (`reference(i, t)`): every loop of the project runs here, and
/// differs only in its [`LoopHost`]. `row` holds `t`, then per actuator its block (`LOOP_SIGNALS` but `t`,
/// then its controller's own signals; [`block_start`]), then the host's. Each block carries the
/// actuator's sensors held from its last sample (zero before the first), its command as applied, and its
/// controller's own signals read 0 on a tick it did not run. Returns the number of ticks that ran to
/// their end. At most [`MAX_ACTUATORS`] controllers.
pub fn run_loops<H, C>(
    host: &mut H,
    controllers: &mut [&mut C],
    reference: &mut dyn FnMut(usize, f64) -> Setpoint,
    dt: f64,
    row: &mut [f64],
) -> Result<u64, H::Error>
where
    H: LoopHost + ?Sized,
    C: Controller + ?Sized,
{
    let n = controllers.len();
    assert!(
        n <= MAX_ACTUATORS,
        "{n} actuators in one loop, more than {MAX_ACTUATORS}"
    );
    let n_ctl = block_start(controllers.iter().map(|c| c.signals().len()), n);
    debug_assert!(row.len() >= n_ctl);
    let mut last: [Option<Sensors>; MAX_ACTUATORS] = [None; MAX_ACTUATORS];
    let mut out = [(
        ValveCommand::default(),
        Telemetry::default(),
        Setpoint::default(),
    ); MAX_ACTUATORS];
    let mut k: u64 = 0;
    loop {
        // Tick times are k·dt, not a running sum, so a long run does not drift.
        let t = k as f64 * dt;
        if host.begin_tick(k, t)? == Flow::Stop {
            break;
        }
        let (ctl_row, host_row) = row.split_at_mut(n_ctl);
        let mut at = 1;
        for (i, controller) in controllers.iter_mut().enumerate() {
            if let Some(s) = host.sense(k, t, i) {
                last[i] = Some(Sensors { t, ..s });
            }
            let setpoint = reference(i, t);
            let end = at + LOOP_SIGNALS.len() - 1 + controller.signals().len();
            // The block as control_tick writes it: t in front (restored below), then the block.
            let block = &mut ctl_row[at - 1..end];
            let t_before = block[0];
            block[LOOP_SIGNALS.len()..].fill(0.0);
            let mut result = None;
            if host.may_control()
                && let Some(s) = last[i]
            {
                result = host.guard_update(k, t, i, &mut || {
                    control_tick(&mut **controller, &s, &setpoint, dt, block)
                });
            }
            block[0] = t_before;
            let (command, telemetry) = result.unwrap_or_default();
            out[i] = (command, telemetry, setpoint);
            at = end;
        }
        host.record(host_row);
        let mut at = 1;
        for (i, controller) in controllers.iter().enumerate() {
            let (command, telemetry, setpoint) = out[i];
            let u = host.actuate(k, t, i, &command, &telemetry);
            let sensors = last[i].map(|s| Sensors { t, ..s }).unwrap_or(Sensors {
                t,
                ..Sensors::default()
            });
            let block = &mut row[at - 1..];
            let t_before = block[0];
            write_loop_row(block, &sensors, &setpoint, &telemetry, u);
            block[0] = t_before;
            at += LOOP_SIGNALS.len() - 1 + controller.signals().len();
        }
        row[0] = t;
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
        fn sense(&mut self, k: u64, _t: f64, _i: usize) -> Option<Sensors> {
            (k != 0 && k != 3).then_some(Sensors {
                f_e: self.f_e,
                ..Sensors::default()
            })
        }
        fn record(&mut self, row: &mut [f64]) {
            row[0] = self.u;
        }
        fn actuate(
            &mut self,
            _k: u64,
            _t: f64,
            _i: usize,
            c: &ValveCommand,
            _tel: &Telemetry,
        ) -> f64 {
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

#[cfg(test)]
mod several_tests {
    use super::*;
    use crate::signal::index;

    /// u = gain·(f_ref − f_e), recording its error as its own signal.
    struct Gain {
        gain: f64,
        e: f64,
    }
    impl Controller for Gain {
        fn update(&mut self, s: &Sensors, sp: &Setpoint, _dt: f64) -> ValveCommand {
            self.e = sp.f_ref - s.f_e;
            ValveCommand {
                u: self.gain * self.e,
            }
        }
        fn telemetry(&self) -> Telemetry {
            Telemetry::default()
        }
        fn reset(&mut self) {
            self.e = 0.0;
        }
        fn signals(&self) -> &'static [crate::signal::Signal] {
            const E: [crate::signal::Signal; 1] =
                [crate::signal::Signal::new("e", "N", "force", "force error")];
            &E
        }
        fn record(&self, out: &mut [f64]) {
            out[0] = self.e;
        }
    }

    /// Two first-order force plants f' = (u − f)/τ_i, coupled: actuator 1's sensor also reads half of
    /// actuator 0's force. Actuator 1's sensor misses tick 2. One host signal: the sum of the forces.
    struct Two {
        f: [f64; 2],
        u: [f64; 2],
        rows: [[f64; 20]; 6],
        n: usize,
    }
    impl LoopHost for Two {
        type Error = ();
        fn begin_tick(&mut self, _k: u64, _t: f64) -> Result<Flow, ()> {
            Ok(Flow::Continue)
        }
        fn sense(&mut self, k: u64, _t: f64, i: usize) -> Option<Sensors> {
            let f_e = if i == 0 {
                self.f[0]
            } else {
                self.f[1] + 0.5 * self.f[0]
            };
            (i == 0 || k != 2).then_some(Sensors {
                f_e,
                ..Sensors::default()
            })
        }
        fn record(&mut self, row: &mut [f64]) {
            row[0] = self.f[0] + self.f[1];
        }
        fn actuate(&mut self, _k: u64, _t: f64, i: usize, c: &ValveCommand, _: &Telemetry) -> f64 {
            self.u[i] = c.u.clamp(-1.0, 1.0);
            self.u[i]
        }
        fn end_tick(&mut self, k: u64, _t: f64, row: &mut [f64]) -> Result<Flow, ()> {
            self.rows[self.n][..row.len()].copy_from_slice(row);
            self.n += 1;
            Ok(if k == 4 { Flow::Stop } else { Flow::Continue })
        }
        fn advance(&mut self, dt: f64) {
            self.f[0] += dt / 0.5 * (self.u[0] - self.f[0]);
            self.f[1] += dt / 0.2 * (self.u[1] - self.f[1]);
        }
    }

    #[test]
    fn each_actuator_has_its_block_after_t_with_its_own_sample_setpoint_and_command() {
        let mut host = Two {
            f: [0.0; 2],
            u: [0.0; 2],
            rows: [[f64::NAN; 20]; 6],
            n: 0,
        };
        let (mut a, mut b) = (Gain { gain: 0.4, e: 0.0 }, Gain { gain: 2.0, e: 0.0 });
        let mut cs: [&mut dyn Controller; 2] = [&mut a, &mut b];
        let refs = [2.0, -1.5];
        let mut reference = |i: usize, _t: f64| Setpoint {
            f_ref: refs[i],
            x_d: 0.0,
        };
        // t | 7 + 1 | 7 + 1 | host 1
        let width = 1 + 8 + 8 + 1;
        assert_eq!(block_start([1, 1], 1), 9);
        let mut row = [f64::NAN; 18];
        let ticks = run_loops(&mut host, &mut cs, &mut reference, 0.1, &mut row).unwrap();
        assert_eq!(ticks, 5);
        // Independent replay.
        let mut f = [0.0f64; 2];
        let mut held1 = None::<f64>;
        for k in 0..5 {
            let r = &host.rows[k][..width];
            let sensed = [f[0], f[1] + 0.5 * f[0]];
            if k != 2 {
                held1 = Some(sensed[1]);
            }
            let e = [refs[0] - sensed[0], refs[1] - held1.unwrap()];
            let sum_before = f[0] + f[1];
            let u = [(0.4 * e[0]).clamp(-1.0, 1.0), (2.0 * e[1]).clamp(-1.0, 1.0)];
            assert_eq!(r[index::T], k as f64 * 0.1, "tick {k}");
            for (i, start) in [(0, 1), (1, 9)] {
                let blk = &r[start - 1..];
                assert_eq!(blk[index::F_REF], refs[i], "tick {k} actuator {i}");
                let f_e = if i == 0 { sensed[0] } else { held1.unwrap() };
                assert_eq!(
                    blk[index::F_E],
                    f_e,
                    "tick {k} actuator {i}: its held sample"
                );
                assert_eq!(blk[index::U], u[i], "tick {k} actuator {i}: u as applied");
                assert_eq!(
                    blk[LOOP_SIGNALS.len()],
                    e[i],
                    "tick {k} actuator {i}: its own signal"
                );
            }
            assert_eq!(
                r[17], sum_before,
                "tick {k}: the host's signal after the blocks"
            );
            f[0] += 0.1 / 0.5 * (u[0] - f[0]);
            f[1] += 0.1 / 0.2 * (u[1] - f[1]);
        }
    }
}
