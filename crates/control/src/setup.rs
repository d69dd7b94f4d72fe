//! What a controller needs to be built where there is no file and no heap (the board): its kind as a
//! code and its parameters as numbered values, and the controller built from them. The protocol carries
//! the code and the values (CtrlStart, CtrlParam: docs/protocol.md §5); the board calls
//! [`ControllerSetup::from_params`] and [`ControllerSetup::build`]. A controller that runs on the board is
//! a variant here: one arm in each function below, and nothing in the protocol or the firmware.

use crate::adaptive::{AdaptiveParams, LambdaDSign, Sigma1Sign, VelocitySource};
use crate::controllers::{AdaptiveImpedanceController, ImpedanceController};
use crate::error::ParamError;
use crate::impedance::ImpedanceParams;
use crate::io::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};
use crate::pid::{AntiWindup, PidParams};
use crate::signal::Signal;

/// Parameter ids: the fields of this crate's parameter structs, as the wire numbers them.
pub mod param {
    /// ImpedanceParams: m_d, b_d, k_d.
    pub const IMPEDANCE: [u8; 3] = [1, 2, 3];
    /// PidParams: kp, ki, kd, derivative filter, u_min, u_max, anti-windup (0 clamping, 1 back-calculation),
    /// tracking time (back-calculation only).
    pub const PID: [u8; 8] = [10, 11, 12, 13, 14, 15, 16, 17];
    /// AdaptiveParams in declaration order: λp, λd, μ1, μ2, μ3, σ1, σ2, σ3, force unit, position unit,
    /// λd sign (0 from ė, 1 as printed), σ1 sign (0 leakage, 1 as printed), adapt in contact only (0/1),
    /// contact threshold, velocity source (0 measured, 1 impedance filter), g_max, p_max, d_max.
    pub const ADAPTIVE: [u8; 18] = [
        20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37,
    ];
    /// One past the largest id: a receiver holds this many values.
    pub const IDS: usize = 38;
}

/// Most parameters a setup sends.
pub const MAX_PARAMS: usize = 3 + 8 + 18;

/// Which controller to build, with its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ControllerSetup {
    /// Impedance filter + PID.
    Impedance {
        /// Target impedance.
        impedance: ImpedanceParams,
        /// Inner loop.
        pid: PidParams,
    },
    /// Impedance filter + adaptive law + PID.
    Adaptive {
        /// Target impedance.
        impedance: ImpedanceParams,
        /// Adaptive law.
        adaptive: AdaptiveParams,
        /// Inner loop.
        pid: PidParams,
    },
}

/// Why parameters do not make a setup.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetupError {
    /// The parameter with this id is missing, or a choice (0/1) holds another value.
    Param(u8),
    /// No controller has this code.
    Kind(u8),
}

fn flag(b: bool) -> f64 {
    if b { 1.0 } else { 0.0 }
}

impl ControllerSetup {
    /// The kind's code (CtrlStart's `controller`).
    pub fn code(&self) -> u8 {
        match self {
            ControllerSetup::Impedance { .. } => 1,
            ControllerSetup::Adaptive { .. } => 2,
        }
    }

    /// The parameters to send, as (id, value) in order; returns the array and how many are used.
    pub fn params(&self) -> ([(u8, f64); MAX_PARAMS], usize) {
        let (imp, pid, ad) = match *self {
            ControllerSetup::Impedance { impedance, pid } => (impedance, pid, None),
            ControllerSetup::Adaptive {
                impedance,
                adaptive,
                pid,
            } => (impedance, pid, Some(adaptive)),
        };
        let mut out = [(0, 0.0); MAX_PARAMS];
        let mut n = 0;
        let mut push = |id: u8, value: f64| {
            out[n] = (id, value);
            n += 1;
        };
        let i = param::IMPEDANCE;
        push(i[0], imp.m_d_kg);
        push(i[1], imp.b_d_ns_per_m);
        push(i[2], imp.k_d_n_per_m);
        let p = param::PID;
        push(p[0], pid.kp_per_m);
        push(p[1], pid.ki_per_m_s);
        push(p[2], pid.kd_s_per_m);
        push(p[3], pid.derivative_filter_s);
        push(p[4], pid.u_min);
        push(p[5], pid.u_max);
        match pid.anti_windup {
            AntiWindup::Clamping => push(p[6], 0.0),
            AntiWindup::BackCalculation { tracking_time_s } => {
                push(p[6], 1.0);
                push(p[7], tracking_time_s);
            }
        }
        if let Some(a) = ad {
            let values = [
                a.lambda_p,
                a.lambda_d,
                a.mu1,
                a.mu2,
                a.mu3,
                a.sigma1,
                a.sigma2,
                a.sigma3,
                a.force_unit_n,
                a.position_unit_m,
                flag(a.lambda_d_sign == LambdaDSign::AsPrinted),
                flag(a.sigma1_sign == Sigma1Sign::AsPrinted),
                flag(a.adapt_in_contact_only),
                a.contact_threshold_n,
                flag(a.velocity_source == VelocitySource::ImpedanceFilter),
                a.g_max_m,
                a.p_max_m_per_n,
                a.d_max_s,
            ];
            for (id, v) in param::ADAPTIVE.into_iter().zip(values) {
                push(id, v);
            }
        }
        (out, n)
    }

