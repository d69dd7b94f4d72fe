//! A mechanism as viewers draw it: every collision shape and visual mesh of every link, and their poses
//! now (the same drawing as the paper rig's, [`crate::plants::drawn_links`]).

use pneuflex_multibody::{Mechanism, Pose};

use crate::plants::{Visual, VisualPose, VisualRole, drawn_links, drawn_poses};

/// The shapes: `<link>` (or `<link>/<i>`) for collision shapes, `<link>/visual/<i>` for visual meshes.
pub fn visuals(m: &Mechanism) -> Vec<Visual> {
    drawn_links(m.link_views(), |_| VisualRole::Other)
}

/// The pose of each of [`visuals`]' shapes now, in that order.
pub fn visual_poses(m: &Mechanism, pose: &mut dyn FnMut(usize, VisualPose)) {
    drawn_poses(m.link_views(), Pose::IDENTITY, pose)
}
