//! The controller that runs on the board: a `pneuflex_control::Controller` whose `update` sends the tick's
//! sensors to the firmware and returns the valve command the firmware computed. The scene runner drives it
//! exactly as it drives a controller on the host, so the plant, the events, the trace and the metrics are the
//! simulation's own.

use pneuflex_control::ControllerSetup;
use pneuflex_control::{
    Controller, Sensors, Setpoint, SetpointSchedule, Signal, Telemetry, ValveCommand,
};
use pneuflex_protocol::ctrl::{
    MAX_SIGNALS, OutputPayload, SafePayload, SensorsPayload, StartPayload, ready, setup_crc_update,
};
use pneuflex_protocol::{Message, ValveMode, ValvePayload, crc::CRC16_INIT, fault_code};

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use crate::PilError;
use crate::link::Link;
use crate::observe::Live;

/// Per-update cost on the board clock (virtual ns under `-icount shift=0` = instructions).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Cost {
    /// Updates measured.
    pub updates: u64,
    /// Smallest, ns.
    pub min_ns: u32,
    /// Mean, ns.
    pub mean_ns: f64,
    /// Largest, ns.
    pub max_ns: u32,
}

/// A human name of a fault code.
pub fn reason_name(code: u8) -> &'static str {
    match code {
        fault_code::HOST_SILENT => "host silent past the watchdog",
        fault_code::CRC => "too many bad frames",
        fault_code::PANIC => "firmware panic",
        fault_code::HOST_REQUEST => "host request",
        _ => "board fault",
    }
}

/// The firmware's controller, driven over the link (its own, or one shared by a board's several
/// controllers, each addressed by its channel: docs/protocol.md §5, "Several controllers").
pub struct FirmwareController {
    link: Rc<RefCell<Link>>,
    /// The board's channel of this controller (`None`: the board's one controller, no CtrlChannel sent).
    channel: Option<u8>,
    tick: u32,
    signals: &'static [Signal],
    telemetry: Telemetry,
    /// The controller's own signals of the last output, in declared order.
    own: [f64; MAX_SIGNALS],
    /// The first link or firmware error; after it every update returns u = 0 and a non-finite x_r, which
    /// stops the scene runner at once.
    pub error: Option<PilError>,
    /// Ticks where the board's own setpoint differed from the host's, and the first such tick.
    pub setpoint_mismatches: (u64, Option<u32>),
    sum_ns: f64,
    cost: Cost,
    /// Each tick's output as received.
    pub outputs: Vec<OutputPayload>,
    live: Rc<Cell<Live>>,
}

/// The setup a scene run describes ([`pneuflex_scene::schema::RunSpec::board_setup`]), refused with the
/// run's name and key.
pub fn setup_of(run: &pneuflex_scene::schema::RunSpec) -> Result<ControllerSetup, PilError> {
    run.board_setup()
        .map_err(|e| PilError::Setup(format!("run `{}`: {e}", run.name)))
}

/// Uploads the setup and starts the controller; Ok once the board answered Ready OK.
pub fn start(
    link: &mut Link,
    setup: &ControllerSetup,
    schedule: &SetpointSchedule,
    dt_s: f64,
    watchdog_ms: u16,
) -> Result<(), PilError> {
    let mut crc = CRC16_INIT;
    let (params, n) = pneuflex_protocol::ctrl::param_payloads(setup);
    let segments: Vec<_> = pneuflex_protocol::ctrl::segments(schedule).collect();
    for m in params[..n]
        .iter()
        .map(|&p| Message::CtrlParam(p))
        .chain(segments.iter().map(|&s| Message::CtrlSegment(s)))
    {
        crc = setup_crc_update(crc, &m);
        link.send(&m)?;
    }
    link.send(&Message::CtrlStart(StartPayload {
        controller: setup.code(),
        dt_s,
        watchdog_ms,
        safe_mode: ValveMode::SafeVent,
        n_params: n as u8,
        n_segments: segments.len() as u8,
        setup_crc: crc,
    }))?;
    loop {
        match link.recv()?.msg {
            Message::CtrlReady(r) if r.result == ready::OK => return Ok(()),
            Message::CtrlReady(r) => {
                return Err(PilError::Setup(format!(
                    "the board refused the setup: code {} detail {} (docs/protocol.md §5)",
                    r.result, r.detail
                )));
            }
            _ => {}
        }
    }
}

/// Waits for the board's Safe frame; returns it with the text the board sent before it (a panic message)
/// and the outputs it sent meanwhile.
pub fn await_safe(link: &mut Link) -> Result<(SafePayload, String), PilError> {
    let mut text = Vec::new();
    loop {
        match link.recv()?.msg {
            Message::Safe(s) => return Ok((s, String::from_utf8_lossy(&text).into_owned())),
            Message::Text(t) => text.extend_from_slice(t.text()),
            _ => {}
        }
    }
}

impl FirmwareController {
    /// A started firmware controller; `signals` are the controller's own recorded signals (the host
    /// controller of the same kind declares them).
    pub fn new(link: Link, signals: &'static [Signal]) -> Self {
        Self::on(Rc::new(RefCell::new(link)), None, signals)
    }

    /// The started controller of channel `channel` on a board of several, over the board's shared link.
    pub fn on_channel(link: Rc<RefCell<Link>>, channel: u8, signals: &'static [Signal]) -> Self {
        Self::on(link, Some(channel), signals)
    }