    /// The setup of kind `code` from the values received (`value(id)`: None if that id never came). The
    /// numbers are checked by the controller's constructor in [`ControllerSetup::build`].
    pub fn from_params(code: u8, value: impl Fn(u8) -> Option<f64>) -> Result<Self, SetupError> {
        let get = |id: u8| value(id).ok_or(SetupError::Param(id));
        match code {
            1 => Ok(ControllerSetup::Impedance {
                impedance: impedance_from(&get)?,
                pid: pid_from(&get)?,
            }),
            2 => Ok(ControllerSetup::Adaptive {
                impedance: impedance_from(&get)?,
                pid: pid_from(&get)?,
                adaptive: adaptive_from(&get)?,
            }),
            other => Err(SetupError::Kind(other)),
        }
    }

    /// The controller, its parameters checked by its constructor.
    pub fn build(&self) -> Result<SetUpController, ParamError> {
        Ok(match *self {
            ControllerSetup::Impedance { impedance, pid } => {
                SetUpController::Impedance(ImpedanceController::new(impedance, pid)?)
            }
            ControllerSetup::Adaptive {
                impedance,
                adaptive,
                pid,
            } => SetUpController::Adaptive(AdaptiveImpedanceController::new(
                impedance, adaptive, pid,
            )?),
        })
    }
}

/// A value the receiver holds, or the id it lacks.
type Get<'a> = &'a dyn Fn(u8) -> Result<f64, SetupError>;

/// A 0/1 choice: any other value is refused by its id.
fn choice(get: Get<'_>, id: u8) -> Result<bool, SetupError> {
    let v = get(id)?;
    if v == 0.0 {
        Ok(false)
    } else if v == 1.0 {
        Ok(true)
    } else {
        Err(SetupError::Param(id))
    }
}

fn impedance_from(get: Get<'_>) -> Result<ImpedanceParams, SetupError> {
    let i = param::IMPEDANCE;
    Ok(ImpedanceParams {
        m_d_kg: get(i[0])?,
        b_d_ns_per_m: get(i[1])?,
        k_d_n_per_m: get(i[2])?,
    })
}

fn pid_from(get: Get<'_>) -> Result<PidParams, SetupError> {
    let p = param::PID;
    Ok(PidParams {
        kp_per_m: get(p[0])?,
        ki_per_m_s: get(p[1])?,
        kd_s_per_m: get(p[2])?,
        derivative_filter_s: get(p[3])?,
        u_min: get(p[4])?,
        u_max: get(p[5])?,
        anti_windup: if choice(get, p[6])? {
            AntiWindup::BackCalculation {
                tracking_time_s: get(p[7])?,
            }
        } else {
            AntiWindup::Clamping
        },
    })
}

fn adaptive_from(get: Get<'_>) -> Result<AdaptiveParams, SetupError> {
    let a = param::ADAPTIVE;
    Ok(AdaptiveParams {
        lambda_p: get(a[0])?,
        lambda_d: get(a[1])?,
        mu1: get(a[2])?,
        mu2: get(a[3])?,
        mu3: get(a[4])?,
        sigma1: get(a[5])?,
        sigma2: get(a[6])?,
        sigma3: get(a[7])?,
        force_unit_n: get(a[8])?,
        position_unit_m: get(a[9])?,
        lambda_d_sign: if choice(get, a[10])? {
            LambdaDSign::AsPrinted
        } else {
            LambdaDSign::FromEdot
        },
        sigma1_sign: if choice(get, a[11])? {
            Sigma1Sign::AsPrinted
        } else {
            Sigma1Sign::Leakage
        },
        adapt_in_contact_only: choice(get, a[12])?,
        contact_threshold_n: get(a[13])?,
        velocity_source: if choice(get, a[14])? {
            VelocitySource::ImpedanceFilter
        } else {
            VelocitySource::Measured
        },
        g_max_m: get(a[15])?,
        p_max_m_per_n: get(a[16])?,
        d_max_s: get(a[17])?,
    })
}

