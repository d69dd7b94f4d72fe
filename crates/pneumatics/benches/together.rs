//! Eight plants of the paper's actuator over 1 ms control periods (10 RK4 substeps each, PWM valve, each
//! plant its own mass, command and spring): stepped one after another (`OneDofModel::advance`) and together
//! (`advance_together`, packed arithmetic), interleaved in rounds on one thread. Prints the time per plant
//! and period of each, and their ratio per round (min / median / max), and checks the two runs ended in the
//! same states. `cargo bench -p pneuflex-pneumatics --bench together [-- ROUNDS]`.

use std::hint::black_box;
use std::time::Instant;

use pneuflex_pneumatics::{
    ActuatorSheet, ChamberState, OneDofModel, OneDofState, PACK, Together, advance_together,
};

const N: usize = PACK;
/// Control periods per timed slice.
const PERIODS: u64 = 2000;

fn main() {
    let rounds: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(30);
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../pneumatics/paper-actuator.toml");
    let base = ActuatorSheet::load(path).expect("shipped sheet").model();
    let models: [OneDofModel; N] = std::array::from_fn(|i| {
        let mut m = base;
        m.mechanics.moving_mass_kg *= 0.8 + 0.05 * i as f64;
        m
    });
    let start = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 2.8e5), 0.0);
    let spring = |x: f64| -1400.0 * (x - 0.02).max(0.0);
    let gravity = models.map(|m| m.mechanics.gravity_force());
    let command = |k: u64, i: usize| {
        if (k / 40 + i as u64).is_multiple_of(2) {
            0.3
        } else {
            -0.3
        }
    };
    let restart = |s: &mut [OneDofState; N]| {
        for s in s.iter_mut() {
            if s.x <= 0.001 || s.x >= 0.049 {
                *s = start;
            }
        }
    };
    let (mut alone, mut together) = ([start; N], [start; N]);
    let (mut k_alone, mut k_together) = (0u64, 0u64);
    let (mut t_alone, mut t_together, mut ratio) = (vec![], vec![], vec![]);
    for _ in 0..rounds {
        let t0 = Instant::now();
        for _ in 0..PERIODS {
            k_alone += 1;
            for (i, (m, s)) in models.iter().zip(alone.iter_mut()).enumerate() {
                m.advance(
                    black_box(s),
                    command(k_alone, i),
                    gravity[i],
                    1e-3,
                    10,
                    spring,
                );
            }
            restart(&mut alone);
        }
        let a = t0.elapsed().as_secs_f64() / (PERIODS * N as u64) as f64;
        let t0 = Instant::now();
        for _ in 0..PERIODS {
            k_together += 1;
            let plants = Together {
                models: std::array::from_fn(|i| &models[i]),
                states: together.each_mut().map(black_box),
                u: std::array::from_fn(|i| command(k_together, i)),
                gravity_n: gravity,
            };
            advance_together(plants, 1e-3, 10, &mut |_, x| spring(x));
            restart(&mut together);
        }
        let b = t0.elapsed().as_secs_f64() / (PERIODS * N as u64) as f64;
        t_alone.push(a * 1e6);
        t_together.push(b * 1e6);
        ratio.push(a / b);
    }
    assert_eq!(
        format!("{alone:?}"),
        format!("{together:?}"),
        "the two runs differ"
    );
    let stats = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        format!(
            "{:.3} (min {:.3}, max {:.3})",
            v[v.len() / 2],
            v[0],
            v[v.len() - 1]
        )
    };
    println!(
        "{N} plants, 1 ms periods of 10 RK4 substeps, {rounds} rounds of {PERIODS} periods, interleaved:"
    );
    println!(
        "  alone     us per plant and period: {}",
        stats(&mut t_alone)
    );
    println!(
        "  together  us per plant and period: {}",
        stats(&mut t_together)
    );
    println!("  alone / together:                  {}", stats(&mut ratio));
}
