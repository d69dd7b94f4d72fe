//! `pneuflex run scenes/jaw-gripper.toml`: the shipped scene whose URDF uses a mesh (urdf/meshes/jaw_pad.obj
//! as each finger's `<visual>` and `<collision>`) loads and runs, and each finger holds its set point at the
//! stroke the mesh's geometry gives: the jaw's contact face is the mesh's largest y ahead of the finger's
//! frame, so it touches the part at x_touch = 0.06 - 0.02 - y_face (joint origin 0.06 m from the centre, the
//! part 0.04 m wide) and holds f on the k = 8 kN/m pad at x = x_touch + f / k.

use std::path::Path;
use std::process::Command;

/// The OBJ's vertices, read line by line (`v x y z`), apart from the mesh reader.
fn obj_vertices(path: &Path) -> Vec<[f64; 3]> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f64> = l.split_whitespace().map(|s| s.parse().unwrap()).collect();
            [c[0], c[1], c[2]]
        })
        .collect()
}

#[test]
fn the_jaw_gripper_with_mesh_pads_holds_each_set_point_at_the_stroke_its_mesh_gives() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let vertices = obj_vertices(&root.join("urdf/meshes/jaw_pad.obj"));
    assert_eq!(
        vertices.len(),
        12,
        "jaw_pad.obj as urdf/meshes/jaw_pad.py writes it"
    );
    let y_face = vertices
        .iter()
        .map(|v| v[1])
        .fold(f64::NEG_INFINITY, f64::max);
    let x_touch = 0.06 - 0.02 - y_face;
    let k = 8000.0;

    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("jaw");
    let o = Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args([
            "run",
            "scenes/jaw-gripper.toml",
            "--out",
            out.to_str().unwrap(),
        ])
        .current_dir(root)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let trace = std::fs::read_to_string(out.join("impedance/trace.csv")).unwrap();
    let mut lines = trace.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|s| s.parse().unwrap()).collect())
        .collect();
    // 4 s at 1 ms: every tick is there (a diverged run would be cut short and named trace.diverged.csv).
    assert_eq!(rows.len(), 4001);
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("{name}: {header:?}"))
    };
    for side in ["left", "right"] {
        let (x, f_e) = (col(&format!("{side}.x")), col(&format!("{side}.f_e")));
        for (t0, t1, f) in [(1.0, 2.0, 8.0), (3.0, 4.0, 12.0)] {
            let w: Vec<&Vec<f64>> = rows.iter().filter(|r| r[0] >= t0 && r[0] < t1).collect();
            let mean = |c: usize| w.iter().map(|r| r[c]).sum::<f64>() / w.len() as f64;
            let want = x_touch + f / k;
            // Measured: within 0.5 µm of x_touch + f / k; a 1 mm error in the face would be 2000x this bound.
            assert!(
                (mean(x) - want).abs() < 5e-6,
                "{side}, {t0}-{t1} s: stroke {} m, x_touch + f / k = {want} m",
                mean(x)
            );
            assert!(
                (mean(f_e) - f).abs() < 0.01 * f,
                "{side}, {t0}-{t1} s: mean f_e {} N, set point {f} N",
                mean(f_e)
            );
        }
    }
}