/// A controller built from a setup, held by value (no heap to box it in).
// The session that holds it lives in the board's main frame; its stack peak is measured (docs/firmware.md).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
pub enum SetUpController {
    /// Impedance filter + PID.
    Impedance(ImpedanceController),
    /// Impedance filter + adaptive law + PID.
    Adaptive(AdaptiveImpedanceController),
}

impl SetUpController {
    fn inner(&self) -> &dyn Controller {
        match self {
            SetUpController::Impedance(c) => c,
            SetUpController::Adaptive(c) => c,
        }
    }

    fn inner_mut(&mut self) -> &mut dyn Controller {
        match self {
            SetUpController::Impedance(c) => c,
            SetUpController::Adaptive(c) => c,
        }
    }
}

impl Controller for SetUpController {
    fn update(&mut self, sensors: &Sensors, setpoint: &Setpoint, dt: f64) -> ValveCommand {
        self.inner_mut().update(sensors, setpoint, dt)
    }

    fn telemetry(&self) -> Telemetry {
        self.inner().telemetry()
    }

    fn reset(&mut self) {
        self.inner_mut().reset()
    }

    fn signals(&self) -> &'static [Signal] {
        self.inner().signals()
    }

    fn record(&self, out: &mut [f64]) {
        self.inner().record(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every setup comes back from its own parameters; a missing one, a choice that is neither 0 nor 1 and
    /// an unknown code are refused by id and code.
    #[test]
    fn a_setup_comes_back_from_its_parameters_and_bad_ones_are_named() {
        let mut adaptive = AdaptiveParams::paper();
        adaptive.adapt_in_contact_only = true;
        adaptive.velocity_source = VelocitySource::ImpedanceFilter;
        let pid = PidParams {
            anti_windup: AntiWindup::BackCalculation {
                tracking_time_s: 0.05,
            },
            ..PidParams::default()
        };
        for setup in [
            ControllerSetup::Impedance {
                impedance: ImpedanceParams::default(),
                pid: PidParams::default(),
            },
            ControllerSetup::Adaptive {
                impedance: ImpedanceParams::default(),
                adaptive,
                pid,
            },
        ] {
            let (params, n) = setup.params();
            let mut values = [None; param::IDS];
            for &(id, v) in &params[..n] {
                assert!(values[usize::from(id)].is_none(), "id {id} sent twice");
                values[usize::from(id)] = Some(v);
            }
            let back = ControllerSetup::from_params(setup.code(), |id| values[usize::from(id)]);
            assert_eq!(back, Ok(setup));
            let built = setup.build().unwrap();
            assert_eq!(built.signals().len(), setup.code() as usize * 3 - 3);
            let mut missing = values;
            missing[usize::from(param::PID[2])] = None;
            assert_eq!(
                ControllerSetup::from_params(setup.code(), |id| missing[usize::from(id)]),
                Err(SetupError::Param(param::PID[2]))
            );
            let mut not_a_choice = values;
            not_a_choice[usize::from(param::PID[6])] = Some(0.5);
            assert_eq!(
                ControllerSetup::from_params(setup.code(), |id| not_a_choice[usize::from(id)]),
                Err(SetupError::Param(param::PID[6]))
            );
            assert_eq!(
                ControllerSetup::from_params(9, |id| values[usize::from(id)]),
                Err(SetupError::Kind(9))
            );
            // The kind is read first: it says which parameters must have come.
            assert_eq!(
                ControllerSetup::from_params(9, |_| None),
                Err(SetupError::Kind(9))
            );
        }
    }

    /// The built controller is the one the host builds: the same commands, tick for tick.
    #[test]
    fn a_set_up_controller_updates_as_the_host_built_one() {
        let setup = ControllerSetup::Adaptive {
            impedance: ImpedanceParams::default(),
            adaptive: AdaptiveParams::paper(),
            pid: PidParams::default(),
        };
        let mut board = setup.build().unwrap();
        let mut host = AdaptiveImpedanceController::new(
            ImpedanceParams::default(),
            AdaptiveParams::paper(),
            PidParams::default(),
        )
        .unwrap();
        let sp = Setpoint {
            f_ref: 20.0,
            x_d: 0.01,
        };
        for k in 0..200 {
            let s = Sensors {
                x: 0.01 + 1e-4 * k as f64,
                x_dot: 0.01,
                f_e: 15.0 + 0.1 * k as f64,
                ..Sensors::default()
            };
            let a = board.update(&s, &sp, 1e-3);
            let b = host.update(&s, &sp, 1e-3);
            assert_eq!(a.u.to_bits(), b.u.to_bits(), "tick {k}");
        }
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        board.record(&mut a);
        host.record(&mut b);
        assert_eq!(a, b);
    }
}