    fn on(link: Rc<RefCell<Link>>, channel: Option<u8>, signals: &'static [Signal]) -> Self {
        Self {
            link,
            channel,
            tick: 0,
            signals,
            telemetry: Telemetry::default(),
            own: [0.0; MAX_SIGNALS],
            error: None,
            setpoint_mismatches: (0, None),
            sum_ns: 0.0,
            cost: Cost::default(),
            outputs: Vec::new(),
            live: Rc::default(),
        }
    }

    /// The link counters and the last update's cost after each tick, for observers ([`crate::observe`]).
    pub fn live(&self) -> Rc<Cell<Live>> {
        self.live.clone()
    }

    /// The per-update cost so far.
    pub fn cost(&self) -> Cost {
        Cost {
            mean_ns: if self.cost.updates > 0 {
                self.sum_ns / self.cost.updates as f64
            } else {
                0.0
            },
            ..self.cost
        }
    }

    /// The link's counters.
    pub fn link_stats(&self) -> crate::link::LinkStats {
        self.link.borrow().stats()
    }

    /// Ends the run: commands the safe state (the board parks the valve) and returns the board's report.
    pub fn finish(&mut self) -> Result<SafePayload, PilError> {
        let mut link = self.link.borrow_mut();
        link.send(&Message::Valve(ValvePayload {
            tick: self.tick,
            duty_q15: 0,
            mode: ValveMode::SafeVent,
        }))?;
        let (s, _) = await_safe(&mut link)?;
        Ok(s)
    }

    fn exchange(&mut self, s: &Sensors, sp: &Setpoint) -> Result<OutputPayload, PilError> {
        let link = self.link.clone();
        let mut link = link.borrow_mut();
        if let Some(c) = self.channel {
            link.send(&Message::CtrlChannel(c))?;
        }
        link.send(&Message::CtrlSensors(SensorsPayload {
            tick: self.tick,
            t: s.t,
            x: s.x,
            x_dot: s.x_dot,
            f_e: s.f_e,
            p_a: s.p_a,
            p_b: s.p_b,
        }))?;
        let mut text = Vec::new();
        loop {
            match link.recv()?.msg {
                Message::CtrlOutput(o) if o.tick == self.tick => {
                    if o.status != 0 {
                        return Err(PilError::Firmware(format!(
                            "the board answered tick {} from its safe state (status {:#04x})",
                            o.tick, o.status
                        )));
                    }
                    if o.signals().len() != self.signals.len() {
                        return Err(PilError::Firmware(format!(
                            "the board sent {} controller signals at tick {}; the host's controller of \
                             the same kind declares {} ({}): the firmware was built from another \
                             controller (docs/protocol.md §5)",
                            o.signals().len(),
                            o.tick,
                            self.signals.len(),
                            self.signals
                                .iter()
                                .map(|s| s.name)
                                .collect::<Vec<_>>()
                                .join(", ")
                        )));
                    }
                    if (o.f_ref.to_bits(), o.x_d.to_bits())
                        != (sp.f_ref.to_bits(), sp.x_d.to_bits())
                    {
                        self.setpoint_mismatches.0 += 1;
                        self.setpoint_mismatches.1.get_or_insert(o.tick);
                    }
                    return Ok(o);
                }
                Message::Text(t) => text.extend_from_slice(t.text()),
                Message::Safe(f) => {
                    return Err(PilError::Firmware(format!(
                        "the board went to its safe state at tick {} ({}){}",
                        self.tick,
                        reason_name(f.reason),
                        if text.is_empty() {
                            String::new()
                        } else {
                            format!(": {}", String::from_utf8_lossy(&text))
                        }
                    )));
                }
                _ => {}
            }
        }
    }
}

impl Controller for FirmwareController {
    fn update(&mut self, s: &Sensors, sp: &Setpoint, _dt: f64) -> ValveCommand {
        if self.error.is_none() {
            match self.exchange(s, sp) {
                Ok(o) => {
                    self.telemetry = Telemetry {
                        x_r: o.x_r,
                        ..Telemetry::default()
                    };
                    self.own = o.signals;
                    let c = &mut self.cost;
                    c.min_ns = if c.updates == 0 {
                        o.update_ns
                    } else {
                        c.min_ns.min(o.update_ns)
                    };
                    c.max_ns = c.max_ns.max(o.update_ns);
                    c.updates += 1;
                    self.sum_ns += f64::from(o.update_ns);
                    self.outputs.push(o);
                    self.live.set(Live {
                        link: self.link_stats(),
                        update_ns: o.update_ns,
                    });
                    self.tick = self.tick.wrapping_add(1);
                    // The command as the board sent it: no clamping or rounding on the host.
                    return ValveCommand { u: o.u };
                }
                Err(e) => self.error = Some(e),
            }
        }
        self.telemetry = Telemetry {
            x_r: f64::NAN,
            ..Telemetry::default()
        };
        self.own = [f64::NAN; MAX_SIGNALS];
        ValveCommand { u: 0.0 }
    }

    fn telemetry(&self) -> Telemetry {
        self.telemetry
    }

    fn reset(&mut self) {}

    fn signals(&self) -> &'static [Signal] {
        self.signals
    }

    fn record(&self, out: &mut [f64]) {
        // The board's values of the signals it declares, in declared order (checked in `exchange`).
        out.copy_from_slice(&self.own[..out.len()]);
    }
}
