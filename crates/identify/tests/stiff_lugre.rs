//! A LuGre seal with stiff bristles, 2e4 to 1.6e5 N/m (where the reference analysis of the shipped seal
//! data puts a real seal's pre-sliding, docs/identification.md "Seal friction"): the emulated rig runs it
//! without a fault (an explicit step of the bristles diverged at 4e4 N/m: "p_a = -1298675 Pa outside
//! [60000, 800000]" at tick 14), and the fit's replay of its log through the truth is at the sensors'
//! resolution.
mod common;

use common::{ACT, SMOOTH, sheets, steps};
use pneuflex_identify::log::read_log;
use pneuflex_identify::replay::{Prepared, ReplayOptions};
use pneuflex_pneumatics::{ActuatorSheet, Friction};

#[test]
fn a_rig_with_stiff_lugre_bristles_runs_and_replays_through_its_truth() {
    let scratch = common::scratch("stiff-lugre");
    for (i, sigma0) in ["2e4", "4e4", "1.6e5"].into_iter().enumerate() {
        let edit = format!(
            "friction = \"lugre\"\ncoulomb_n = 0.6\nstatic_n = 0.9\nstribeck_velocity_m_per_s = 0.005\n\
             bristle_stiffness_n_per_m = {sigma0}\nbristle_damping_n_s_per_m = 100.0"
        );
        let truth = sheets(
            &scratch.path().join(format!("truth-{i}")),
            &[(ACT, SMOOTH, &edit)],
        );
        let model = ActuatorSheet::load(&truth).unwrap().model();
        assert!(matches!(
            model.mechanics.friction,
            Friction::LuGre { bristle_stiffness_n_per_m: s, .. } if s == sigma0.parse::<f64>().unwrap()
        ));
        // `record` asserts that the run ends without a fault.
        let trace = scratch.path().join(format!("trace-{i}.csv"));
        common::record(&truth, 3, steps(3), 2.0, None, &trace);
        let log = read_log(&trace).unwrap();
        let n = log.len();
        assert!(n >= 1900, "{sigma0}: {n} rows");
        let p = Prepared::new(log, &ReplayOptions::default(), n - 1);
        let [rms_p, rms_x] = common::rms_of(&p, &model);
        eprintln!(
            "sigma0 {sigma0} N/m: replay through the truth {rms_p:.0} Pa, {:.3} mm",
            rms_x * 1e3
        );
        // The 12-bit channels resolve 270 / 540 Pa and 19 um (a count of noise on each).
        assert!(
            rms_p < 1000.0 && rms_x < 1e-4,
            "{sigma0}: {rms_p} Pa, {rms_x} m"
        );
    }
}
