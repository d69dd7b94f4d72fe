//! `[plant]`: which plant the controllers drive. Its kinds, keys and checks are the plants' own
//! ([`crate::plants::PlantSpec`], beside the plants they build); here the scene checks and builds its plant.

use super::Scene;
use crate::error::SceneError;
use crate::origin::Check;
use crate::plants::{
    LinearPlant, LinearSpring, Linearisable, MultibodyPlant, OneDofPneumatic, Plant, PlantSite,
};
pub use crate::plants::{MaterialSpec, MultibodySpec, PlantSpec};

impl Scene {
    /// What the plant is checked and built against: the scene's origin, control period, environment and
    /// events.
    pub fn plant_site(&self) -> PlantSite<'_> {
        PlantSite {
            origin: self.origin(),
            dt_s: self.dt_s,
            environment: self.spring_at(self.environment.stiffness_n_per_m),
            events: &self.events,
        }
    }

    /// The scene's environment as a spring of stiffness `k_e`.
    fn spring_at(&self, k_e: f64) -> LinearSpring {
        LinearSpring {
            stiffness_n_per_m: k_e,
            x_e_m: self.environment.x_e_m,
        }
    }
}

/// Checks `[plant]` (the plant's own checks, [`PlantSpec`]).
pub(crate) fn validate(scene: &Scene, _v: &Check<'_>) -> Result<(), SceneError> {
    scene.plant.check(&scene.plant_site())
}

/// Builds the plant a scene describes, at its initial state.
pub fn build_plant(scene: &Scene) -> Result<Box<dyn Plant>, SceneError> {
    let site = scene.plant_site();
    scene.plant.build(&site, site.environment)
}

/// The scene's plant against a spring of stiffness `k_e` at the scene's contact position, as the loop
/// analyses take it ([`PlantSpec::linearisable`]).
pub fn linearisable_at(
    scene: &Scene,
    k_e: f64,
) -> Result<Option<Box<dyn Linearisable>>, SceneError> {
    scene
        .plant
        .linearisable(&scene.plant_site(), scene.spring_at(k_e))
}

impl OneDofPneumatic {
    /// The plant a pneumatic scene describes, against `env` (actuator sheet resolved against the scene's
    /// directory).
    pub fn from_scene(scene: &Scene, env: LinearSpring) -> Result<Self, SceneError> {
        Self::from_spec(&scene.plant, &scene.plant_site(), env)
    }
}

impl LinearPlant {
    /// The plant a `kind = "linear"` scene describes, against `env`.
    pub fn from_scene(scene: &Scene, env: LinearSpring) -> Result<Self, SceneError> {
        Self::from_spec(&scene.plant, &scene.plant_site(), env)
    }
}

impl MultibodyPlant {
    /// The plant a multibody scene describes (URDF and actuator sheet resolved against the scene's
    /// directory). Checks `environment.x_e_m` against the URDF's first-touch position of the initial
    /// material.
    pub fn from_scene(scene: &Scene) -> Result<Self, SceneError> {
        let PlantSpec::Multibody(mb) = &scene.plant else {
            return Err(scene.origin().plant_error("not a multibody plant".into()));
        };
        Self::from_spec(mb, &scene.plant_site())
    }
}
