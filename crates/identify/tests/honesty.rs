//! Issue 44: identification honest at every magnitude. Each effect beyond the paper is planted in a truth at
//! 0.25, 0.5, 1 and 2 times the magnitude of the model-check tests (tests/model_check.rs), hidden from a fit
//! of the shipped sheet's six usual keys; the model check must either find the model not adequate (and rank
//! the planted effect first in `likely_missing`) or leave intervals that hold every truth. Prints the
//! honesty table (effect, magnitude, seed, adequate, every interval holding its truth, the planted effect's
//! rank).
//!
//! CI runs a reduced grid (`honest_at_a_quarter_of_the_tests_magnitudes`); the full grid is
//! `cargo test -p pneuflex-identify --test honesty -- --ignored --nocapture` (docs/identification.md), and
//! `PNEUFLEX_HONESTY=effect:magnitude:seed,...` runs any cells. `matched_models_false_alarms` measures the
//! check's false-alarm rate on truths of the fitted model (seeds the other tests do not use).
mod common;

use common::{ACT, CYL, SMOOTH, USUAL_KEYS as KEYS, VALVE, names, request, shipped, steps};
use pneuflex_identify::params::Key;
use pneuflex_identify::perturb::{Perturbed, perturb};
use pneuflex_identify::request::{Identified, identify};

/// One effect planted at a magnitude: the sheet edits (file, text replaced, replacement; "" appends).
type Edits = Vec<(&'static str, &'static str, String)>;

/// An effect, its keys (perturbed in the truth with the usual six), the name `likely_missing` gives it, and
/// its edits at `f` times the model-check tests' magnitude.
struct Effect {
    name: &'static str,
    keys: &'static [Key],
    missing: &'static str,
    edits: fn(f64) -> Edits,
}

const EFFECTS: [Effect; 7] = [
    Effect {
        // Leaks across the piston and from A to atmosphere, C = 1e-10 each at 1x.
        name: "leak",
        keys: &[Key::LeakConductance(0), Key::LeakConductance(1)],
        missing: "leakage",
        edits: |f| {
            vec![(
                CYL,
                "",
                format!(
                    "[cylinder.leaks.piston]\nsonic_conductance_m3_per_s_pa = {c:e}\n\
                     [cylinder.leaks.a_atmosphere]\nsonic_conductance_m3_per_s_pa = {c:e}",
                    c = 1e-10 * f
                ),
            )]
        },
    },
    Effect {
        // Wall heat, h = 60 W/(m^2 K) at 1x.
        name: "wall heat",
        keys: &[Key::WallHeat],
        missing: "heat_transfer",
        edits: |f| {
            vec![(
                CYL,
                "",
                format!("wall_heat_transfer_w_per_m2_k = {:e}", 60.0 * f),
            )]
        },
    },
    Effect {
        // LuGre: the break-away 0.3 N above F_c (above the truth's perturbed F_c: `cell`) and a bristle
        // damping of 100 N s/m at 1x, bristles 1e4 N/m (the damping scaled too: alone, the break-away's
        // excess hardly changed the residuals, 2.40 / 2.37 / 2.40 floors on x at 0.25 / 0.5 / 1x).
        name: "lugre",
        keys: &[Key::BristleStiffness],
        missing: "friction",
        edits: |f| {
            vec![(
                ACT,
                SMOOTH,
                format!(
                    "friction = \"lugre\"\ncoulomb_n = 0.6\nstatic_n = {:e}\n\
                     stribeck_velocity_m_per_s = 0.005\nbristle_stiffness_n_per_m = 1e4\n\
                     bristle_damping_n_s_per_m = {:e}",
                    // Above any perturbed F_c (at most 1.4 x 0.6) until `cell` sets it.
                    0.9 + 0.3 * f,
                    100.0 * f
                ),
            )]
        },
    },
    Effect {
        // The seal term, 8e-6 N/Pa at 1x (the 2e-6 is 0.25x).
        name: "seal pressure",
        keys: &[Key::CoulombPressure],
        missing: "friction",
        edits: |f| {
            vec![(
                ACT,
                SMOOTH,
                format!(
                    "friction = \"smooth\"\ncoulomb_n = 0.6\nsmooth_velocity_m_per_s = 0.002\n\
                     coulomb_pressure_n_per_pa = {:e}",
                    8e-6 * f
                ),
            )]
        },
    },
    Effect {
        // Spool travel, 0.2 ms at 1x.
        name: "spool",
        keys: &[Key::SpoolTimeConstant],
        missing: "valve_dynamics",
        edits: |f| vec![(VALVE, "", format!("spool_time_constant_s = {:e}", 2e-4 * f))],
    },
    Effect {
        // The chambers polytropic: n = 1.4 - 0.15 at 1x (1.25, the model-check test's).
        name: "polytropic",
        keys: &[],
        missing: "heat_transfer",
        edits: |f| {
            vec![(
                ACT,
                "polytropic_exponent = 1.4",
                format!("polytropic_exponent = {}", 1.4 - 0.15 * f),
            )]
        },
    },
    Effect {
        // Lines of 1.5 cm^3, C = 1e-8, 1.5 m at 1x: the volume scaled (3 m of line at 2x faulted the
        // emulated rig on p_a > 800 kPa in its first ticks).
        name: "lines",
        keys: &[Key::LineVolume],
        missing: "valve_dynamics",
        edits: |f| {
            vec![(
                ACT,
                "",
                format!(
                    "[lines]\nvolume_m3 = {:e}\nsonic_conductance_m3_per_s_pa = 1e-8\nlength_m = 1.5",
                    1.5e-6 * f
                ),
            )]
        },
    },
];

