//! The model check of issue 26: a truth of the fitted model is found adequate; truths with an effect
//! beyond the paper hidden and not freed are found not adequate, with the effect named and every interval
//! marked not valid; the same truths with the effect freed are adequate with the truths inside.
mod common;

use common::{ACT, CYL, SMOOTH, USUAL_KEYS as KEYS, VALVE, names, request, shipped, steps};
use pneuflex_identify::params::Key;
use pneuflex_identify::perturb::perturb;
use pneuflex_identify::request::{Identified, identify};

/// One planted effect: sheet edits, the effect's keys, and the name `likely_missing` should give.
struct Effect {
    name: &'static str,
    edits: &'static [(&'static str, &'static str, &'static str)],
    keys: &'static [Key],
    missing: &'static str,
}

const EFFECTS: [Effect; 7] = [
    Effect {
        name: "leak",
        edits: &[(
            CYL,
            "",
            "[cylinder.leaks.piston]\nsonic_conductance_m3_per_s_pa = 1e-10\n\
             [cylinder.leaks.a_atmosphere]\nsonic_conductance_m3_per_s_pa = 1e-10",
        )],
        keys: &[Key::LeakConductance(0), Key::LeakConductance(1)],
        missing: "leakage",
    },
    Effect {
        name: "wall heat",
        edits: &[(CYL, "", "wall_heat_transfer_w_per_m2_k = 60.0")],
        keys: &[Key::WallHeat],
        missing: "heat_transfer",
    },
    Effect {
        name: "lugre",
        edits: &[(
            ACT,
            SMOOTH,
            "friction = \"lugre\"\ncoulomb_n = 0.6\nstatic_n = 0.9\nstribeck_velocity_m_per_s = 0.005\n\
             bristle_stiffness_n_per_m = 1e4\nbristle_damping_n_s_per_m = 100.0",
        )],
        keys: &[Key::BristleStiffness],
        missing: "friction",
    },
    Effect {
        name: "seal pressure",
        edits: &[(
            ACT,
            SMOOTH,
            "friction = \"smooth\"\ncoulomb_n = 0.6\nsmooth_velocity_m_per_s = 0.002\n\
             coulomb_pressure_n_per_pa = 8e-6",
        )],
        keys: &[Key::CoulombPressure],
        missing: "friction",
    },
    Effect {
        name: "lines",
        edits: &[(
            ACT,
            "",
            "[lines]\nvolume_m3 = 1.5e-6\nsonic_conductance_m3_per_s_pa = 1e-8\nlength_m = 1.5",
        )],
        keys: &[Key::LineVolume],
        missing: "valve_dynamics",
    },
    Effect {
        name: "spool",
        edits: &[(VALVE, "", "spool_time_constant_s = 0.0002")],
        keys: &[Key::SpoolTimeConstant],
        missing: "valve_dynamics",
    },
    Effect {
        // The example: a gas that exchanges heat with the wall, lumped as n = 1.25 (the exponent is
        // planted, not perturbed).
        name: "polytropic",
        edits: &[(
            ACT,
            "polytropic_exponent = 1.4",
            "polytropic_exponent = 1.25",
        )],
        keys: &[],
        missing: "heat_transfer",
    },
];

const SECONDS: f64 = 4.0;

fn fit(actuator: std::path::PathBuf, log: std::path::PathBuf, keys: &[Key]) -> Identified {
    identify(&request(vec![log], actuator, names(keys))).unwrap_or_else(|e| panic!("{e}"))
}

fn show(name: &str, id: &Identified) {
    let mc = &id.report.model_check;
    eprintln!(
        "{name}: adequate {} failed {:?} missing {:?} signatures {:?}",
        mc.adequate,
        mc.failed,
        mc.likely_missing
            .iter()
            .map(|m| m.effect)
            .collect::<Vec<_>>(),
        mc.signatures
    );
    for c in &mc.channels {
        eprintln!(
            "  {}: q {:.3e} still {:.3e} ({} rows) floor {:.3e} rms {:.3e} ratio {:.2} acf1 {:.2} mean|acf| {:.3} out {:.2} Q {:.0} val {:.2}",
            c.signal,
            c.resolution,
            c.still_noise,
            c.still_rows,
            c.floor,
            c.rms_fit,
            c.floor_ratio,
            c.autocorrelation[0],
            c.mean_abs_autocorrelation,
            c.lags_outside_fraction,
            c.ljung_box,
            c.validation_ratio
        );
    }
}

