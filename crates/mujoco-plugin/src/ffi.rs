//! The MuJoCo C API the plugin uses: the plugin struct of mjplugin.h, the functions it calls (looked up
//! at load time in the process's libmujoco, so that nothing links against it), and typed reads of the
//! mjModel/mjData fields at the offsets of src/layout.rs.

use std::ffi::{CStr, c_char, c_int, c_void};
use std::sync::OnceLock;

use crate::layout::*;

/// `mjModel`, opaque: fields are read at the offsets of layout.rs.
#[repr(C)]
pub struct MjModel {
    _p: [u8; 0],
}

/// `mjData`, opaque.
#[repr(C)]
pub struct MjData {
    _p: [u8; 0],
}

type NState = unsafe extern "C" fn(*const MjModel, c_int) -> c_int;
/// "C-unwind": `init` reports a bad configuration through `mju_error`, whose handler leaves `init` by a
/// longjmp (MuJoCo's compiler) or an exception (a host's), never by returning (see plugin.rs).
type Init = unsafe extern "C-unwind" fn(*const MjModel, *mut MjData, c_int) -> c_int;
type Destroy = unsafe extern "C" fn(*mut MjData, c_int);
type Reset = unsafe extern "C" fn(*const MjModel, *mut f64, *mut c_void, c_int);
type Compute = unsafe extern "C" fn(*const MjModel, *mut MjData, c_int, c_int);
type Advance = unsafe extern "C" fn(*const MjModel, *mut MjData, c_int);
/// A callback slot the plugin leaves empty; its signature does not matter, only that it is NULL.
type Unused = unsafe extern "C" fn();

/// `mjpPlugin` of MuJoCo 4.0.0's mjplugin.h, field for field (an `Option` of a function pointer is
/// NULL when `None`).
#[repr(C)]
pub struct MjpPlugin {
    pub name: *const c_char,
    pub nattribute: c_int,
    pub attributes: *const *const c_char,
    pub capabilityflags: c_int,
    pub needstage: c_int,
    pub nstate: Option<NState>,
    pub nsensordata: Option<Unused>,
    pub init: Option<Init>,
    pub destroy: Option<Destroy>,
    pub copy: Option<Unused>,
    pub reset: Option<Reset>,
    pub compute: Option<Compute>,
    pub advance: Option<Advance>,
    pub visualize: Option<Unused>,
    pub actuator_act_dot: Option<Unused>,
    pub sdf_distance: Option<Unused>,
    pub sdf_gradient: Option<Unused>,
    pub sdf_staticdistance: Option<Unused>,
    pub sdf_attribute: Option<Unused>,
    pub sdf_aabb: Option<Unused>,
}

const _: () = assert!(std::mem::size_of::<MjpPlugin>() == PLUGIN_SIZE);
const _: () = assert!(std::mem::offset_of!(MjpPlugin, compute) == 80);
const _: () = assert!(std::mem::offset_of!(MjpPlugin, sdf_aabb) == 144);

/// The MuJoCo functions the plugin calls.
pub struct Api {
    pub mj_version: unsafe extern "C" fn() -> c_int,
    pub mjp_default_plugin: unsafe extern "C" fn(*mut MjpPlugin),
    pub mjp_register_plugin: unsafe extern "C" fn(*const MjpPlugin) -> c_int,
    pub mjp_get_plugin: unsafe extern "C" fn(*const c_char, *mut c_int) -> *const MjpPlugin,
    pub mj_get_plugin_config:
        unsafe extern "C" fn(*const MjModel, c_int, *const c_char) -> *const c_char,
    pub mj_id2name: unsafe extern "C" fn(*const MjModel, c_int, c_int) -> *const c_char,
    pub mju_warning: unsafe extern "C" fn(*const c_char, ...),
    /// Does not return when a handler is installed (MuJoCo's compiler installs one while it loads a model).
    pub mju_error: unsafe extern "C-unwind" fn(*const c_char, ...),
}

static API: OnceLock<Api> = OnceLock::new();

/// The API once [`load_api`] found it.
pub fn api() -> Option<&'static Api> {
    API.get()
}

/// The SONAME of the library whose layout layout.rs describes.
const LIBMUJOCO: &CStr = c"libmujoco.so.4.0.0";

