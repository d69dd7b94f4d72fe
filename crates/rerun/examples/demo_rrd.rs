//! Writes a small demo recording: `cargo run -p pneuflex-rerun --example demo_rrd -- out.rrd [steps]`.
//! Used to check `scripts/check_rrd.py` and to look at the default layout in a viewer.

use pneuflex_rerun::{ChamberSample, Contact, EventLevel, LinkShape, RunRecorder, Sink, paths};
use pneuflex_scene::plants::VisualShape;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let file = args.next().ok_or("usage: demo_rrd OUT.rrd [STEPS]")?;
    let steps: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(2000);
    let dt = 1e-3;
    let mut rec = RunRecorder::new("pneuflex-demo", "demo", &Sink::Save(file.into()))?;
    rec.log_link_shape(&LinkShape {
        entity: paths::link("flange"),
        shape: VisualShape::Cylinder {
            radius_m: 0.03,
            half_length_m: 0.005,
        },
        colour: [200, 200, 210, 255],
    })?;
    rec.log_link_shape(&LinkShape {
        entity: paths::link("block"),
        shape: VisualShape::Box {
            half_extents_m: [0.04, 0.04, 0.02],
        },
        colour: [110, 80, 60, 255],
    })?;
    rec.set_link_pose(
        0.0,
        &paths::link("block"),
        [0.0, 0.0, 0.135],
        [0.0, 0.0, 0.0, 1.0],
    )?;
    rec.set_chamber_bore(0.032)?;
    rec.log_event(0.0, EventLevel::Info, "start")?;
    let (k_env, x_wall) = (2.0e4, 0.11);
    for k in 0..steps {
        let t = k as f64 * dt;
        // A first-order approach to the wall and a linear spring behind it: demo data only.
        let x = 0.12 * (1.0 - (-t / 0.3).exp());
        let f_e = (k_env * (x - x_wall)).max(0.0);
        let (p_a, p_b) = (1.0e5 + 4.0e5 * x / 0.12, 3.0e5 - 1.5e5 * x / 0.12);
        rec.log_scalars(
            t,
            &[
                (paths::F_REF, 50.0),
                (paths::F_E, f_e),
                (paths::X, x),
                (paths::X_R, 0.12),
                (paths::P_A, p_a),
                (paths::P_B, p_b),
                (paths::VALVE_U, (50.0 - f_e) / 50.0),
                (paths::VALVE_SPOOL, (k % 10 < 5) as u8 as f64),
                (paths::ADAPTIVE_G, 1.0),
                (paths::ADAPTIVE_P, 0.5),
                (paths::ADAPTIVE_D, 0.1),
            ],
        )?;
        rec.set_link_pose(
            t,
            &paths::link("flange"),
            [0.0, 0.0, 0.02 + x],
            [0.0, 0.0, 0.0, 1.0],
        )?;
        let contact = (f_e > 0.0).then_some(Contact {
            point_m: [0.0, 0.0, 0.115],
            force_n: [0.0, 0.0, f_e],
            arrow_from_m: [0.0, 0.04, 0.115],
        });
        rec.log_contact(t, contact.as_ref())?;
        rec.log_chambers(
            t,
            &ChamberSample {
                length_a_m: 0.01 + x,
                pressure_a_pa: p_a,
                length_b_m: 0.14 - x,
                pressure_b_pa: p_b,
            },
        )?;
        if k > 0
            && f_e > 0.0
            && contact.is_some()
            && (k_env * (0.12 * (1.0 - (-(t - dt) / 0.3).exp()) - x_wall)) <= 0.0
        {
            rec.log_event(t, EventLevel::Info, "contact with block")?;
        }
    }
    rec.finish()?;
    Ok(())
}
