//! The firmware on the emulated Cortex-M4F (QEMU mps2-an386). These tests need `qemu-system-arm` and the
//! firmware built (`cargo build --release` in firmware/, and the test-panic build for the panic test);
//! scripts/ci_firmware provides both and sets PNEUFLEX_REQUIRE_FIRMWARE=1, which turns a missing one into a
//! failure. Without them (an everyday `cargo test`) each test says what is missing and passes.
//!
//! The PIL loop is lockstep, and the board's clock is QEMU's virtual time (`-icount shift=0`): one ns per
//! instruction. The firmware spins on RAM while it waits (its UART and timer interrupts fill a ring buffer and
//! a deadline flag), so even a silent host's watchdog trips at an exact instruction count. Host speed enters in
//! one place only: how many spin instructions pass while the host is busy, which is why the safety tests send
//! their frames in one burst and the watchdog is 100 ms (≈ 1 s of host time at QEMU's speed here).

use std::path::{Path, PathBuf};
use std::time::Duration;

use pneuflex_pil::controller::{await_safe, setup_of, start};
use pneuflex_pil::{Link, qemu};
use pneuflex_protocol::ctrl::{SensorsPayload, StartPayload, ready, status};
use pneuflex_protocol::{MAX_FRAME, Message, RESET_MAGIC, ValveMode, encode, fault_code};
use pneuflex_scene::Scene;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The firmware image, or None (with the reason printed) when this machine cannot run it.
fn firmware(var: &str, default: &str) -> Option<PathBuf> {
    let elf = std::env::var_os(var)
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(default));
    let missing = if let Err(e) = qemu::qemu_binary() {
        Some(e.to_string())
    } else if !elf.is_file() {
        Some(format!("{} is not built (docs/firmware.md)", elf.display()))
    } else {
        None
    };
    match missing {
        None => Some(elf),
        Some(why) if std::env::var_os("PNEUFLEX_REQUIRE_FIRMWARE").is_some() => {
            panic!("PNEUFLEX_REQUIRE_FIRMWARE is set but: {why}")
        }
        Some(why) => {
            eprintln!("skipped (scripts/ci_firmware runs this): {why}");
            None
        }
    }
}

fn release_elf() -> Option<PathBuf> {
    firmware(
        "PNEUFLEX_FIRMWARE",
        "firmware/target/thumbv7em-none-eabihf/release/pneuflex-firmware",
    )
}

fn pil(scene: &str) {
    let Some(elf) = release_elf() else { return };
    let scene = Scene::load(&root().join(scene)).expect("scene loads");
    for (i, run) in scene
        .runs
        .iter()
        .enumerate()
        .filter(|(_, r)| r.frozen.is_none())
    {
        let r = pneuflex_pil::run_pil(&scene, i, &elf, &mut |_| {}).expect("PIL run");
        let c = &r.comparison;
        eprintln!(
            "{} {}: {} ticks, max|du| {:e}, max|dfe| {:e} N, first divergent tick {:?}, {} bit-identical, \
             update {:.0} ns mean ({}..{}), stack {} B, link {:?}",
            scene.name,
            run.name,
            c.ticks,
            c.max_abs_du,
            c.max_abs_dfe_n,
            c.first_divergent_tick,
            c.bit_identical_ticks,
            r.cost.mean_ns,
            r.cost.min_ns,
            r.cost.max_ns,
            r.end.stack_peak_bytes,
            r.link
        );
        assert_eq!(c.ticks_firmware, c.ticks_host, "{}: same length", run.name);
        assert_eq!(
            c.first_divergent_tick, None,
            "{}: |du| <= 1e-9 at every tick",
            run.name
        );
        assert!(c.max_abs_du <= 1e-9, "{}", run.name);
        assert_eq!(
            c.setpoint_mismatches, 0,
            "{}: the board's schedule is the host's",
            run.name
        );
        assert!(
            c.metrics_equal,
            "{}: metrics {:?}",
            run.name, c.rms_force_error_n
        );
        assert_eq!(
            (r.link.crc_errors, r.link.seq_gaps, r.link.malformed),
            (0, 0, 0)
        );
        assert_eq!(
            r.end.reason,
            fault_code::HOST_REQUEST,
            "parked by the host at the end"
        );
        assert!(r.cost.updates as usize == c.ticks && r.cost.min_ns > 0);
    }
}