/// Log length, s (as the model-check tests').
const SECONDS: f64 = 4.0;

/// One cell of the table.
struct Row {
    effect: String,
    magnitude: f64,
    seed: u64,
    adequate: bool,
    /// Every truth inside its interval (noise and widening).
    covered: bool,
    /// Every truth inside the interval before widening.
    covered_noise: bool,
    /// 1-based rank of the planted effect in `likely_missing` (None: not named or adequate).
    rank: Option<usize>,
    named: Vec<&'static str>,
    /// The intervals widened: the largest ratio of a widened width to its noise width.
    widening: f64,
}

fn print_header() {
    eprintln!(
        "| effect | magnitude | seed | adequate | every interval holds its truth (before widening) | rank of the planted effect in likely_missing | likely_missing | widest widening |"
    );
    eprintln!("|---|---|---|---|---|---|---|---|");
}

fn print_row(r: &Row) {
    eprintln!(
        "| {} | {}x | {} | {} | {} ({}) | {} | {} | {:.2} |",
        r.effect,
        r.magnitude,
        r.seed,
        r.adequate,
        r.covered,
        r.covered_noise,
        r.rank.map_or("-".to_string(), |k| k.to_string()),
        if r.named.is_empty() {
            "-".to_string()
        } else {
            r.named.join(", ")
        },
        r.widening
    );
}

fn detail(id: &Identified, changes: &[Perturbed]) {
    let mc = &id.report.model_check;
    eprintln!("  failed {:?}", mc.failed);
    for c in &mc.channels {
        eprintln!(
            "  {}: floor ratio {:.3} mean|acf| {:.4} held-out {:.3}",
            c.signal, c.floor_ratio, c.mean_abs_autocorrelation, c.validation_ratio
        );
    }
    for s in &mc.signatures {
        eprintln!(
            "  probe {} / {}: r {:.3} effect r {:.3} amount {:.3} +- {:.3} (t {:.2}){}",
            s.effect,
            s.probe,
            s.correlation,
            s.effect_correlation,
            s.amount,
            s.amount_se,
            s.amount / s.amount_se,
            if s.modelled { " modelled" } else { "" }
        );
    }
    for e in &id.report.fit.estimates {
        let truth = changes
            .iter()
            .find(|c| c.key.name() == e.key)
            .map_or(f64::NAN, |c| c.truth);
        let noise = e.widened.as_ref().map_or(e.ci95, |w| w.noise_ci95);
        eprintln!(
            "  {}: truth {:.5e} fitted {:.5e} ({:+.2} %) ci [{:.5e}, {:.5e}] noise [{:.5e}, {:.5e}] by {:?}",
            e.key,
            truth,
            e.value,
            100.0 * (e.value / truth - 1.0),
            e.ci95[0],
            e.ci95[1],
            noise[0],
            noise[1],
            e.widened.as_ref().map(|w| (&w.probe, w.amounts))
        );
    }
}