/// Finds the MuJoCo functions in the process: first among the global symbols (a C host linked to
/// libmujoco), then in an already loaded libmujoco.so.4.0.0 (Python loads it with RTLD_LOCAL, so its
/// symbols are not global). Never loads a libmujoco itself: the host's own must be the one used.
pub fn load_api() -> Result<&'static Api, String> {
    if let Some(a) = API.get() {
        return Ok(a);
    }
    // SAFETY: dlsym/dlopen with valid C strings; RTLD_NOLOAD only returns a library already loaded.
    let handle = unsafe {
        if !libc::dlsym(libc::RTLD_DEFAULT, c"mjp_registerPlugin".as_ptr()).is_null() {
            libc::RTLD_DEFAULT
        } else {
            let h = libc::dlopen(LIBMUJOCO.as_ptr(), libc::RTLD_NOW | libc::RTLD_NOLOAD);
            if h.is_null() {
                return Err(format!(
                    "no {} in this process: load MuJoCo 4.0.0 first (`import mujoco` in Python, or link the \
                     host against it), then mj_loadPluginLibrary",
                    LIBMUJOCO.to_string_lossy()
                ));
            }
            h
        }
    };
    let sym = |name: &CStr| -> Result<*mut c_void, String> {
        // SAFETY: `handle` is RTLD_DEFAULT or a live handle; `name` is a C string.
        let p = unsafe { libc::dlsym(handle, name.as_ptr()) };
        if p.is_null() {
            Err(format!("MuJoCo has no `{}`", name.to_string_lossy()))
        } else {
            Ok(p)
        }
    };
    // SAFETY: each symbol is the MuJoCo 4.0 function of that name, whose C signature the field spells.
    macro_rules! f {
        ($name:literal, $ty:ty) => {
            unsafe { std::mem::transmute::<*mut c_void, $ty>(sym($name)?) }
        };
    }
    let api = Api {
        mj_version: f!(c"mj_version", unsafe extern "C" fn() -> c_int),
        mjp_default_plugin: f!(c"mjp_defaultPlugin", unsafe extern "C" fn(*mut MjpPlugin)),
        mjp_register_plugin: f!(
            c"mjp_registerPlugin",
            unsafe extern "C" fn(*const MjpPlugin) -> c_int
        ),
        mjp_get_plugin: f!(
            c"mjp_getPlugin",
            unsafe extern "C" fn(*const c_char, *mut c_int) -> *const MjpPlugin
        ),
        mj_get_plugin_config: f!(
            c"mj_getPluginConfig",
            unsafe extern "C" fn(*const MjModel, c_int, *const c_char) -> *const c_char
        ),
        mj_id2name: f!(
            c"mj_id2name",
            unsafe extern "C" fn(*const MjModel, c_int, c_int) -> *const c_char
        ),
        mju_warning: f!(c"mju_warning", unsafe extern "C" fn(*const c_char, ...)),
        mju_error: f!(
            c"mju_error",
            unsafe extern "C-unwind" fn(*const c_char, ...)
        ),
    };
    // SAFETY: mj_version takes nothing and returns an int.
    let version = unsafe { (api.mj_version)() };
    if version != MJ_VERSION {
        return Err(format!(
            "this MuJoCo is version {version}; the plugin reads mjModel/mjData at the offsets of MuJoCo {MJ_VERSION} \
             and would read the wrong fields: rebuild it for this version"
        ));
    }
    Ok(API.get_or_init(|| api))
}

/// A MuJoCo warning (through MuJoCo's handler: the compiler appends it to the error of a failed load).
pub fn warn(api: &Api, msg: &str) {
    // An interior NUL cannot come from our messages' text, but never panic for it.
    let c = std::ffi::CString::new(msg.replace('\0', " ")).unwrap_or_default();
    // SAFETY: "%s" with one C string argument.
    unsafe { (api.mju_warning)(c"%s".as_ptr(), c.as_ptr()) }
}

/// Reads a value of type `T` at byte offset `off` of the struct at `base`.
///
/// # Safety
/// `base` points to a live struct with a `T` at `off`.
#[inline]
unsafe fn at<T: Copy>(base: *const u8, off: usize) -> T {
    // SAFETY: the caller's contract; the fields are naturally aligned in MuJoCo's structs.
    unsafe { base.add(off).cast::<T>().read() }
}

/// Typed reads of an mjModel.
#[derive(Clone, Copy)]
pub struct Model(pub *const MjModel);

