//! What viewers draw of a URDF: every collision shape, then every visual mesh whole, each at its pose.

use std::path::Path;

use pneuflex_multibody::{CarriageRig, RigConfig};
use pneuflex_scene::plants::{VisualRole, VisualShape, drawn_links, drawn_poses};

#[test]
fn a_visual_mesh_is_drawn_whole_at_its_link_pose_times_its_origin() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let text = std::fs::read_to_string(root.join("urdf/rig.urdf")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // A tetrahedron as the flange's visual mesh, turned 0.5 rad about z and moved 5 mm along x.
    std::fs::write(
        dir.path().join("tip.obj"),
        "v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nv 0 0 0.01\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let link = text.find("<link name=\"flange\">").unwrap();
    let at = link + text[link..].find("</visual>").unwrap() + "</visual>".len();
    let urdf = format!(
        "{}\n    <visual>\n      <origin xyz=\"0.005 0 0\" rpy=\"0 0 0.5\"/>\n      <geometry><mesh filename=\"tip.obj\"/></geometry>\n    </visual>{}",
        &text[..at],
        &text[at..]
    )
    .replace("filename=\"../", &format!("filename=\"{}/", root.display()));
    let path = dir.path().join("rig.urdf");
    std::fs::write(&path, urdf).unwrap();
    let rig = CarriageRig::from_urdf(&path, &RigConfig::paper_rig()).unwrap();

    let drawn = drawn_links(rig.link_views(), |_| VisualRole::Other);
    let i = drawn
        .iter()
        .position(|v| v.name == "flange/visual/0")
        .expect("the visual mesh");
    let VisualShape::Mesh { triangles, .. } = &drawn[i].shape else {
        panic!("{:?}", drawn[i].shape)
    };
    assert_eq!(triangles.len(), 4);
    // One pose per drawn shape, in order; the mesh's is the flange's pose times its origin.
    let mut poses = Vec::new();
    drawn_poses(
        rig.link_views(),
        pneuflex_multibody::Pose::IDENTITY,
        &mut |k, p| {
            assert_eq!(k, poses.len());
            poses.push(p);
        },
    );
    assert_eq!(poses.len(), drawn.len());
    let flange = rig.link_views().find(|l| l.name == "flange").unwrap().pose;
    let t = poses[i].translation_m;
    assert!(
        (t[0] - (flange.translation.x + 0.005)).abs() < 1e-12,
        "{t:?}"
    );
    let q = poses[i].rotation_xyzw;
    // Half the turn about z: (0, 0, sin 0.25, cos 0.25) on the flange's identity rotation.
    assert!(
        (q[2] - 0.25f64.sin()).abs() < 1e-12 && (q[3] - 0.25f64.cos()).abs() < 1e-12,
        "{q:?}"
    );
}
