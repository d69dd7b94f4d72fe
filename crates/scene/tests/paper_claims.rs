//! The paper's claims as the tool states them: every shipped paper scene carries its claims (Section III-E,
//! Figs. 3–4; Section IV, Fig. 7) in `[[claims]]`, and `pneuflex run` prints each with the two values and a
//! verdict. These tests assert the verdicts on the shipped scenes — the ones that hold and, as honestly, the
//! ones that do not — so a model or controller change that flips one is seen. The values behind each
//! verdict are in docs/scenes.md ("The paper scenes and what they show").

use std::path::Path;

use pneuflex_scene::analysis::claims::{ClaimResult, EarnedBy, check_all};
use pneuflex_scene::{RunResult, Scene, run_scene};

fn run(file: &str) -> (Vec<RunResult>, Vec<ClaimResult>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(file);
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let res = run_scene(&scene, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    let claims = check_all(&scene, &res);
    (res, claims)
}

/// Both runs bounded: no divergence, |f_e| below three times the largest reference, x finite.
fn bounded(res: &[RunResult], f_cap: f64) {
    for r in res {
        assert!(
            r.diverged.is_none(),
            "{} diverged: {:?}",
            r.name,
            r.diverged
        );
        let f_max = r.trace.f_e().iter().fold(0.0_f64, |m, f| m.max(f.abs()));
        assert!(f_max < f_cap, "{}: peak |f_e| = {f_max} N", r.name);
        assert!(r.trace.x().iter().all(|x| x.is_finite()));
    }
}

/// The verdict of each claim, by statement prefix, as expected.
fn verdicts(claims: &[ClaimResult], expected: &[(&str, bool)]) {
    assert_eq!(claims.len(), expected.len(), "{claims:#?}");
    for (c, (prefix, holds)) in claims.iter().zip(expected) {
        assert!(
            c.statement.starts_with(prefix),
            "{} vs {prefix}",
            c.statement
        );
        assert_eq!(
            c.holds, *holds,
            "{}: {} {:?} vs {} {:?} ({:?})",
            c.statement, c.better, c.better_value, c.than, c.than_value, c.why_not
        );
    }
}

/// What earned each claim's win, by the scene's frozen runs (docs/scenes.md "What adaptation buys").
fn earned(claims: &[ClaimResult], expected: &[EarnedBy]) {
    assert_eq!(claims.len(), expected.len());
    for (c, e) in claims.iter().zip(expected) {
        let a = c
            .adaptation
            .as_ref()
            .unwrap_or_else(|| panic!("{}: no adaptation verdict", c.statement));
        assert_eq!(
            a.earned_by, *e,
            "{}: {} {:#?}",
            c.statement, a.why, a.frozen
        );
    }
}

const FIG3_CLAIMS: [&str; 5] = [
    "adaptive tracks the sine with less phase lag",
    "adaptive tracks the sine with a lower RMS",
    "after the stiffness change, adaptive recovers with less overshoot",
    "after the stiffness change, adaptive settles faster",
    "on the stiffer environment, adaptive tracks the sine",
];

#[test]
fn ideal_loop_every_claim_of_fig3_holds() {
    let (res, claims) = run("paper-fig3-ideal.toml");
    bounded(&res, 36.0);
    verdicts(&claims, &FIG3_CLAIMS.map(|s| (s, true)));
}

#[test]
fn proportional_valve_every_claim_of_fig3_holds() {
    // The Fig. 3 variant on the proportional valve with kp = 7 /m (below the limit-cycle onset).
    let (res, claims) = run("paper-fig3-proportional.toml");
    bounded(&res, 36.0);
    verdicts(&claims, &FIG3_CLAIMS.map(|s| (s, true)));
    // Held at the bounds the recovery overshoot keeps 95 % of the lead and the settling 86 %: those two
    // wins are the projection bound's, the sine tracking the adaptation's.
    use EarnedBy::*;
    earned(
        &claims,
        &[
            Adaptation,
            Adaptation,
            ProjectionBound,
            ProjectionBound,
            Adaptation,
        ],
    );
}

#[test]
fn linear_plant_claims_of_fig3() {
    // The paper's own model: lag and RMS hold; after the stiffness change impedance recovers with less
    // overshoot (5 % against 14 % of the jump) and settles 7 % sooner.
    let (res, claims) = run("paper-fig3-linear.toml");
    bounded(&res, 36.0);
    verdicts(
        &claims,
        &[
            (FIG3_CLAIMS[0], true),
            (FIG3_CLAIMS[1], true),
            (FIG3_CLAIMS[2], false),
            (FIG3_CLAIMS[3], false),
            (FIG3_CLAIMS[4], true),
        ],
    );
}

/// The fig3 claims on the 40 Hz PWM valve, 1-DOF or multibody: the recovery overshoot claim does not hold
/// (docs/scenes.md). The faster settling is the projection bound's: held at p_max and -d_max the controller
/// settles in 0.444 s on the 1-DOF plant (84 % of adaptive's lead over impedance) and 0.464 s on the rig
/// (122 %); the sine tracking is lost when frozen. A frozen run would win the overshoot claim.
fn pwm_claims_of_fig3(file: &str) {
    let (res, claims) = run(file);
    bounded(&res, 36.0);
    verdicts(
        &claims,
        &[
            (FIG3_CLAIMS[0], true),
            (FIG3_CLAIMS[1], true),
            (FIG3_CLAIMS[2], false),
            (FIG3_CLAIMS[3], true),
            (FIG3_CLAIMS[4], true),
        ],
    );
    use EarnedBy::*;
    earned(
        &claims,
        &[Adaptation, Adaptation, NoWin, ProjectionBound, Adaptation],
    );
    let overshoot = claims[2].adaptation.as_ref().unwrap();
    assert!(overshoot.frozen.iter().all(|f| f.wins), "{overshoot:#?}");
}

#[test]
fn pneumatic_plant_claims_of_fig3() {
    pwm_claims_of_fig3("paper-fig3.toml");
}

#[test]
fn multibody_rig_claims_of_fig3() {
    // With the PWM edges located inside the step (issue 13 item 1) adaptive settles faster here too
    // (0.580 s against impedance's 1.111 s, a fragile time: 0.805–1.121 s with the band 5 % wider or
    // narrower, the verdict the same across it); with the spool sampled once per substep it settled later.
    pwm_claims_of_fig3("paper-fig3-multibody.toml");
}

#[test]
fn wood_to_iron_claims_of_fig7() {
    let (res, claims) = run("paper-fig7-wood-to-iron.toml");
    bounded(&res, 60.0);
    // With the PWM edges located inside the step (issue 13 item 1) the impact peaks are a tie that
    // impedance wins by 0.3 N (45.34 vs 45.07 N with the 2 ms physics step; 45.27 vs 44.84 N at 1 ms; before
    // issue 13: 45.15 vs 47.67 N, set by where in the PWM cycle the flange met the iron face), and adaptive
    // settles faster (1.28 vs 2.37 s; 1.26 vs 2.33 s at 1 ms).
    verdicts(
        &claims,
        &[
            (
                "on the swap to iron, adaptive hits with a lower peak force",
                false,
            ),
            (
                "on the swap to iron, adaptive recovers with less overshoot",
                false,
            ),
            ("on the swap to iron, adaptive settles faster", true),
            // Within 0.1 %: too close to call.
            (
                "on iron, adaptive holds the force with a lower RMS error",
                false,
            ),
        ],
    );
}

#[test]
fn lyapunov_field_is_present_and_non_increasing() {
    for file in ["paper-fig3-ideal.toml", "paper-fig3.toml"] {
        let (res, _) = run(file);
        let a = res.iter().find(|r| r.name == "adaptive").unwrap();
        let l = a.lyapunov.expect("adaptive runs carry the Lyapunov check");
        assert!(l.non_increasing && l.v_end <= l.v0, "{l:?}");
        assert!(
            res.iter()
                .find(|r| r.name == "impedance")
                .unwrap()
                .lyapunov
                .is_none()
        );
    }
}

#[test]
fn a_claim_on_an_unknown_window_or_metric_is_refused_with_its_key() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-ideal.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    for (from, to, key) in [
        (
            "window = \"sine\"",
            "window = \"sinus\"",
            "claims[0].window",
        ),
        (
            "metric = \"phase_lag_deg\"",
            "metric = \"lag\"",
            "claims[0].metric",
        ),
        ("than = \"impedance\"", "than = \"pid\"", "claims[0].than"),
    ] {
        let bad = text.replacen(from, to, 1);
        let e = Scene::from_toml_str(&bad, &path, path.parent().unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains(key), "{e}");
    }
}