#[test]
#[ignore = "2-4 min with a host core spinning for the emulated board; scripts/ci_firmware runs the same check \
            through `rig pil` (comparison.json asserted); run with --ignored"]
fn pil_paper_fig3_both_controllers_match_the_host_simulation() {
    pil("scenes/paper-fig3.toml");
}

#[test]
#[ignore = "2-4 min with a host core spinning for the emulated board; scripts/ci_firmware runs the same check \
            through `rig pil` (comparison.json asserted); run with --ignored"]
fn pil_paper_fig7_wood_to_iron_both_controllers_match_the_host_simulation() {
    pil("scenes/paper-fig7-wood-to-iron.toml");
}

/// The safety tests' board watchdog, ms.
const WATCHDOG_MS: u16 = 100;

/// Boots the firmware and starts fig3's adaptive run with a [`WATCHDOG_MS`] watchdog.
fn started(elf: &Path) -> (qemu::Board, Link) {
    let scene = Scene::load(&root().join("scenes/paper-fig3.toml")).expect("scene");
    let (board, stdin, stdout) = qemu::Board::start(elf).expect("QEMU starts");
    let mut link = Link::new(stdin, stdout);
    let setup = setup_of(&scene.runs[1]).expect("setup");
    start(
        &mut link,
        &setup,
        &scene.setpoints().unwrap(),
        scene.dt_s,
        WATCHDOG_MS,
    )
    .expect("Ready OK");
    (board, link)
}

fn sensors(tick: u32) -> Message {
    Message::CtrlSensors(SensorsPayload {
        tick,
        t: f64::from(tick) * 1e-3,
        x: 0.004,
        x_dot: 0.0,
        f_e: 5.0,
        p_a: 3e5,
        p_b: 2e5,
    })
}

/// Sends sensors for `ticks` ticks in one burst, then checks each answer is a live (not safe) output.
fn run_ticks(link: &mut Link, ticks: std::ops::Range<u32>) {
    let mut burst = Vec::new();
    let mut buf = [0u8; MAX_FRAME];
    for k in ticks.clone() {
        let n = encode(k as u8, &sensors(k), &mut buf);
        burst.extend_from_slice(&buf[..n]);
    }
    link.send_raw(&burst).unwrap();
    for k in ticks {
        match link.recv().unwrap().msg {
            Message::CtrlOutput(o) => {
                assert_eq!((o.tick, o.status), (k, 0));
                assert!(o.u.is_finite());
            }
            m => panic!("expected an output for tick {k}, got {m:?}"),
        }
    }
}

/// After a latched trip the board answers sensors with SAFE | LATCHED and u = 0, and Start is refused
/// until Reset; after Reset the valve is still safe (SAFE, not latched) until a new Start.
fn assert_latched(link: &mut Link, tick: u32) {
    link.send(&sensors(tick)).unwrap();
    match link.recv().unwrap().msg {
        Message::CtrlOutput(o) => {
            assert_eq!(o.status, status::SAFE | status::LATCHED, "latched");
            assert_eq!(o.u, 0.0);
        }
        m => panic!("expected a safe output, got {m:?}"),
    }
    // A new Start does not clear a latched fault.
    link.send(&Message::CtrlStart(StartPayload {
        controller: 1,
        dt_s: 1e-3,
        watchdog_ms: WATCHDOG_MS,
        safe_mode: ValveMode::SafeVent,
        n_params: 0,
        n_segments: 0,
        setup_crc: 0xFFFF,
    }))
    .unwrap();
    match link.recv().unwrap().msg {
        Message::CtrlReady(r) => assert_eq!(r.result, ready::START, "Start refused while latched"),
        m => panic!("expected Ready, got {m:?}"),
    }
    link.send(&Message::Reset(RESET_MAGIC)).unwrap();
    link.send(&sensors(tick + 1)).unwrap();
    match link.recv().unwrap().msg {
        Message::CtrlOutput(o) => {
            assert_eq!(o.status, status::SAFE, "reset: still safe, not latched")
        }
        m => panic!("expected a safe output, got {m:?}"),
    }
}

