//! One controller update, impedance and adaptive. The crate is no_std without alloc, so an
//! update cannot allocate.
use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_control::{
    AdaptiveImpedanceController, AdaptiveParams, Controller, ImpedanceController, ImpedanceParams,
    PidParams, Sensors, Setpoint,
};
use std::hint::black_box;

fn bench_update(c: &mut Criterion) {
    let dt = 1e-3;
    let mut imp =
        ImpedanceController::new(ImpedanceParams::default(), PidParams::default()).unwrap();
    let mut ada = AdaptiveImpedanceController::new(
        ImpedanceParams::default(),
        AdaptiveParams::default(),
        PidParams::default(),
    )
    .unwrap();
    let sensors = Sensors {
        t: 1.0,
        x: 0.012,
        x_dot: 0.01,
        f_e: 9.0,
        p_a: 3e5,
        p_b: 2e5,
    };
    let sp = Setpoint {
        f_ref: 10.0,
        x_d: 0.0,
    };
    // Alternate the measurement a little so the optimiser cannot fold the state.
    let mut k = 0u32;
    c.bench_function("impedance_update", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let s = Sensors {
                f_e: sensors.f_e + (k & 7) as f64 * 0.01,
                ..sensors
            };
            black_box(imp.update(black_box(&s), black_box(&sp), black_box(dt)))
        })
    });
    c.bench_function("adaptive_update", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let s = Sensors {
                f_e: sensors.f_e + (k & 7) as f64 * 0.01,
                ..sensors
            };
            black_box(ada.update(black_box(&s), black_box(&sp), black_box(dt)))
        })
    });
}

criterion_group!(benches, bench_update);
criterion_main!(benches);
