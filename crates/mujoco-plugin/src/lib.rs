//! pneuflex-mujoco: the MuJoCo 4.0 actuator plugins `pneuflex.cylinder` and `pneuflex.muscle`, a shared
//! library (`libpneuflex_mujoco.so`) that MuJoCo loads with `mj_loadPluginLibrary`. Any MJCF can then
//! declare the two-chamber pneumatic cylinder of `pneuflex-pneumatics` (the same force element the Rapier
//! rig and the Python cross-validation use) as an actuator, configured by an actuator sheet and inline
//! values, and the McKibben muscle of `pneuflex-muscle` (the element the engine's mechanism steps) on a
//! spatial tendon, configured by a muscle sheet. Usage, the MJCF and the C host: docs/mujoco-plugin.md.
//!
//! - The chamber state (pressures, temperatures, valve spool and PWM clock) lives in MuJoCo's
//!   plugin_state, 11 numbers per actuator, and moves on in `advance` with MuJoCo's timestep.
//! - The force comes from the actuator length and velocity (gear 1 on a slide joint: the piston extension
//!   in m and its rate), the valve command from ctrl, clamped to ctrlrange.
//! - The library links no libmujoco: at load time it finds MuJoCo's functions in the process (which has
//!   MuJoCo loaded, since MuJoCo is loading the plugin) and registers only under MuJoCo 4.0.0, whose
//!   struct layout src/layout.rs holds (checked against the headers by build.rs when they are found).

mod config;
mod cylinder;
mod ffi;
// The check tables are build.rs's; the library uses the offsets.
#[allow(dead_code)]
mod layout;
mod muscle;
mod muscle_plugin;
mod plugin;

/// Runs when the library is loaded (dlopen runs `.init_array`; this is what MuJoCo's
/// `mjPLUGIN_LIB_INIT` macro does in C).
extern "C" fn on_load() {
    type Register = fn() -> Result<(), String>;
    let plugins: [(&std::ffi::CStr, Register); 2] = [
        (plugin::NAME, plugin::register),
        (muscle_plugin::NAME, muscle_plugin::register),
    ];
    for (name, register) in plugins {
        let msg = match std::panic::catch_unwind(register) {
            Ok(Ok(())) => continue,
            Ok(Err(msg)) => msg,
            Err(_) => "internal error (a panic) while registering".to_string(),
        };
        // MuJoCo's warning may not be reachable (no MuJoCo found): stderr is.
        eprintln!("{}: not registered: {msg}", name.to_string_lossy());
    }
}

#[used]
#[unsafe(link_section = ".init_array")]
static ON_LOAD: extern "C" fn() = on_load;
