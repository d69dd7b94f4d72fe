// Byte offsets of the mjModel and mjData fields the plugin reads and writes, for MuJoCo 4.0.0 on a 64-bit
// Linux (mjtNum = double, mjtSize = int64_t), taken with offsetof from the 4.0.0 wheel's headers. The
// structs change between releases, so the plugin registers only under MuJoCo 4.0.0 (mj_version), and
// build.rs compiles these numbers as static assertions against the headers whenever it finds them
// (PNEUFLEX_MUJOCO_DIR or the repo's .venv). This file is included by build.rs too: constants only.

/// The MuJoCo version these offsets are for, as `mj_version()` returns it.
pub const MJ_VERSION: i32 = 4_000_000;

/// `mjModel.nactuator` (mjtSize).
pub const M_NACTUATOR: usize = 24;
/// `mjModel.opt.timestep` (mjtNum).
pub const M_TIMESTEP: usize = 792;
/// `mjModel.opt.integrator` (int, mjtIntegrator).
pub const M_INTEGRATOR: usize = 1040;
/// `mjModel.opt.disableactuator` (int, bit per actuator group).
pub const M_DISABLEACTUATOR: usize = 1080;
/// `mjModel.actuator_ctrladr` (int*).
pub const M_ACTUATOR_CTRLADR: usize = 4800;
/// `mjModel.actuator_ctrlnum` (int*).
pub const M_ACTUATOR_CTRLNUM: usize = 4808;
/// `mjModel.actuator_outadr` (int*).
pub const M_ACTUATOR_OUTADR: usize = 4824;
/// `mjModel.actuator_outnum` (int*).
pub const M_ACTUATOR_OUTNUM: usize = 4832;
/// `mjModel.actuator_group` (int*).
pub const M_ACTUATOR_GROUP: usize = 4968;
/// `mjModel.actuator_plugin` (int*).
pub const M_ACTUATOR_PLUGIN: usize = 4984;
/// `mjModel.actuator_ctrllimited` (mjtBool*, one byte per control).
pub const M_ACTUATOR_CTRLLIMITED: usize = 5008;
/// `mjModel.actuator_ctrlrange` (mjtNum*, two per control).
pub const M_ACTUATOR_CTRLRANGE: usize = 5016;
/// `mjModel.plugin_stateadr` (int*).
pub const M_PLUGIN_STATEADR: usize = 5208;
/// `mjModel.plugin_statenum` (int*).
pub const M_PLUGIN_STATENUM: usize = 5216;

/// `mjData.plugin_state` (mjtNum*).
pub const D_PLUGIN_STATE: usize = 160_736;
/// `mjData.ctrl` (mjtNum*).
pub const D_CTRL: usize = 160_744;
/// `mjData.plugin_data` (uintptr_t*).
pub const D_PLUGIN_DATA: usize = 160_840;
/// `mjData.actuator_length` (mjtNum*).
pub const D_ACTUATOR_LENGTH: usize = 161_152;
/// `mjData.actuator_velocity` (mjtNum*).
pub const D_ACTUATOR_VELOCITY: usize = 161_288;
/// `mjData.actuator_force` (mjtNum*).
pub const D_ACTUATOR_FORCE: usize = 161_416;

/// `sizeof(mjpPlugin)`; the Rust struct in ffi.rs asserts it and build.rs checks it against the header.
pub const PLUGIN_SIZE: usize = 152;

/// `mjINT_RK4`: the one integrator the plugin refuses (it calls compute four times a step; the chamber
/// state advances once, in advance, so the stages would see a state that is not theirs).
pub const MJ_INT_RK4: i32 = 1;
/// `mjPLUGIN_ACTUATOR`.
pub const MJ_PLUGIN_ACTUATOR: i32 = 1;
/// `mjOBJ_ACTUATOR` (for mj_id2name).
pub const MJ_OBJ_ACTUATOR: i32 = 19;
/// `mjOBJ_PLUGIN` (for mj_id2name).
pub const MJ_OBJ_PLUGIN: i32 = 25;

