//! One fixed RK4 step of the full nonlinear 1-DOF model (chambers with temperatures, ISO 6358 flows,
//! PWM 5/2 valve, friction, incline), and one chamber-only RK4 step as used by the Rapier force element.
use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_pneumatics::*;

fn sheet() -> ActuatorSheet {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../pneumatics/paper-actuator.toml");
    ActuatorSheet::load(path).expect("shipped actuator sheet")
}

fn bench(c: &mut Criterion) {
    let model = sheet().model();
    let dt = 1e-4;
    let mut st = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 2.8e5), 0.0);
    let mut k = 0u64;
    c.bench_function("one_dof_rk4_step_pwm", |b| {
        b.iter(|| {
            // A command that keeps the valve switching and the piston moving mid-stroke.
            k += 1;
            let u = if (k / 400).is_multiple_of(2) {
                0.3
            } else {
                -0.3
            };
            model.step(black_box(&mut st), black_box(u), black_box(-2.0), dt);
            if st.x <= 0.001 || st.x >= 0.049 {
                st = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 2.8e5), 0.0);
            }
        })
    });
    let act = model.actuator;
    let mut s = ChamberState::new(3.0e5, 2.8e5);
    c.bench_function("chambers_rk4_step", |b| {
        b.iter(|| {
            act.step_chambers(
                black_box(&mut s),
                black_box(0.025),
                black_box(0.01),
                black_box(1.0),
                dt,
            );
            if s.p_a > 5.5e5 {
                s = ChamberState::new(3.0e5, 2.8e5);
            }
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