/// Inside-count of the truths: (inside, total), and asserts no interval that excludes its truth is valid.
fn coverage(
    name: &str,
    id: &Identified,
    changes: &[pneuflex_identify::perturb::Perturbed],
) -> (usize, usize) {
    let mut inside = 0;
    let mut total = 0;
    for e in &id.report.fit.estimates {
        let Some(c) = changes.iter().find(|c| c.key.name() == e.key) else {
            continue;
        };
        total += 1;
        let ok = common::inside(c, e);
        eprintln!(
            "  {name} {}: truth {:e} fitted {:e} ({:+.2} %) [{:e}, {:e}] valid {}",
            e.key,
            c.truth,
            e.value,
            100.0 * (e.value / c.truth - 1.0),
            e.ci95[0],
            e.ci95[1],
            e.interval_valid
        );
        if ok {
            inside += 1;
        }
        assert!(
            ok || !e.interval_valid,
            "{name}: {}: truth {:e} outside [{:e}, {:e}], and the interval is marked valid",
            e.key,
            c.truth,
            e.ci95[0],
            e.ci95[1]
        );
    }
    (inside, total)
}

/// A truth of `effect` (its keys and the six usual ones perturbed 20-40 %, seeded) and a 4 s lockstep log
/// of it: (the base sheet with the effect, the truth's values, the log). The scratch directory lives as
/// long as the returned guard.
fn planted(
    effect: &Effect,
    seed: u64,
) -> (
    tempfile::TempDir,
    std::path::PathBuf,
    Vec<pneuflex_identify::perturb::Perturbed>,
    std::path::PathBuf,
) {
    let scratch = common::scratch(&format!("model-check-{}", effect.name.replace(' ', "-")));
    let dir = scratch.path().to_path_buf();
    let base = common::sheets(&dir.join("base"), effect.edits);
    let mut keys: Vec<Key> = KEYS.to_vec();
    keys.extend_from_slice(effect.keys);
    let (truth, changes) = perturb(&base, &keys, seed, &dir.join("truth")).unwrap();
    let log = dir.join("log.csv");
    common::record(&truth, seed, steps(seed), SECONDS, None, &log);
    (scratch, base, changes, log)
}

/// A truth of the fitted model (the shipped sheet, the usual keys perturbed) and a 4 s lockstep log of it,
/// in the scratch directory `name`: (its guard, the truth's values, the log).
fn matched(
    name: &str,
) -> (
    tempfile::TempDir,
    Vec<pneuflex_identify::perturb::Perturbed>,
    std::path::PathBuf,
) {
    let scratch = common::scratch(name);
    let dir = scratch.path().to_path_buf();
    let (truth, changes) = perturb(&shipped(), &KEYS, SEED, &dir.join("truth")).unwrap();
    let log = dir.join("log.csv");
    common::record(&truth, SEED, steps(SEED), SECONDS, None, &log);
    (scratch, changes, log)
}

fn effect(name: &str) -> &'static Effect {
    EFFECTS.iter().find(|e| e.name == name).unwrap()
}

/// The truth's seed: any (51 is outside the other tests' seeds).
const SEED: u64 = 51;

/// A truth of the model that is fitted (the shipped sheet, six keys perturbed): adequate, every interval
/// valid and holding its truth, every channel's residual within 1.3 floors.
#[test]
fn a_truth_of_the_fitted_model_is_adequate() {
    let (_scratch, changes, log) = matched("model-check-matched");
    let id = fit(shipped(), log, &KEYS);
    show("matched", &id);
    let mc = &id.report.model_check;
    assert!(mc.adequate, "{:?}", mc.failed);
    assert!(mc.likely_missing.is_empty());
    for c in &mc.channels {
        assert!(c.floor_ratio < 1.3, "{}: {}", c.signal, c.floor_ratio);
    }
    assert!(id.report.fit.estimates.iter().all(|e| e.interval_valid));
    assert_eq!(coverage("matched", &id, &changes), (6, 6));
}