/// The truth of `effect` at `magnitude` (its keys and the usual six perturbed 20-40 %, seeded), a 4 s
/// lockstep log of it, and the fit of the usual six from the shipped sheet (the effect hidden); `None`
/// when the emulated rig faulted on the truth.
fn cell(effect: &Effect, magnitude: f64, seed: u64) -> Option<Row> {
    let scratch = common::scratch(&format!("honesty-{}", effect.name.replace(' ', "-")));
    let dir = scratch.path().to_path_buf();
    let edits = (effect.edits)(magnitude);
    let refs: Vec<(&str, &str, &str)> =
        edits.iter().map(|(f, a, b)| (*f, *a, b.as_str())).collect();
    let base = common::sheets(&dir.join("base"), &refs);
    let mut keys: Vec<Key> = KEYS.to_vec();
    keys.extend_from_slice(effect.keys);
    let (truth, changes) = perturb(&base, &keys, seed, &dir.join("truth")).unwrap();
    if effect.name == "lugre" {
        // The break-away's excess over the truth's own (perturbed) Coulomb force is the magnitude: a
        // perturbed F_c above a small F_s is no sheet.
        let f_c = changes
            .iter()
            .find(|c| c.key == Key::Coulomb)
            .unwrap()
            .truth;
        set_static(&truth, f_c + 0.3 * magnitude);
    }
    let log = dir.join("log.csv");
    let recorded = std::panic::catch_unwind(|| {
        common::record(&truth, seed, steps(seed), SECONDS, None, &log);
    });
    if recorded.is_err() {
        // The emulated rig faulted (its limits): no log, no row to judge; the table says so.
        eprintln!(
            "| {} | {magnitude}x | {seed} | the emulated rig faulted: no log | | | | |",
            effect.name
        );
        return None;
    }
    let id =
        identify(&request(vec![log], shipped(), names(&KEYS))).unwrap_or_else(|e| panic!("{e}"));
    Some(judge(
        effect.name,
        effect.missing,
        magnitude,
        seed,
        &id,
        &changes,
    ))
}