#[test]
fn host_silence_puts_the_valve_safe_within_the_watchdog_period_in_virtual_time_latched() {
    let Some(elf) = release_elf() else { return };
    let (_board, mut link) = started(&elf);
    run_ticks(&mut link, 0..100);
    // The host falls silent: the board's clock runs on in virtual time.
    let wall = std::time::Instant::now();
    let (safe, _) = await_safe(&mut link).expect("the board reports its safe state");
    // Printed, never asserted: how long the host waited for 100 ms of the board's time.
    eprintln!(
        "host silence: the trip arrived after {:?} of wall time",
        wall.elapsed()
    );
    assert_eq!(safe.reason, fault_code::HOST_SILENT);
    assert_eq!(safe.last_tick, 99);
    let waited_us = safe.safe_at_us - safe.last_valid_us;
    eprintln!(
        "watchdog {WATCHDOG_MS} ms: safe {waited_us} us (virtual) after the last valid frame"
    );
    // The board's timer fires at the last valid frame + the period (its clock, instruction counts):
    // exactly, up to the few instructions of the wake-up (100 000 us measured).
    let period = u32::from(WATCHDOG_MS) * 1000;
    assert!(
        (period..=period + 10).contains(&waited_us),
        "{waited_us} us"
    );
    assert_latched(&mut link, 100);
}

#[test]
fn a_storm_of_corrupted_frames_puts_the_valve_safe_before_the_watchdog() {
    let Some(elf) = release_elf() else { return };
    let (_board, mut link) = started(&elf);
    run_ticks(&mut link, 0..50);
    // Valid sensor frames with one bit flipped in the payload: each fails its CRC.
    let mut buf = [0u8; MAX_FRAME];
    let mut storm = Vec::new();
    for k in 50..70u32 {
        let n = encode(k as u8, &sensors(k), &mut buf);
        buf[10] ^= 0x10;
        storm.extend_from_slice(&buf[..n]);
    }
    link.send_raw(&storm).unwrap();
    let (safe, _) = await_safe(&mut link).expect("safe state");
    assert_eq!(safe.reason, fault_code::CRC, "bad frames, not the watchdog");
    eprintln!(
        "storm: safe after {} CRC errors, {} us after the last valid frame",
        safe.crc_errors,
        safe.safe_at_us - safe.last_valid_us
    );
    assert!(
        safe.crc_errors >= 9,
        "{} CRC errors counted",
        safe.crc_errors
    );
    assert!(
        safe.safe_at_us - safe.last_valid_us < u32::from(WATCHDOG_MS) * 1000,
        "before the watchdog"
    );
    assert_eq!(safe.last_tick, 49);
    assert_latched(&mut link, 70);
}

