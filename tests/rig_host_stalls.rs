//! `rig run` says the host loop's stalls apart from the plant's verdict, which it takes from the board's own
//! record (crates/outputs/tests/host_stalls.rs has the stalled and oscillating recordings; this is the
//! command's side, on a lockstep run, whose host never stalls).

mod common;

use common::{repo, run, s};

#[test]
fn a_lockstep_rig_run_is_judged_on_the_boards_record_and_says_its_host_did_not_stall() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec");
    let r = run(
        &[
            "rig",
            "run",
            "--lockstep-truth",
            "pneumatics/paper-actuator.toml",
            "--scene",
            "scenes/paper-fig3.toml",
            "--duration",
            "3",
            "--out",
            s(&out),
        ],
        repo(),
    );
    r.accepted();
    for said in [
        "host: no stalls of the loop",
        "judged on the board's record: 3000 sample periods of 0.001 s on its own clock (0 missing from it)",
    ] {
        assert!(r.stderr.contains(said), "`{said}` not in:\n{}", r.stderr);
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let rig = &summary["rig"];
    assert_eq!(rig["judged_on"], "board", "{rig}");
    assert_eq!(rig["host_stalls"]["count"], 0, "{rig}");
    assert_eq!(rig["host_stalls"]["late_ticks"], 0, "{rig}");
    assert_eq!(rig["host_stalls"]["threshold_s"], 0.0015, "{rig}");
}