/// An effect planted in the truth and not freed (the fit starts from the shipped sheet, which lacks it):
/// not adequate, the effect named among `likely_missing`, every interval marked not valid.
fn hidden(name: &str) {
    let e = effect(name);
    let (_scratch, _base, changes, log) = planted(e, SEED);
    let id = fit(shipped(), log, &KEYS);
    show(&format!("{name} hidden"), &id);
    let mc = &id.report.model_check;
    assert!(!mc.adequate, "{name}: found adequate");
    let named: Vec<&str> = mc.likely_missing.iter().map(|m| m.effect).collect();
    assert!(
        named.contains(&e.missing),
        "{name}: likely missing {named:?}, not {}",
        e.missing
    );
    assert!(id.report.fit.estimates.iter().all(|e| !e.interval_valid));
    let md = pneuflex_identify::report::markdown(&id.report);
    assert!(
        md.starts_with("# Identification report\n\n**The model does not explain these logs"),
        "{md}"
    );
    coverage(name, &id, &changes);
}

/// The same truth with the effect's keys freed too (the fit starts from the sheet with the effect at its
/// unperturbed value): adequate, and every truth inside its interval.
fn freed(name: &str) {
    let e = effect(name);
    let (_scratch, base, changes, log) = planted(e, SEED);
    let mut keys: Vec<Key> = KEYS.to_vec();
    keys.extend_from_slice(e.keys);
    let id = fit(base, log, &keys);
    show(&format!("{name} freed"), &id);
    let mc = &id.report.model_check;
    assert!(mc.adequate, "{name} freed: {:?}", mc.failed);
    let (inside, total) = coverage(name, &id, &changes);
    assert_eq!((inside, total), (keys.len(), keys.len()), "{name} freed");
}

#[test]
fn a_hidden_leak_is_flagged_and_named() {
    hidden("leak");
}

#[test]
fn a_freed_leak_is_adequate() {
    freed("leak");
}

#[test]
fn hidden_wall_heat_is_flagged_and_named() {
    hidden("wall heat");
}

#[test]
fn freed_wall_heat_is_adequate() {
    freed("wall heat");
}

#[test]
fn hidden_lugre_friction_is_flagged_and_named() {
    hidden("lugre");
}

#[test]
fn freed_lugre_friction_is_adequate() {
    freed("lugre");
}

#[test]
fn a_hidden_seal_pressure_term_is_flagged_and_named() {
    hidden("seal pressure");
}

#[test]
fn a_freed_seal_pressure_term_is_adequate() {
    freed("seal pressure");
}

// Spool travel: its hidden fit drives F_c to its bound and takes 36-39 s of CI's test time; the quick form in
// CI leaves this pair out, the full form runs it (`cargo test -p pneuflex-identify --test model_check --
// --include-ignored`, docs/identification.md).
#[test]
#[ignore = "36-39 s per fit in a debug build: the full form (--include-ignored)"]
fn hidden_spool_travel_is_flagged_and_named() {
    hidden("spool");
}

#[test]
#[ignore = "the full form (--include-ignored), with its hidden pair"]
fn freed_spool_travel_is_adequate() {
    freed("spool");
}

// Lines between valve and ports: named too (valve_dynamics) and adequate once freed, but each fit takes
// 23-31 s in a debug build (the hidden one drives b and F_c to their bounds): run with `--ignored`.
#[test]
#[ignore = "23-31 s per fit in a debug build"]
fn hidden_lines_are_flagged_and_named() {
    hidden("lines");
}

#[test]
#[ignore = "23-31 s per fit in a debug build"]
fn freed_lines_are_adequate() {
    freed("lines");
}