#[test]
fn a_panic_in_the_firmware_puts_the_valve_safe_and_is_reported() {
    let Some(elf) = firmware(
        "PNEUFLEX_FIRMWARE_PANIC",
        "firmware/target/pneuflex-firmware-test-panic",
    ) else {
        return;
    };
    let (_board, mut link) = started(&elf);
    run_ticks(&mut link, 0..500);
    link.send(&sensors(500)).unwrap();
    let mut fault = None;
    let (safe, text) = loop {
        // The Fault frame comes first, then the message, then Safe.
        let f = link.recv().unwrap();
        match f.msg {
            Message::Fault { code, detail } => fault = Some((code, detail)),
            Message::Text(_) | Message::Safe(_) => {
                link.timeout = Duration::from_secs(20);
                // Put it back in order: await_safe collects the text.
                let mut first = String::new();
                if let Message::Text(t) = f.msg {
                    first = String::from_utf8_lossy(t.text()).into_owned();
                }
                if let Message::Safe(s) = f.msg {
                    break (s, first);
                }
                let (s, rest) = await_safe(&mut link).unwrap();
                break (s, first + &rest);
            }
            m => panic!("unexpected {m:?}"),
        }
    };
    assert_eq!(fault.map(|f| f.0), Some(fault_code::PANIC));
    assert_eq!(safe.reason, fault_code::PANIC);
    assert_eq!(safe.last_tick, 499, "the panic came in tick 500's update");
    assert!(text.contains("deliberate panic at tick 500"), "{text}");
    eprintln!("panic reported: {text}");
    // The board stays safe and silent: no output for tick 500 or later.
    link.send(&sensors(501)).unwrap();
    assert!(link.recv_within(Duration::from_millis(500)).is_err());
}

/// What the I/O board said besides its Samples: the Fault, and the Applied echoes in order.
#[derive(Default)]
struct BoardSaid {
    fault: Option<(u8, u16)>,
    applied: Vec<pneuflex_protocol::AppliedPayload>,
}

/// The next Sample, keeping the Fault and Applied frames on the way in `said`.
fn next_sample(link: &mut Link, said: &mut BoardSaid) -> pneuflex_protocol::SamplePayload {
    loop {
        match link.recv().unwrap().msg {
            Message::Sample(s) => return s,
            Message::Fault { code, detail } => said.fault = Some((code, detail)),
            Message::Applied(a) => said.applied.push(a),
            _ => {}
        }
    }
}

