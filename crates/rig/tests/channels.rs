//! Two actuators on one emulated board, end to end over the N-channel frames (docs/protocol.md §6): the
//! rig file's two channels, the host driver and supervisor, the emulated board of two independent plants.

mod common;

use pneuflex_control::ValveCommand;
use pneuflex_rig::channel_board::{ChannelBoard, SerialChannels};
use pneuflex_rig::emulator::{Emulator, MemLink};
use pneuflex_rig::error::ErrorKind;
use pneuflex_rig::protocol::{ConfigPayload, ValveMode};
use pneuflex_rig::rigfile::InjectedFault;
use pneuflex_rig::supervisor::ChannelSupervisor;
use pneuflex_rig::{RigFile, session};

/// Supply lost on channel 1 at 50 ms of experiment time: that channel's supply transmitter reads
/// atmosphere, its limit trips, and both valves must be safe from that very tick on.
#[test]
fn supply_lost_on_channel_1_of_2_puts_both_valves_safe_in_the_tick_that_sees_it() {
    let file = common::rig_path();
    let text = std::fs::read_to_string(&file).unwrap()
        + "\n[[channel]]\nname = \"left\"\n\n[[channel]]\nname = \"right\"\n[channel.valve]\nsafe_state = \"hold\"\n";
    let rig = RigFile::parse(&text, &file).expect("the two-channel rig file loads");
    let channels = rig.channels();
    let plant = session::emulated_plant(&rig, &file).unwrap();
    let cfg = rig.emulator.clone().unwrap();
    let mut subs = Vec::new();
    for (i, ch) in channels.iter().enumerate() {
        let mut cfg = cfg.clone();
        cfg.faults = if i == 1 {
            vec![InjectedFault::SupplyLoss { at_s: 0.05 }]
        } else {
            vec![]
        };
        let (to_board, board_end) = MemLink::pair();
        subs.push((
            Emulator::new(plant.clone(), board_end, ch.cal, cfg),
            to_board,
        ));
    }
    let (host, board_end) = MemLink::pair();
    let mut board = ChannelBoard::new(board_end, subs).unwrap();
    let mut driver = SerialChannels::new(host, &channels, rig.rt.velocity_cutoff_hz);
    driver
        .configure(ConfigPayload {
            sample_period_us: 1000,
            watchdog_ms: 50,
            safe_mode: ValveMode::SafeVent,
        })
        .unwrap();
    let mut sup = ChannelSupervisor::new(&mut driver, channels.clone());
    // Each piston held near 10 mm by a proportional position loop (well inside every limit).
    let mut u = [ValveCommand { u: 0.0 }; 2];
    for k in 0..200u64 {
        let t = k as f64 * 1e-3;
        assert!(board.step(t).unwrap(), "the board runs");
        if let Some(s) = sup.sense(k, t) {
            for (u, s) in u.iter_mut().zip(&s) {
                u.u = (50.0 * (0.01 - s.sensors.x)).clamp(-1.0, 1.0);
            }
        }
        sup.actuate(k, t, &u);
    }
    let f = sup
        .fault()
        .expect("the supply loss trips the supervisor")
        .clone();
    drop(sup);
    board.step(0.2).unwrap();
    assert_eq!(
        (f.channel, f.fault.kind),
        (Some(1), ErrorKind::Limit),
        "{f:?}"
    );
    assert!(
        f.fault
            .message
            .contains("channel 1 (right): supply pressure"),
        "{}",
        f.fault.message
    );
    let k = f.fault.tick as u32;
    for (i, safe) in [(0, ValveMode::SafeVent), (1, ValveMode::SafeHold)] {
        let log = board.log(i).unwrap();
        let before: Vec<_> = log.commands.iter().filter(|c| c.tick < k).collect();
        let after: Vec<_> = log.commands.iter().filter(|c| c.tick >= k).collect();
        assert!(
            before.len() > 40,
            "channel {i} ran before the fault: {}",
            before.len()
        );
        assert!(
            before.iter().all(|c| c.mode == ValveMode::Run),
            "channel {i}"
        );
        // The first command of the fault's tick is already safe, and every later one.
        assert_eq!(after.first().map(|c| c.tick), Some(k), "channel {i}");
        assert!(
            after.iter().all(|c| c.mode == safe && c.duty_q15 == 0),
            "channel {i}: {:?}",
            after.first()
        );
    }
}
