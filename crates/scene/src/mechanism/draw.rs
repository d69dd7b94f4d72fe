//! A mechanism as viewers draw it: every collision shape of every link, and their poses now.

use pneuflex_multibody::Mechanism;

use crate::plants::{Visual, VisualPose, VisualRole, VisualShape};

/// The shapes, named `<link>` (or `<link>/<i>` for a link's i-th of several).
pub fn visuals(m: &Mechanism) -> Vec<Visual> {
    let mut out = Vec::new();
    for (link, _, geoms) in m.link_poses() {
        for (j, g) in geoms.iter().enumerate() {
            out.push(Visual {
                name: if geoms.len() == 1 {
                    link.to_string()
                } else {
                    format!("{link}/{j}")
                },
                shape: VisualShape::of(&g.shape),
                role: VisualRole::Other,
            });
        }
    }
    out
}

/// The pose of each of [`visuals`]' shapes now, in that order.
pub fn visual_poses(m: &Mechanism, pose: &mut dyn FnMut(usize, VisualPose)) {
    let mut i = 0;
    for (_, link, geoms) in m.link_poses() {
        for g in geoms {
            let p = link * g.origin;
            let (t, q) = (p.translation, p.rotation);
            pose(
                i,
                VisualPose {
                    translation_m: [t.x, t.y, t.z],
                    rotation_xyzw: [q.x, q.y, q.z, q.w],
                },
            );
            i += 1;
        }
    }
}