#[test]
fn io_board_mode_applies_valve_commands_and_trips_its_own_watchdog_latched() {
    use pneuflex_protocol::{ConfigPayload, ValvePayload, status as st};
    let Some(elf) = release_elf() else { return };
    let (_board, stdin, stdout) = qemu::Board::start(&elf).expect("QEMU starts");
    let mut link = Link::new(stdin, stdout);
    // Config (1 kHz samples, 20 ms board watchdog, vent), then the handshake's heartbeat.
    link.send(&Message::Config(ConfigPayload {
        sample_period_us: 1000,
        watchdog_ms: 20,
        safe_mode: ValveMode::SafeVent,
    }))
    .unwrap();
    link.send(&Message::Heartbeat(0xC0DE_0001)).unwrap();
    let mut said = BoardSaid::default();
    loop {
        if let Message::Heartbeat(c) = link.recv().unwrap().msg {
            assert_eq!(c, 0xC0DE_0001, "echoed unchanged");
            break;
        }
    }
    // Before any command the valve is safe (vent) and the watchdog does not run.
    let s = next_sample(&mut link, &mut said);
    assert_eq!((s.status, s.duty_q15), (st::SAFE, 0));
    // A Run command: applied and echoed.
    let mut burst = Vec::new();
    let mut buf = [0u8; MAX_FRAME];
    for tick in 1..=5u32 {
        let n = encode(
            tick as u8,
            &Message::Valve(ValvePayload {
                tick,
                duty_q15: 16384,
                mode: ValveMode::Run,
            }),
            &mut buf,
        );
        burst.extend_from_slice(&buf[..n]);
    }
    link.send_raw(&burst).unwrap();
    let mut s = next_sample(&mut link, &mut said);
    while s.last_cmd_tick != 5 {
        s = next_sample(&mut link, &mut said);
    }
    assert_eq!((s.status, s.duty_q15), (0, 16384), "running at duty 0.5");
    // Each command echoed as applied, in order, on the samples' clock, before the sample that shows it.
    let ticks: Vec<u32> = said.applied.iter().map(|a| a.tick).collect();
    assert_eq!(ticks, [1, 2, 3, 4, 5]);
    for a in &said.applied {
        assert_eq!((a.duty_q15, a.mode), (16384, ValveMode::Run));
        assert!(
            a.board_time_us <= s.board_time_us,
            "applied at {} us",
            a.board_time_us
        );
    }
    said.applied.clear();
    let last_cmd_seen_us = s.board_time_us;
    // Silence: the board's own watchdog trips, latched, with the Fault frame.
    while s.status == 0 {
        s = next_sample(&mut link, &mut said);
    }
    assert_eq!(said.fault, Some((fault_code::HOST_SILENT, 20)));
    assert_eq!(s.status, st::SAFE | st::BOARD_FAULT | st::WATCHDOG);
    assert_eq!(s.duty_q15, 0);
    let waited = s.board_time_us - last_cmd_seen_us;
    eprintln!(
        "I/O board: watchdog 20 ms tripped in the sample {waited} us after the last command's echo"
    );
    // Checked each 1 ms sample: after 20 ms, within 20 ms + two periods of the echo.
    assert!((19_000..=22_000).contains(&waited), "{waited} us");
    // Latched: a Run command is echoed but not applied; Reset clears the fault, the valve stays safe.
    link.send(&Message::Valve(ValvePayload {
        tick: 6,
        duty_q15: 16384,
        mode: ValveMode::Run,
    }))
    .unwrap();
    while s.last_cmd_tick != 6 {
        s = next_sample(&mut link, &mut said);
    }
    assert_eq!(
        (s.status & st::BOARD_FAULT, s.duty_q15),
        (st::BOARD_FAULT, 0)
    );
    // The echo says what the valve does: the safe state, not the command.
    let echo = said.applied.last().expect("tick 6 echoed");
    assert_eq!(
        (echo.tick, echo.duty_q15, echo.mode),
        (6, 0, ValveMode::SafeVent)
    );
    link.send(&Message::Reset(RESET_MAGIC)).unwrap();
    while s.status & st::BOARD_FAULT != 0 {
        s = next_sample(&mut link, &mut said);
    }
    assert_eq!((s.status, s.duty_q15), (st::SAFE, 0), "cleared, still safe");
}

/// Boots the firmware and starts fig3's adaptive run on channels 0 and 1 (docs/protocol.md §5, "Several
/// controllers"), each with a [`WATCHDOG_MS`] watchdog.
fn started_two(elf: &Path) -> (qemu::Board, Link) {
    let scene = Scene::load(&root().join("scenes/paper-fig3.toml")).expect("scene");
    let (board, stdin, stdout) = qemu::Board::start(elf).expect("QEMU starts");
    let mut link = Link::new(stdin, stdout);
    let setup = setup_of(&scene.runs[1]).expect("setup");
    for ch in 0..2 {
        link.send(&Message::CtrlChannel(ch)).unwrap();
        start(
            &mut link,
            &setup,
            &scene.setpoints().unwrap(),
            scene.dt_s,
            WATCHDOG_MS,
        )
        .expect("Ready OK");
    }
    (board, link)
}

/// Channel `ch`'s tick `k`: its CtrlChannel and CtrlSensors, and the board's answer.
fn tick_on(link: &mut Link, ch: u8, k: u32) -> Message {
    link.send(&Message::CtrlChannel(ch)).unwrap();
    link.send(&sensors(k)).unwrap();
    link.recv().unwrap().msg
}