/// Sets `static_n` in the actuator sheet `sheet`.
fn set_static(sheet: &std::path::Path, f_s: f64) {
    let text = std::fs::read_to_string(sheet).unwrap();
    let mut done = false;
    let out: Vec<String> = text
        .lines()
        .map(|l| {
            if l.trim_start().starts_with("static_n") {
                done = true;
                format!("static_n = {f_s:e}")
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(done, "{} has no static_n", sheet.display());
    std::fs::write(sheet, out.join("\n") + "\n").unwrap();
}

fn judge(
    name: &str,
    missing: &str,
    magnitude: f64,
    seed: u64,
    id: &Identified,
    changes: &[Perturbed],
) -> Row {
    let mc = &id.report.model_check;
    let mut covered = true;
    let mut covered_noise = true;
    let mut widening: f64 = 1.0;
    for e in &id.report.fit.estimates {
        let Some(c) = changes.iter().find(|c| c.key.name() == e.key) else {
            continue;
        };
        covered &= e.ci95[0] <= c.truth && c.truth <= e.ci95[1];
        let noise = e.widened.as_ref().map_or(e.ci95, |w| w.noise_ci95);
        covered_noise &= noise[0] <= c.truth && c.truth <= noise[1];
        widening = widening.max((e.ci95[1] - e.ci95[0]) / (noise[1] - noise[0]));
    }
    let named: Vec<&'static str> = mc.likely_missing.iter().map(|m| m.effect).collect();
    let row = Row {
        effect: name.to_string(),
        magnitude,
        seed,
        adequate: mc.adequate,
        covered,
        covered_noise,
        rank: named.iter().position(|n| *n == missing).map(|k| k + 1),
        named,
        widening,
    };
    print_row(&row);
    detail(id, changes);
    row
}

fn effect(name: &str) -> &'static Effect {
    EFFECTS.iter().find(|e| e.name == name).unwrap()
}

/// What every cell must show: an adequate fit leaves no interval that excludes its truth; a fit that is
/// not adequate names the planted effect first.
fn assert_honest(rows: &[Row]) {
    for r in rows {
        assert!(
            !r.adequate || r.covered,
            "{} at {}x, seed {}: adequate with an interval excluding its truth",
            r.effect,
            r.magnitude,
            r.seed
        );
        assert!(
            r.adequate || r.rank == Some(1),
            "{} at {}x, seed {}: not adequate, likely missing {:?}",
            r.effect,
            r.magnitude,
            r.seed,
            r.named
        );
    }
}

/// Cells from `PNEUFLEX_HONESTY` (effect:magnitude:seed, comma-separated), else `default`.
fn cells(default: &[(&str, f64, u64)]) -> Vec<(String, f64, u64)> {
    match std::env::var("PNEUFLEX_HONESTY") {
        Ok(s) => s
            .split(',')
            .map(|c| {
                let p: Vec<&str> = c.split(':').collect();
                (
                    p[0].to_string(),
                    p[1].parse().unwrap(),
                    p[2].parse().unwrap(),
                )
            })
            .collect(),
        Err(_) => default
            .iter()
            .map(|&(e, m, s)| (e.to_string(), m, s))
            .collect(),
    }
}

fn run(cells: &[(String, f64, u64)]) -> Vec<Row> {
    print_header();
    cells
        .iter()
        .filter_map(|(e, m, s)| cell(effect(e), *m, *s))
        .collect()
}

/// The quick form for CI: issue 44's seal term of 2e-6 N/Pa (0.25x: found adequate with F_c +174 % outside
/// its interval before), a quarter of the spool travel (0.05 ms: blamed on leakage first before) and a
/// quarter of the polytropic exponent's drop at seed 52 (n = 1.3625: found adequate with C and b outside
/// their widened intervals while the exponent's probe was a secant of one whole probe).
#[test]
fn honest_at_a_quarter_of_the_tests_magnitudes() {
    let rows = run(&cells(&[
        ("seal pressure", 0.25, 51),
        ("spool", 0.25, 51),
        ("polytropic", 0.25, 52),
    ]));
    assert_honest(&rows);
}

/// The full grid: every effect at 0.25, 0.5, 1 and 2x, seeds 51-53 (the table of docs/identification.md).
#[test]
#[ignore = "the full grid: 84 fits, ~30 min in a debug build"]
fn honest_at_every_magnitude() {
    let mut grid = Vec::new();
    for e in &EFFECTS {
        for m in [0.25, 0.5, 1.0, 2.0] {
            for s in [51, 52, 53] {
                grid.push((e.name, m, s));
            }
        }
    }
    let rows = run(&cells(&grid));
    print_header();
    for r in &rows {
        print_row(r);
    }
    assert_honest(&rows);
}

/// Truths of the fitted model (the shipped sheet, the usual six perturbed) on seeds `PNEUFLEX_MATCHED`
/// (a range a..b) or 9170-9179: the fraction found not adequate is the check's false-alarm rate.
#[test]
#[ignore = "calibration: ~10 s per seed in a debug build"]
fn matched_models_false_alarms() {
    let (a, b) = match std::env::var("PNEUFLEX_MATCHED") {
        Ok(s) => {
            let (a, b) = s.split_once("..").unwrap();
            (a.parse::<u64>().unwrap(), b.parse::<u64>().unwrap())
        }
        Err(_) => (9170, 9180),
    };
    let mut alarms = 0;
    let mut covered = 0;
    // Per key, each truth's widened interval width over its noise interval's: the widening's cost.
    let mut cost: Vec<(String, Vec<f64>)> = Vec::new();
    for seed in a..b {
        let scratch = common::scratch("honesty-matched");
        let dir = scratch.path().to_path_buf();
        let (truth, changes) = perturb(&shipped(), &KEYS, seed, &dir.join("truth")).unwrap();
        let log = dir.join("log.csv");
        common::record(&truth, seed, steps(seed), SECONDS, None, &log);
        let id = identify(&request(vec![log], shipped(), names(&KEYS))).unwrap();
        let r = judge("none", "-", 0.0, seed, &id, &changes);
        alarms += usize::from(!r.adequate);
        covered += usize::from(r.covered);
        for e in &id.report.fit.estimates {
            let noise = e.widened.as_ref().map_or(e.ci95, |w| w.noise_ci95);
            let ratio = (e.ci95[1] - e.ci95[0]) / (noise[1] - noise[0]);
            match cost.iter_mut().find(|(k, _)| *k == e.key) {
                Some((_, v)) => v.push(ratio),
                None => cost.push((e.key.clone(), vec![ratio])),
            }
        }
    }
    for (key, mut v) in cost {
        v.sort_by(f64::total_cmp);
        eprintln!(
            "{key}: widened / noise width, median {:.2}, range {:.2}-{:.2}",
            0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2]),
            v[0],
            v[v.len() - 1]
        );
    }
    eprintln!(
        "matched models, seeds {a}..{b}: {alarms} not adequate (false alarms), {covered} with every truth inside"
    );
}