impl Model {
    fn b(self) -> *const u8 {
        self.0.cast()
    }
    /// # Safety
    /// `self` points to a live MuJoCo 4.0.0 mjModel (true in every callback); the same holds for the methods below.
    pub unsafe fn nactuator(self) -> usize {
        let n: i64 = unsafe { at(self.b(), M_NACTUATOR) };
        usize::try_from(n).unwrap_or(0)
    }
    /// # Safety
    /// As [`Model::nactuator`].
    pub unsafe fn timestep(self) -> f64 {
        unsafe { at(self.b(), M_TIMESTEP) }
    }
    /// # Safety
    /// As [`Model::nactuator`].
    pub unsafe fn integrator(self) -> i32 {
        unsafe { at(self.b(), M_INTEGRATOR) }
    }
    /// # Safety
    /// As [`Model::nactuator`].
    pub unsafe fn disableactuator(self) -> i32 {
        unsafe { at(self.b(), M_DISABLEACTUATOR) }
    }
    /// Element `i` of the `int*` array at `off`.
    unsafe fn int_array(self, off: usize, i: usize) -> i32 {
        unsafe {
            let p: *const i32 = at(self.b(), off);
            p.add(i).read()
        }
    }
    /// # Safety
    /// As [`Model::nactuator`], and `a < nactuator`; the same for the actuator methods below.
    pub unsafe fn actuator_plugin(self, a: usize) -> i32 {
        unsafe { self.int_array(M_ACTUATOR_PLUGIN, a) }
    }
    /// # Safety
    /// As [`Model::actuator_plugin`].
    pub unsafe fn actuator_ctrladr(self, a: usize) -> i32 {
        unsafe { self.int_array(M_ACTUATOR_CTRLADR, a) }
    }
    /// # Safety
    /// As [`Model::actuator_plugin`].
    pub unsafe fn actuator_ctrlnum(self, a: usize) -> i32 {
        unsafe { self.int_array(M_ACTUATOR_CTRLNUM, a) }
    }
    /// # Safety
    /// As [`Model::actuator_plugin`].
    pub unsafe fn actuator_outadr(self, a: usize) -> i32 {
        unsafe { self.int_array(M_ACTUATOR_OUTADR, a) }
    }
    /// # Safety
    /// As [`Model::actuator_plugin`].
    pub unsafe fn actuator_outnum(self, a: usize) -> i32 {
        unsafe { self.int_array(M_ACTUATOR_OUTNUM, a) }
    }
    /// # Safety
    /// As [`Model::actuator_plugin`].
    pub unsafe fn actuator_group(self, a: usize) -> i32 {
        unsafe { self.int_array(M_ACTUATOR_GROUP, a) }
    }
    /// Whether control `u` is limited, and its range.
    ///
    /// # Safety
    /// As [`Model::nactuator`], and `u < nu`.
    pub unsafe fn ctrlrange(self, u: usize) -> Option<(f64, f64)> {
        unsafe {
            let limited: *const u8 = at(self.b(), M_ACTUATOR_CTRLLIMITED);
            if limited.add(u).read() == 0 {
                return None;
            }
            let range: *const f64 = at(self.b(), M_ACTUATOR_CTRLRANGE);
            Some((range.add(2 * u).read(), range.add(2 * u + 1).read()))
        }
    }
    /// Address and length of instance `i`'s slice of plugin_state.
    ///
    /// # Safety
    /// As [`Model::nactuator`], and `i < nplugin`.
    pub unsafe fn plugin_state_span(self, i: usize) -> (usize, usize) {
        unsafe {
            let adr = self.int_array(M_PLUGIN_STATEADR, i);
            let num = self.int_array(M_PLUGIN_STATENUM, i);
            (
                usize::try_from(adr).unwrap_or(0),
                usize::try_from(num).unwrap_or(0),
            )
        }
    }
}

/// Typed access to an mjData.
#[derive(Clone, Copy)]
pub struct Data(pub *mut MjData);

impl Data {
    fn b(self) -> *const u8 {
        self.0.cast_const().cast()
    }
    /// The `mjtNum*` array at `off`.
    unsafe fn nums(self, off: usize) -> *mut f64 {
        unsafe { at(self.b(), off) }
    }
    /// # Safety
    /// `self` points to a live MuJoCo 4.0.0 mjData and `i < nplugin`.
    pub unsafe fn plugin_data(self, i: usize) -> *mut c_void {
        unsafe {
            let p: *const usize = at(self.b(), D_PLUGIN_DATA);
            p.add(i).read() as *mut c_void
        }
    }
    /// # Safety
    /// As [`Data::plugin_data`].
    pub unsafe fn set_plugin_data(self, i: usize, v: *mut c_void) {
        unsafe {
            let p: *mut usize = at(self.b(), D_PLUGIN_DATA);
            p.add(i).write(v as usize);
        }
    }
    /// # Safety
    /// `self` points to a live mjData; the state array has `npluginstate` entries.
    pub unsafe fn plugin_state(self) -> *mut f64 {
        unsafe { self.nums(D_PLUGIN_STATE) }
    }
    /// # Safety
    /// As [`Data::plugin_state`], `u < nu`.
    pub unsafe fn ctrl(self, u: usize) -> f64 {
        unsafe { self.nums(D_CTRL).add(u).read() }
    }
    /// # Safety
    /// As [`Data::plugin_state`], `o < nout`.
    pub unsafe fn actuator_length(self, o: usize) -> f64 {
        unsafe { self.nums(D_ACTUATOR_LENGTH).add(o).read() }
    }
    /// # Safety
    /// As [`Data::plugin_state`], `o < nout`.
    pub unsafe fn actuator_velocity(self, o: usize) -> f64 {
        unsafe { self.nums(D_ACTUATOR_VELOCITY).add(o).read() }
    }
    /// # Safety
    /// As [`Data::plugin_state`], `o < nout`.
    pub unsafe fn set_actuator_force(self, o: usize, f: f64) {
        unsafe { self.nums(D_ACTUATOR_FORCE).add(o).write(f) }
    }
}

/// A C string from MuJoCo as text (`None` for NULL; bytes that are not UTF-8 replaced).
///
/// # Safety
/// `p` is NULL or a NUL-terminated string that outlives the call.
pub unsafe fn text(p: *const c_char) -> Option<String> {
    if p.is_null() {
        None
    } else {
        // SAFETY: the caller's contract.
        Some(unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
    }
}
