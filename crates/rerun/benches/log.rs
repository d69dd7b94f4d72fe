//! Cost of one logged control step (10 scalars + 3 link poses) saving to an .rrd file.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_rerun::{RecorderOptions, RunRecorder, Sink, paths};

fn bench_step(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("pneuflex-rerun-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let links = [
        paths::link("rod"),
        paths::link("flange"),
        paths::link("block"),
    ];
    for batch_rows in [1usize, 1024] {
        let opts = RecorderOptions {
            batch_rows,
            send_blueprint: false,
            ..RecorderOptions::default()
        };
        let file = dir.join(format!("bench-{batch_rows}.rrd"));
        let mut rec = RunRecorder::with_options("bench", "bench", &Sink::Save(file), opts).unwrap();
        let mut k = 0u64;
        c.bench_function(
            &format!("step_10_scalars_3_poses_batch_{batch_rows}"),
            |b| {
                b.iter(|| {
                    k += 1;
                    let t = k as f64 * 1e-4;
                    let v = black_box(t.sin());
                    rec.log_scalars(
                        t,
                        &[
                            (paths::F_REF, v),
                            (paths::F_E, v),
                            (paths::X, v),
                            (paths::X_R, v),
                            (paths::P_A, v),
                            (paths::P_B, v),
                            (paths::VALVE_U, v),
                            (paths::ADAPTIVE_G, v),
                            (paths::ADAPTIVE_P, v),
                            (paths::ADAPTIVE_D, v),
                        ],
                    )
                    .unwrap();
                    for l in &links {
                        rec.set_link_pose(t, l, [0.0, 0.0, v], [0.0, 0.0, 0.0, 1.0])
                            .unwrap();
                    }
                })
            },
        );
        rec.finish().unwrap();
    }
    std::fs::remove_dir_all(&dir).ok();
}

criterion_group!(benches, bench_step);
criterion_main!(benches);
