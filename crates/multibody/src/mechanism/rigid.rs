//! Rigid contacts: Rapier's own contact solver between the colliders of two links, for a contact whose
//! compliance lives elsewhere (a face on a spring mount: the mount is the environment's k_e, the contact
//! itself is as stiff as the solver makes it). The contact-force sensor reads the solver's normal impulse
//! over the step, F = Σ λ_n / h.
//!
//! A pad ([`super::ContactConfig`]) is explicit in its own stiffness and needs a step short against the
//! light body it touches (ω h < 2); a rigid contact has no stiffness of its own and keeps the mechanism's
//! step whatever the masses, which is what the paper's rig needs (a 9 g face behind a 700 N/m mount,
//! stepped at 1 or 2 ms).

use rapier3d_f64::prelude::*;

use super::{ContactReading, Mechanism, link};
use crate::error::MultibodyError;

/// A rigid contact between two links' colliders, solved by Rapier (frictional, no stiffness of its own).
#[derive(Debug, Clone, PartialEq)]
pub struct RigidContactConfig {
    /// Its name (the contact-force sensor's name).
    pub name: String,
    /// One side's link.
    pub link_a: String,
    /// The other side's link.
    pub link_b: String,
    /// Coulomb friction coefficient of the two links' colliders, -.
    pub friction: f64,
}

/// A rigid contact as built.
#[derive(Debug, Clone)]
pub(super) struct BuiltRigid {
    pub(super) name: String,
    /// Every collider of link a against every collider of link b.
    pairs: Vec<(ColliderHandle, ColliderHandle)>,
}

/// The rigid contacts of a mechanism and what they read over the last step.
#[derive(Debug, Clone, Default)]
pub(super) struct RigidContacts {
    pub(super) built: Vec<BuiltRigid>,
    pub(super) readings: Vec<ContactReading>,
    /// Each link's collision-group bit (index into `rig.links`, bit).
    groups: Vec<(usize, u32)>,
}

impl RigidContacts {
    /// What each contact did over the step just taken: Σ λ_n / h over its touching pairs, and the
    /// deepest penetration the solver saw.
    pub(super) fn read(&mut self, world: &PhysicsWorld) {
        let h = world.integration_parameters.dt;
        for (c, r) in self.built.iter().zip(self.readings.iter_mut()) {
            *r = ContactReading::default();
            for &(a, b) in &c.pairs {
                let Some(pair) = world.contact_pair(a, b) else {
                    continue;
                };
                if !pair.has_any_active_contact() {
                    continue;
                }
                r.force_n += pair.total_impulse_magnitude() / h;
                if let Some((_, deepest)) = pair.find_deepest_contact() {
                    r.penetration_m = r.penetration_m.max(-deepest.dist);
                }
            }
        }
    }
}

impl Mechanism {
    /// Adds a rigid contact between two links (Rapier's solver, friction `config.friction`), returning
    /// its index for [`Mechanism::rigid_contact`]. The two links' colliders are paired with each other and
    /// with the links of the other rigid contacts they name, nothing else.
    pub fn add_rigid_contact(
        &mut self,
        config: &RigidContactConfig,
    ) -> Result<usize, MultibodyError> {
        let rig = &self.rig;
        let item = config.name.as_str();
        if self.rigid.built.iter().any(|c| c.name == config.name) {
            return Err(super::bad(
                rig,
                "rigid contact",
                item,
                "name",
                "is listed twice".into(),
            ));
        }
        let la = link(rig, "rigid contact", item, "link_a", &config.link_a)?;
        let lb = link(rig, "rigid contact", item, "link_b", &config.link_b)?;
        for (key, l) in [("link_a", la), ("link_b", lb)] {
            if rig.links[l].colliders.is_empty() {
                return Err(super::bad(
                    rig,
                    "rigid contact",
                    item,
                    key,
                    format!(
                        "link '{}' has no <collision> element to touch with",
                        rig.links[l].name
                    ),
                ));
            }
        }
        if rig.links[la].body == rig.links[lb].body {
            return Err(super::bad(
                rig,
                "rigid contact",
                item,
                "link_b",
                format!(
                    "'{}' and '{}' are one rigid body: they cannot touch",
                    config.link_a, config.link_b
                ),
            ));
        }
        if !(config.friction.is_finite() && config.friction >= 0.0) {
            return Err(super::bad(
                rig,
                "rigid contact",
                item,
                "friction",
                format!("must be finite and >= 0, got {}", config.friction),
            ));
        }
        // One collision-group bit per link that takes part; a link's filter is the bits of its partners.
        for l in [la, lb] {
            if !self.rigid.groups.iter().any(|(x, _)| *x == l) {
                let bit = self.rigid.groups.len() as u32;
                if bit >= 32 {
                    return Err(super::bad(
                        rig,
                        "rigid contact",
                        item,
                        "link_a",
                        "at most 32 links can take part in rigid contacts".into(),
                    ));
                }
                self.rigid.groups.push((l, 1 << bit));
            }
        }
        let pairs = rig.links[la]
            .colliders
            .iter()
            .flat_map(|&a| rig.links[lb].colliders.iter().map(move |&b| (a, b)))
            .collect();
        self.rigid.built.push(BuiltRigid {
            name: config.name.clone(),
            pairs,
        });
        self.rigid.readings.push(ContactReading::default());
        self.pair_links(la, lb, config.friction);
        let ip = &mut self.rig.world.integration_parameters;
        // Near-rigid contacts (the compliance lives in the mounts), no CCD substeps: the faces move by µm.
        ip.contact_softness = SpringCoefficients::new(1.0e6, 1.0);
        ip.static_contact_softness = SpringCoefficients::new(1.0e6, 1.0);
        ip.max_ccd_substeps = 0;
        ip.contact_recycling = false;
        Ok(self.rigid.built.len() - 1)
    }

    /// Index of the named rigid contact.
    pub fn rigid_contact_index(&self, name: &str) -> Result<usize, MultibodyError> {
        self.rigid
            .built
            .iter()
            .position(|c| c.name == name)
            .ok_or_else(|| {
                super::unknown(
                    &self.rig,
                    "rigid contact",
                    name,
                    self.rigid.built.iter().map(|c| c.name.as_str()),
                )
            })
    }

    /// What rigid contact `i` did over the last step: its normal force is the contact-force sensor.
    pub fn rigid_contact(&self, i: usize) -> ContactReading {
        self.rigid.readings[i]
    }

    /// Enables the colliders of links `la` and `lb` for each other (and keeps their other partners).
    fn pair_links(&mut self, la: usize, lb: usize, friction: f64) {
        let bit = |l: usize| {
            self.rigid
                .groups
                .iter()
                .find(|(x, _)| *x == l)
                .map_or(0, |(_, b)| *b)
        };
        let (ba, bb) = (bit(la), bit(lb));
        for (l, own, partner) in [(la, ba, bb), (lb, bb, ba)] {
            for &h in &self.rig.links[l].colliders {
                let c = &mut self.rig.world.colliders[h];
                let old = c.collision_groups();
                let filter = if c.is_enabled() {
                    old.filter.bits() | partner
                } else {
                    partner
                };
                c.set_collision_groups(InteractionGroups::new(
                    Group::from_bits_truncate(own),
                    Group::from_bits_truncate(filter),
                    InteractionTestMode::And,
                ));
                c.set_friction(friction);
                c.set_enabled(true);
            }
        }
    }
}