/// The structures of `names` (the full list of `identify --select` adds stick-slip, the seal term and spool
/// travel; docs/identification.md): a few, for the test's time.
fn some_structures(names: &[&str]) -> Vec<pneuflex_identify::select::Structure> {
    pneuflex_identify::select::STRUCTURES
        .iter()
        .filter(|s| names.contains(&s.name))
        .copied()
        .collect()
}

fn select_on(log: std::path::PathBuf, work: &std::path::Path, structures: &[&str]) -> Identified {
    let req = request(vec![log], shipped(), names(&KEYS));
    let id =
        pneuflex_identify::select::select(&req, &some_structures(structures), work, None, &|_| {})
            .unwrap_or_else(|e| panic!("{e}"));
    let sel = id.report.structure_selection.as_ref().unwrap();
    for c in &sel.candidates {
        eprintln!(
            "  {}: bic {:.1} fit {:.3} held-out {:.3} adequate {}{} ({:.1} s) {:?}",
            c.structure,
            c.bic,
            c.fit_over_floor_sq,
            c.validation_over_floor_sq,
            c.adequate,
            if c.screened { " screened only" } else { "" },
            c.fit_seconds,
            c.skipped
        );
    }
    // A structure left at its screening fit could not have been chosen: its screening BIC is above the
    // chosen structure's by more than the margin (n ln 1.02, 2 % on the mean (residual / floor)^2) by which
    // the full fit's reweighting moves the figures.
    let chosen = sel
        .candidates
        .iter()
        .find(|c| c.structure == sel.chosen)
        .unwrap();
    assert!(!chosen.screened, "{}", sel.chosen);
    let n = (3 * id.report.model_check.rows) as f64;
    for c in sel.candidates.iter().filter(|c| c.screened) {
        assert!(
            c.bic >= chosen.bic + n * 1.02f64.ln(),
            "{}: {} against {}",
            c.structure,
            c.bic,
            chosen.bic
        );
    }
    id
}

/// Structure selection on the leak truth, fitted from the shipped sheet (no leaks): of the sheet as given,
/// leakage, wall heat and LuGre friction it chooses leakage, whose fit the model check finds adequate, with
/// the truth's leak and the six usual truths inside their intervals.
#[test]
#[ignore = "45-90 s in a debug build (the leaks' fit); structure_selection_finds_a_polytropic_chamber and the CLI's select test keep the rule checked"]
fn structure_selection_finds_a_hidden_leak() {
    let (scratch, _base, changes, log) = planted(effect("leak"), SEED);
    let names = ["as_given", "leakage", "heat_transfer", "lugre"];
    let id = select_on(log, &scratch.path().join("structures"), &names);
    let sel = id.report.structure_selection.as_ref().unwrap();
    assert_eq!(sel.chosen, "leakage", "{}", sel.verdict);
    assert!(
        id.report.model_check.adequate,
        "{:?}",
        id.report.model_check.failed
    );
    let (inside, total) = coverage("selected leak", &id, &changes);
    assert_eq!((inside, total), (8, 8));
    let md = pneuflex_identify::report::markdown(&id.report);
    assert!(
        md.contains("## Structure selection") && md.contains("`leakage` **(chosen)**"),
        "{md}"
    );
}

/// Structure selection on a truth whose chambers are polytropic at n = 1.25 (the shipped sheet's are
/// adiabatic, 1.4): of the sheet as given, wall heat and the polytropic process it chooses the polytropic
/// one, found adequate, with n's interval holding 1.25 and excluding 1.4, and the six usual truths inside
/// theirs.
#[test]
fn structure_selection_finds_a_polytropic_chamber() {
    let (scratch, _base, changes, log) = planted(effect("polytropic"), SEED);
    let names = ["as_given", "heat_transfer", "polytropic"];
    let id = select_on(log, &scratch.path().join("structures"), &names);
    let sel = id.report.structure_selection.as_ref().unwrap();
    assert_eq!(sel.chosen, "polytropic", "{}", sel.verdict);
    assert!(
        id.report.model_check.adequate,
        "{:?}",
        id.report.model_check.failed
    );
    let n = (id.keys.iter().zip(&id.report.fit.estimates))
        .find(|(k, _)| **k == Key::PolytropicExponent)
        .map(|(_, e)| e)
        .expect("the exponent is fitted");
    eprintln!("n = {} ci95 {:?}", n.value, n.ci95);
    assert!(
        n.ci95[0] <= 1.25 && 1.25 <= n.ci95[1] && n.ci95[1] < 1.4,
        "{:?}",
        n.ci95
    );
    assert_eq!(coverage("selected polytropic", &id, &changes), (6, 6));
}

