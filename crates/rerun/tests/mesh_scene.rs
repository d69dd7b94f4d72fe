//! scenes/jaw-gripper.toml, the shipped scene whose URDF uses a mesh (urdf/meshes/jaw_pad.obj as each
//! finger's `<visual>` and `<collision>`): recorded to an .rrd and read back with Rerun's decoder, each finger's
//! visual mesh holds the file's vertices and triangles (counts and vertex values, the file parsed here on its
//! own) and its collision hull the file's corners (count and bounds). Its run's closed form: tests/cli_mesh_scene.rs.

use std::path::{Path, PathBuf};

use pneuflex_rerun::{MechanismRecorder, Sink, paths, sink_for_run};
use pneuflex_scene::mechanism::{self, MechanismScene};
use re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};

mod common;
use common::{read_back, temp_dir};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// The OBJ's vertices and triangle count, read line by line (`v x y z`, `f a b c`), apart from the mesh reader.
fn obj(path: &Path) -> (Vec<[f64; 3]>, usize) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut vertices = Vec::new();
    let mut faces = 0;
    for line in text.lines() {
        let mut w = line.split_whitespace();
        match w.next() {
            Some("v") => {
                let c: Vec<f64> = w.map(|s| s.parse().unwrap()).collect();
                vertices.push([c[0], c[1], c[2]]);
            }
            Some("f") => faces += 1,
            _ => {}
        }
    }
    (vertices, faces)
}

fn bounds(v: impl Iterator<Item = [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in v {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// The Mesh3D logged at `entity` (with its leading `/`), from the .rrd: its vertex positions and its
/// triangles' count.
fn logged_mesh(file: &Path, entity: &str) -> Option<(Vec<[f64; 3]>, usize)> {
    let reader = std::io::BufReader::new(std::fs::File::open(file).unwrap());
    let positions = rerun::Mesh3D::descriptor_vertex_positions().component;
    let triangles = rerun::Mesh3D::descriptor_triangle_indices().component;
    for msg in DecoderApp::decode_eager(reader).unwrap() {
        let LogMsg::ArrowMsg(store, arrow) = msg.unwrap() else {
            continue;
        };
        if !store.is_recording() {
            continue;
        }
        let chunk = Chunk::from_arrow_msg(&arrow).unwrap();
        if chunk.entity_path().to_string() != entity {
            continue;
        }
        if let Some(rows) = chunk.iter_slices::<[f32; 3]>(positions).next() {
            let n = chunk
                .iter_slices::<[u32; 3]>(triangles)
                .next()
                .map_or(0, |t| t.len());
            return Some((rows.iter().map(|v| v.map(f64::from)).collect(), n));
        }
    }
    None
}

#[test]
fn the_jaw_gripper_recording_holds_each_jaw_pad_mesh_as_the_file_gives_it() {
    let scene_path = repo("scenes/jaw-gripper.toml");
    let scene = MechanismScene::load(&scene_path).unwrap();
    let (file_vertices, file_triangles) = obj(&repo("urdf/meshes/jaw_pad.obj"));
    // The pad as jaw_pad.py writes it: 12 corners, 20 triangles, 30 x 10 x 30 mm.
    assert_eq!((file_vertices.len(), file_triangles), (12, 20));
    let (file_lo, file_hi) = bounds(file_vertices.iter().copied());

    let dir = temp_dir("mesh-scene");
    let sink = Sink::Save(dir.path().join("jaw-gripper.rrd"));
    let mut rec = MechanismRecorder::new(sink.clone(), &scene).unwrap();
    let runs = mechanism::run_all(&scene, &mut |_| {}, None, &mut rec).unwrap();
    rec.finish().unwrap();
    assert_eq!(runs.len(), 1);
    let run = &runs[0];
    assert!(
        run.diverged.is_none() && run.interrupted.is_none(),
        "{:?} {:?}",
        run.diverged,
        run.interrupted
    );
    let Sink::Save(file) = sink_for_run(&sink, &run.name, 1) else {
        unreachable!()
    };
    assert!(
        read_back(&file).has_footer,
        "{}: unfinished",
        file.display()
    );

    // STL/OBJ vertices are logged as f32: equal to the file's within f32 rounding of a few cm.
    let close = |a: [f64; 3], b: [f64; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-8);
    for finger in ["finger_left", "finger_right"] {
        let entity = format!("/{}", paths::link(&format!("{finger}/visual/0")));
        let (drawn, triangles) = logged_mesh(&file, &entity)
            .unwrap_or_else(|| panic!("{}: no mesh at {entity}", file.display()));
        assert_eq!(
            (drawn.len(), triangles),
            (file_vertices.len(), file_triangles),
            "{entity}: vertices and triangles"
        );
        // The reader may order the vertices its own way: the same points, each once.
        for f in &file_vertices {
            let n = drawn.iter().filter(|d| close(**d, *f)).count();
            assert_eq!(n, 1, "{entity}: the file's vertex {f:?} drawn {n} times");
        }
        // The collision shape is the mesh's convex hull: every corner of this convex pad is on it.
        let entity = format!("/{}", paths::link(finger));
        let (hull, _) = logged_mesh(&file, &entity)
            .unwrap_or_else(|| panic!("{}: no hull at {entity}", file.display()));
        let (lo, hi) = bounds(hull.iter().copied());
        assert!(
            close(lo, file_lo) && close(hi, file_hi),
            "{entity}: hull bounds {lo:?}..{hi:?}, the file's {file_lo:?}..{file_hi:?}"
        );
        assert_eq!(hull.len(), file_vertices.len(), "{entity}: hull vertices");
    }
}