/// One safe state for the board: channel 1's host falls silent while channel 0's ticks go on; channel 1's
/// watchdog trips, and channel 0 goes safe in the same pass of the main loop (the same board time), latched
/// alike; a channel the board does not have is refused.
#[test]
fn one_silent_channel_puts_every_channel_safe_at_once() {
    let Some(elf) = release_elf() else { return };
    let (_board, mut link) = started_two(&elf);
    for k in 0..20 {
        for ch in 0..2 {
            match tick_on(&mut link, ch, k) {
                Message::CtrlOutput(o) => assert_eq!((o.tick, o.status), (k, 0), "channel {ch}"),
                m => panic!("channel {ch}, tick {k}: expected an output, got {m:?}"),
            }
        }
    }
    // Only channel 0 from here on, until the board says it went safe.
    let mut safes = Vec::new();
    let mut k = 20;
    while safes.is_empty() {
        assert!(k < 100_000, "channel 1's watchdog never tripped");
        link.send(&Message::CtrlChannel(0)).unwrap();
        link.send(&sensors(k)).unwrap();
        loop {
            match link.recv().unwrap().msg {
                Message::CtrlOutput(o) if o.tick == k => {
                    if o.status != 0 {
                        assert_eq!(o.status, status::SAFE | status::LATCHED, "tick {k}");
                    }
                    break;
                }
                Message::Safe(s) => safes.push(s),
                m => panic!("tick {k}: unexpected {m:?}"),
            }
        }
        k += 1;
    }
    // Both Safe frames: channel 1's own trip, then channel 0 taken with it.
    while safes.len() < 2 {
        match link.recv().unwrap().msg {
            Message::Safe(s) => safes.push(s),
            Message::CtrlOutput(_) => {}
            m => panic!("unexpected {m:?}"),
        }
    }
    eprintln!("{safes:?}");
    assert!(
        safes.iter().all(|s| s.reason == fault_code::HOST_SILENT),
        "{safes:?}"
    );
    assert_eq!(
        safes[0].last_tick, 19,
        "channel 1 ran ticks 0..20 and tripped first"
    );
    assert!(safes[1].last_tick >= 20, "channel 0 ran on: {safes:?}");
    assert!(
        safes[1].safe_at_us.abs_diff(safes[0].safe_at_us) <= 10,
        "in the same pass of the main loop: {safes:?}"
    );
    // Channel 0 answers from its latched safe state.
    match tick_on(&mut link, 0, k) {
        Message::CtrlOutput(o) => assert_eq!(o.status, status::SAFE | status::LATCHED),
        m => panic!("expected a safe output, got {m:?}"),
    }
    // A channel past the board's.
    link.send(&Message::CtrlChannel(7)).unwrap();
    match link.recv().unwrap().msg {
        Message::CtrlReady(r) => assert_eq!((r.result, r.detail), (ready::START, 3)),
        m => panic!("expected Ready 5/3, got {m:?}"),
    }
}

/// A storm of corrupted frames while two controllers run: the board's one safe state takes both, for bad
/// frames (not the watchdog), latched.
#[test]
fn a_storm_of_corrupted_frames_puts_both_channels_safe() {
    let Some(elf) = release_elf() else { return };
    let (_board, mut link) = started_two(&elf);
    for k in 0..20 {
        for ch in 0..2 {
            assert!(matches!(tick_on(&mut link, ch, k), Message::CtrlOutput(o) if o.status == 0));
        }
    }
    let mut buf = [0u8; MAX_FRAME];
    let mut storm = Vec::new();
    for k in 20..40u32 {
        let n = encode(k as u8, &sensors(k), &mut buf);
        buf[10] ^= 0x10;
        storm.extend_from_slice(&buf[..n]);
    }
    link.send_raw(&storm).unwrap();
    let safes: Vec<_> = (0..2)
        .map(|_| await_safe(&mut link).expect("safe state").0)
        .collect();
    eprintln!("{safes:?}");
    assert!(
        safes.iter().all(|s| s.reason == fault_code::CRC),
        "{safes:?}"
    );
    assert!(safes.iter().all(|s| s.last_tick == 19), "{safes:?}");
    for ch in 0..2 {
        match tick_on(&mut link, ch, 40) {
            Message::CtrlOutput(o) => {
                assert_eq!(o.status, status::SAFE | status::LATCHED, "channel {ch}")
            }
            m => panic!("channel {ch}: expected a safe output, got {m:?}"),
        }
    }
}
