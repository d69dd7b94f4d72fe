//! Collision meshes (issue 27 item 2): a URDF whose flange collides as an STL or OBJ mesh loads, the mesh
//! becomes its convex hull, the hull holds every vertex of the file and has the solid's volume; bad meshes
//! are refused naming the URDF, the link and the mesh.

use std::path::{Path, PathBuf};

use pneuflex_multibody::{CarriageRig, LinkShape, RigConfig, Vector};

fn rig_text() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/rig.urdf"))
        .unwrap()
}

/// The shipped rig with the flange's collision box (0.01 x 0.04 x 0.04 m at x = 0.005) replaced by `mesh`.
fn rig_with_flange_mesh(dir: &Path, mesh: &str) -> PathBuf {
    let text = rig_text();
    let at = text.find("<link name=\"flange\">").unwrap();
    let (head, tail) = text.split_at(at);
    let i = tail.find("<collision>").unwrap();
    let j = tail[i..].find("</collision>").unwrap() + i + "</collision>".len();
    let new = format!(
        "{head}{}<collision>\n      <origin xyz=\"0.005 0 0\"/>\n      <geometry>{mesh}</geometry>\n    </collision>{}",
        &tail[..i],
        &tail[j..]
    );
    let p = dir.join("rig.urdf");
    std::fs::write(&p, new).unwrap();
    p
}

/// The 8 corners of a box of half extents `h` centred on the origin, and 12 outward triangles.
fn box_mesh(h: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let v: Vec<[f64; 3]> = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { -h[0] } else { h[0] },
                if i & 2 == 0 { -h[1] } else { h[1] },
                if i & 4 == 0 { -h[2] } else { h[2] },
            ]
        })
        .collect();
    let faces = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (v, faces)
}

fn write_ascii_stl(path: &Path, v: &[[f64; 3]], faces: &[[usize; 3]]) {
    let mut s = String::from("solid test\n");
    for f in faces {
        s.push_str("facet normal 0 0 0\n outer loop\n");
        for &i in f {
            s.push_str(&format!("  vertex {} {} {}\n", v[i][0], v[i][1], v[i][2]));
        }
        s.push_str(" endloop\nendfacet\n");
    }
    s.push_str("endsolid test\n");
    std::fs::write(path, s).unwrap();
}

fn write_obj(path: &Path, v: &[[f64; 3]], faces: &[[usize; 3]]) {
    let mut s = String::new();
    for p in v {
        s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for f in faces {
        s.push_str(&format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1));
    }
    std::fs::write(path, s).unwrap();
}

