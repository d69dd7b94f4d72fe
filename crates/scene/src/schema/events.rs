//! `[[events]]`: timed changes of the scene (stiffness, a swap of the environment, the incline), checked
//! against the scene and its plant. The type is the plants' vocabulary ([`crate::plants::events`]).

use super::Scene;
use crate::error::SceneError;
use crate::origin::Check;
pub use crate::plants::events::EventSpec;

/// Checks `[[events]]`: inside the scene, and possible on its plant.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    for (i, ev) in scene.events.iter().enumerate() {
        let at = |k: &str| format!("events[{i}].{k}");
        v.non_negative(&at("t_s"), ev.t_s())?;
        if ev.t_s() > scene.duration_s + 0.5 * scene.dt_s {
            return Err(v.err(
                &at("t_s"),
                format!(
                    "the event would never happen: t_s = {} is after the end of the scene (duration_s = {})",
                    ev.t_s(),
                    scene.duration_s
                ),
            ));
        }
        let mb = scene.plant.multibody();
        match ev {
            EventSpec::Stiffness {
                stiffness_n_per_m,
                material,
                damping_n_s_per_m,
                ..
            } => {
                v.non_negative(&at("stiffness_n_per_m"), *stiffness_n_per_m)?;
                if let Some(c) = damping_n_s_per_m {
                    v.non_negative(&at("damping_n_s_per_m"), *c)?;
                }
                match mb {
                    Some(mb) => {
                        // The mount is a spring: zero stiffness has no rest position.
                        v.positive(&at("stiffness_n_per_m"), *stiffness_n_per_m)?;
                        if let Some(name) = material {
                            crate::plants::multibody::known_material(v, &at("material"), mb, name)?;
                        }
                    }
                    None => {
                        if material.is_some() || damping_n_s_per_m.is_some() {
                            return Err(v.err(
                                &at("material"),
                                "`material` and `damping_n_s_per_m` need plant.kind = \"multibody\"".into(),
                            ));
                        }
                    }
                }
            }
            EventSpec::SwapEnvironment { to, duration_s, .. } => {
                let Some(mb) = mb else {
                    return Err(v.err(
                        &at("kind"),
                        "\"swap_environment\" needs plant.kind = \"multibody\": the 1-DOF plants have one linear-spring environment and no carriage".into(),
                    ));
                };
                crate::plants::multibody::known_material(v, &at("to"), mb, to)?;
                v.positive(&at("duration_s"), *duration_s)?;
                if ev.t_s() + duration_s > scene.duration_s + 0.5 * scene.dt_s {
                    return Err(v.err(
                        &at("duration_s"),
                        format!(
                            "the swap must end within the scene: t_s + duration_s = {} > duration_s = {}",
                            ev.t_s() + duration_s,
                            scene.duration_s
                        ),
                    ));
                }
            }
            EventSpec::Alpha { alpha_deg, .. } => {
                v.within(&at("alpha_deg"), *alpha_deg, -90.0, 90.0)?;
                if !scene.plant.has_gravity() {
                    return Err(v.err(
                        &at("kind"),
                        "\"alpha\" has no effect on plant.kind = \"ideal\" or \"linear\" (no gravity in those models)".into(),
                    ));
                }
            }
        }
    }
    Ok(())
}