/// On a truth of the sheet's own model, the selection keeps the sheet as given: the other structures'
/// extra keys fit only noise and pay their ln n (wall heat and LuGre friction here; measured with leakage
/// too in docs/identification.md).
#[test]
fn structure_selection_keeps_a_matched_model() {
    let (scratch, _changes, log) = matched("model-check-select-matched");
    // Leakage is left out for the test's time (its fit here takes 50-80 s: the leaks fall to their bound).
    let id = select_on(
        log,
        &scratch.path().join("structures"),
        &["as_given", "heat_transfer", "lugre"],
    );
    let sel = id.report.structure_selection.as_ref().unwrap();
    assert_eq!(sel.chosen, "as_given", "{}", sel.verdict);
    assert!(id.report.model_check.adequate);
}

/// The full form (`--include-ignored`, ~10 min in a debug build): every structure of `identify --select`
/// on every planted effect hidden from the shipped sheet. Prints the table of docs/identification.md and
/// asserts that the chosen structure models the planted effect's family (friction for the LuGre and seal
/// truths, valve dynamics for the spool and the lines), or that the choice is marked not adequate.
#[test]
#[ignore = "~10 min: every structure on every planted effect (the table of docs/identification.md)"]
fn structure_selection_on_every_planted_effect() {
    let family = |structure: &str| match structure {
        "leakage" => "leakage",
        "heat_transfer" | "polytropic" => "heat_transfer",
        "stick_slip" | "lugre" | "seal_pressure" => "friction",
        "valve_dynamics" => "valve_dynamics",
        _ => "none",
    };
    let names: Vec<&str> = pneuflex_identify::select::STRUCTURES
        .iter()
        .map(|s| s.name)
        .collect();
    for e in &EFFECTS {
        let (scratch, _base, _changes, log) = planted(e, SEED);
        eprintln!("{}:", e.name);
        let id = select_on(log, &scratch.path().join("structures"), &names);
        let sel = id.report.structure_selection.as_ref().unwrap();
        eprintln!("  chosen {}: {}", sel.chosen, sel.verdict);
        assert!(
            family(sel.chosen) == e.missing || !id.report.model_check.adequate,
            "{}: chose {} ({}), found adequate",
            e.name,
            sel.chosen,
            family(sel.chosen)
        );
    }
}

/// On a sheet with wall heat transfer the polytropic structure is not fitted, and says why: the wall-heat
/// balance takes n as the heat-capacity ratio, so a free n would count the heat twice.
#[test]
fn the_polytropic_structure_stands_aside_for_wall_heat() {
    let (scratch, base, _changes, log) = planted(effect("wall heat"), SEED);
    let req = request(vec![log], base, names(&KEYS));
    let structures = some_structures(&["as_given", "polytropic"]);
    let id = pneuflex_identify::select::select(
        &req,
        &structures,
        &scratch.path().join("structures"),
        None,
        &|_| {},
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let sel = id.report.structure_selection.as_ref().unwrap();
    let poly = sel
        .candidates
        .iter()
        .find(|c| c.structure == "polytropic")
        .unwrap();
    let why = poly.skipped.as_deref().unwrap_or("");
    assert!(
        why.contains("wall heat") && why.contains("heat-capacity ratio"),
        "{why:?}"
    );
    assert_eq!(sel.chosen, "as_given");
}