/// Every vertex of the file inside the flange's hull, by the hull's own faces (each outward plane) and by
/// parry's point query on the collider Rapier holds (1e-9 m); the hull's volume that of the box (closed
/// form 0.01 x 0.04 x 0.04 m^3).
fn check_flange(urdf: &Path, vertices: &[[f64; 3]], scale: [f64; 3]) {
    let rig =
        CarriageRig::from_urdf(urdf, &RigConfig::paper_rig()).unwrap_or_else(|e| panic!("{e}"));
    let flange = rig
        .link_views()
        .find(|l| l.name == "flange")
        .expect("the flange");
    let (link_pose, geometry) = (flange.pose, flange.collisions);
    let LinkShape::ConvexHull(hull) = &geometry[0].shape else {
        panic!(
            "the flange's collision is not a hull: {:?}",
            geometry[0].shape
        )
    };
    let volume = 0.01 * 0.04 * 0.04;
    assert!(
        (hull.volume() - volume).abs() < 1e-9 * volume,
        "{} vs {volume}",
        hull.volume()
    );
    let local: Vec<[f64; 3]> = vertices
        .iter()
        .map(|v| [v[0] * scale[0], v[1] * scale[1], v[2] * scale[2]])
        .collect();
    let h = &hull.vertices;
    for p in &local {
        for t in &hull.triangles {
            let (a, b, c) = (h[t[0] as usize], h[t[1] as usize], h[t[2] as usize]);
            let (u, w) = (sub(b, a), sub(c, a));
            let n = [
                u[1] * w[2] - u[2] * w[1],
                u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0],
            ];
            let d = sub(*p, a);
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let outside = (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / len;
            assert!(
                outside <= 1e-12,
                "vertex {p:?} is {outside} m outside face {t:?}"
            );
        }
    }
    let physics = rig.physics();
    let hulls: Vec<_> = physics
        .colliders
        .iter()
        .filter(|(_, c)| c.shape().as_convex_polyhedron().is_some())
        .collect();
    assert_eq!(hulls.len(), 1, "one hull collider, the flange's");
    let collider = hulls[0].1;
    let origin = geometry[0].origin;
    for p in &local {
        let world = link_pose * origin * Vector::new(p[0], p[1], p[2]);
        let d = collider
            .shape()
            .distance_to_point(collider.position(), world, true);
        assert!(d <= 1e-9, "vertex {p:?} is {d} m outside the collider");
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[test]
fn an_stl_mesh_collides_as_its_convex_hull() {
    let dir = tempfile::tempdir().unwrap();
    // The flange box as a mesh in millimetres (scaled to metres in the URDF), with a small tetrahedron
    // inside it that the hull must swallow.
    let (mut v, mut f) = box_mesh([5.0, 20.0, 20.0]);
    let n = v.len();
    v.extend([
        [1.0, 1.0, 1.0],
        [-2.0, 3.0, 0.5],
        [0.5, -4.0, 2.0],
        [0.0, 0.0, -6.0],
    ]);
    f.extend([
        [n, n + 1, n + 2],
        [n, n + 3, n + 1],
        [n + 1, n + 3, n + 2],
        [n, n + 2, n + 3],
    ]);
    write_ascii_stl(&dir.path().join("flange.stl"), &v, &f);
    let urdf = rig_with_flange_mesh(
        dir.path(),
        "<mesh filename=\"flange.stl\" scale=\"0.001 0.001 0.001\"/>",
    );
    check_flange(&urdf, &v, [0.001; 3]);
}

#[test]
fn an_obj_mesh_collides_as_its_convex_hull() {
    let dir = tempfile::tempdir().unwrap();
    let (v, f) = box_mesh([0.005, 0.02, 0.02]);
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    write_obj(&dir.path().join("meshes/flange.obj"), &v, &f);
    let urdf = rig_with_flange_mesh(dir.path(), "<mesh filename=\"meshes/flange.obj\"/>");
    check_flange(&urdf, &v, [1.0; 3]);
}

/// What the builder refuses, each naming the URDF, the link and the mesh.
#[test]
fn bad_meshes_are_refused_naming_the_link_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (v, f) = box_mesh([0.005, 0.02, 0.02]);
    write_ascii_stl(&dir.path().join("ok.stl"), &v, &f);
    // A flat mesh: the box squashed to z = 0.
    let flat: Vec<[f64; 3]> = v.iter().map(|p| [p[0], p[1], 0.0]).collect();
    write_ascii_stl(&dir.path().join("flat.stl"), &flat, &f);
    std::fs::write(
        dir.path().join("garbage.stl"),
        "solid x\nfacet normal nonsense\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("flange.ply"), "ply\n").unwrap();
    for (mesh, expect) in [
        ("<mesh filename=\"missing.stl\"/>", "missing.stl"),
        (
            "<mesh filename=\"package://rig/flange.stl\"/>",
            "package://",
        ),
        ("<mesh filename=\"flange.ply\"/>", ".stl or .obj"),
        ("<mesh filename=\"flat.stl\"/>", "no volume"),
        ("<mesh filename=\"garbage.stl\"/>", "garbage.stl"),
        ("<mesh filename=\"ok.stl\" scale=\"1 0 1\"/>", "scale"),
    ] {
        let urdf = rig_with_flange_mesh(dir.path(), mesh);
        let msg = match CarriageRig::from_urdf(&urdf, &RigConfig::paper_rig()) {
            Ok(_) => panic!("{mesh} accepted"),
            Err(e) => e.to_string(),
        };
        assert!(
            msg.contains("rig.urdf") && msg.contains("'flange'") && msg.contains(expect),
            "{mesh}: {msg}"
        );
    }
}

/// The shipped rig with a `<visual>` mesh added to the flange, `mesh` the geometry element.
fn rig_with_flange_visual(dir: &Path, mesh: &str) -> PathBuf {
    let text = rig_text();
    // Beside the flange's own <visual> (the URDF reader wants a link's visuals together).
    let link = text.find("<link name=\"flange\">").unwrap();
    let at = link + text[link..].find("</visual>").unwrap() + "</visual>".len();
    let new = format!(
        "{}\n    <visual>\n      <origin xyz=\"0.005 0 0\" rpy=\"0 0 0.5\"/>\n      <geometry>{mesh}</geometry>\n    </visual>{}",
        &text[..at],
        &text[at..]
    );
    let p = dir.join("rig.urdf");
    std::fs::write(&p, new).unwrap();
    p
}

#[test]
fn a_visual_mesh_is_kept_whole_for_viewers_and_a_bad_one_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    // A box in mm, scaled to m: every triangle of the file, every vertex scaled, at the visual's origin.
    let (v, faces) = box_mesh([5.0, 20.0, 20.0]);
    write_obj(&dir.path().join("flange.obj"), &v, &faces);
    let urdf = rig_with_flange_visual(
        dir.path(),
        "<mesh filename=\"flange.obj\" scale=\"0.001 0.001 0.001\"/>",
    );
    let rig =
        CarriageRig::from_urdf(&urdf, &RigConfig::paper_rig()).unwrap_or_else(|e| panic!("{e}"));
    let flange = rig.link_views().find(|l| l.name == "flange").unwrap();
    assert_eq!(flange.visual_meshes.len(), 1);
    let (origin, mesh) = &flange.visual_meshes[0];
    // The same triangles as the file's (the reader may number the vertices anew): corners in mm.
    let corners = |tri: [[f64; 3]; 3]| tri.map(|p| p.map(|c| (c * 1e3).round() as i64));
    let mut got: Vec<_> = mesh
        .triangles
        .iter()
        .map(|t| corners(t.map(|i| mesh.vertices[i as usize])))
        .collect();
    let mut want: Vec<_> = faces
        .iter()
        .map(|f| corners(f.map(|i| v[i].map(|c| 1e-3 * c))))
        .collect();
    got.sort();
    want.sort();
    assert_eq!(got, want);
    assert!((origin.translation.x - 0.005).abs() < 1e-15);
    // The collision stays the URDF's box; links without visual meshes have none.
    assert!(matches!(flange.collisions[0].shape, LinkShape::Box { .. }));
    assert!(
        rig.link_views()
            .filter(|l| l.name != "flange")
            .all(|l| l.visual_meshes.is_empty())
    );
    // A visual mesh that cannot be read is refused, naming the URDF, the link, <visual> and the file.
    let urdf = rig_with_flange_visual(dir.path(), "<mesh filename=\"nowhere.stl\"/>");
    let e = CarriageRig::from_urdf(&urdf, &RigConfig::paper_rig())
        .err()
        .expect("refused")
        .to_string();
    for w in ["rig.urdf", "link 'flange' <visual>", "nowhere.stl"] {
        assert!(e.contains(w), "{e:?} lacks {w:?}");
    }
}