/// What build.rs asserts: (C type, field, offset) for offsetof, and (C expression, value) for the rest.
pub const OFFSET_CHECKS: &[(&str, &str, usize)] = &[
    ("mjModel", "nactuator", M_NACTUATOR),
    ("mjModel", "opt.timestep", M_TIMESTEP),
    ("mjModel", "opt.integrator", M_INTEGRATOR),
    ("mjModel", "opt.disableactuator", M_DISABLEACTUATOR),
    ("mjModel", "actuator_ctrladr", M_ACTUATOR_CTRLADR),
    ("mjModel", "actuator_ctrlnum", M_ACTUATOR_CTRLNUM),
    ("mjModel", "actuator_outadr", M_ACTUATOR_OUTADR),
    ("mjModel", "actuator_outnum", M_ACTUATOR_OUTNUM),
    ("mjModel", "actuator_group", M_ACTUATOR_GROUP),
    ("mjModel", "actuator_plugin", M_ACTUATOR_PLUGIN),
    ("mjModel", "actuator_ctrllimited", M_ACTUATOR_CTRLLIMITED),
    ("mjModel", "actuator_ctrlrange", M_ACTUATOR_CTRLRANGE),
    ("mjModel", "plugin_stateadr", M_PLUGIN_STATEADR),
    ("mjModel", "plugin_statenum", M_PLUGIN_STATENUM),
    ("mjData", "plugin_state", D_PLUGIN_STATE),
    ("mjData", "ctrl", D_CTRL),
    ("mjData", "plugin_data", D_PLUGIN_DATA),
    ("mjData", "actuator_length", D_ACTUATOR_LENGTH),
    ("mjData", "actuator_velocity", D_ACTUATOR_VELOCITY),
    ("mjData", "actuator_force", D_ACTUATOR_FORCE),
];

/// C expressions that must equal the value: the element types behind the offsets, the plugin struct and
/// the enum values.
pub const VALUE_CHECKS: &[(&str, i64)] = &[
    ("mjVERSION_HEADER", MJ_VERSION as i64),
    ("sizeof(mjtNum)", 8),
    ("sizeof(((mjModel*)0)->nactuator)", 8),
    ("sizeof(((mjModel*)0)->opt.integrator)", 4),
    ("sizeof(((mjModel*)0)->opt.disableactuator)", 4),
    ("sizeof(((mjModel*)0)->actuator_ctrladr[0])", 4),
    ("sizeof(((mjModel*)0)->actuator_ctrlnum[0])", 4),
    ("sizeof(((mjModel*)0)->actuator_outadr[0])", 4),
    ("sizeof(((mjModel*)0)->actuator_outnum[0])", 4),
    ("sizeof(((mjModel*)0)->actuator_group[0])", 4),
    ("sizeof(((mjModel*)0)->actuator_plugin[0])", 4),
    ("sizeof(((mjModel*)0)->actuator_ctrllimited[0])", 1),
    ("sizeof(((mjModel*)0)->actuator_ctrlrange[0])", 8),
    ("sizeof(((mjModel*)0)->plugin_stateadr[0])", 4),
    ("sizeof(((mjModel*)0)->plugin_statenum[0])", 4),
    ("sizeof(((mjData*)0)->plugin_data[0])", 8),
    ("sizeof(mjpPlugin)", PLUGIN_SIZE as i64),
    ("offsetof(mjpPlugin, nstate)", 32),
    ("offsetof(mjpPlugin, init)", 48),
    ("offsetof(mjpPlugin, reset)", 72),
    ("offsetof(mjpPlugin, compute)", 80),
    ("offsetof(mjpPlugin, advance)", 88),
    ("offsetof(mjpPlugin, sdf_aabb)", 144),
    ("mjINT_RK4", MJ_INT_RK4 as i64),
    ("mjPLUGIN_ACTUATOR", MJ_PLUGIN_ACTUATOR as i64),
    ("mjOBJ_ACTUATOR", MJ_OBJ_ACTUATOR as i64),
    ("mjOBJ_PLUGIN", MJ_OBJ_PLUGIN as i64),
];
