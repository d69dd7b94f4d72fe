//! The MuJoCo callbacks of `pneuflex.cylinder` and its registration.
//!
//! Every callback runs inside `catch_unwind`: a panic never crosses into MuJoCo (init then fails, a
//! force is written as 0). A bad configuration is `init`'s `mju_error` with the message naming the
//! instance and the key: MuJoCo's compiler makes it the load error (`mj_loadXML`'s error string,
//! Python's ValueError). A return of -1 alone would give only MuJoCo's "plugin->init failed for plugin
//! id 0", and a warning goes to stdout, not into the error. `mju_error` leaves `init` by a longjmp or
//! an exception, so it is called from `init`'s own frame once every Rust value there is dropped; other
//! callbacks never call it. Run-time problems are warnings.

use std::ffi::{c_char, c_int, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};

use crate::config::{self, ConfigError};
use crate::cylinder::{Cylinder, Memo, Refused, STATE_LEN, State};
use crate::ffi::{self, Api, Data, MjData, MjModel, MjpPlugin, Model};
use crate::layout::{MJ_INT_RK4, MJ_OBJ_ACTUATOR, MJ_OBJ_PLUGIN, MJ_PLUGIN_ACTUATOR};

/// The name MJCF files use.
pub const NAME: &std::ffi::CStr = c"pneuflex.cylinder";

/// One cylinder driven by an instance: its actuator, and under `command="pressure"` the actuator after it,
/// whose control is chamber B's set-point (and whose force is 0).
struct Bound {
    /// Actuator id, its control and its force output.
    id: usize,
    ctrl: usize,
    out: usize,
    /// The second actuator's control and output (`command="pressure"`).
    second: Option<(usize, usize)>,
    /// The last step worked out by `compute`.
    memo: Option<Memo>,
}

/// What `init` leaves in plugin_data: the parsed configuration and per-actuator scratch.
struct Instance {
    /// "instance 'cyl1'" or "actuator 'rod'", for messages.
    who: String,
    cylinder: Cylinder,
    actuators: Vec<Bound>,
    /// A refused step was reported (once per instance, not every step).
    warned: bool,
}

/// The actuators whose plugin instance is `instance`.
///
/// # Safety
/// `m` is a live mjModel.
pub(crate) unsafe fn bound(m: Model, instance: usize) -> Vec<usize> {
    let n = unsafe { m.nactuator() };
    (0..n)
        .filter(|&a| usize::try_from(unsafe { m.actuator_plugin(a) }).ok() == Some(instance))
        .collect()
}

/// "instance 'NAME'", or for an implicit instance (config on the actuator) "actuator 'NAME'".
///
/// # Safety
/// `m` is a live mjModel.
pub(crate) unsafe fn who(api: &Api, m: Model, instance: c_int, actuators: &[usize]) -> String {
    let name =
        |ty, id| unsafe { ffi::text((api.mj_id2name)(m.0, ty, id)) }.filter(|s| !s.is_empty());
    if let Some(n) = name(MJ_OBJ_PLUGIN, instance) {
        return format!("instance '{n}'");
    }
    match actuators.first() {
        Some(&a) => match name(MJ_OBJ_ACTUATOR, a as c_int) {
            Some(n) => format!("actuator '{n}'"),
            None => format!("actuator {a}"),
        },
        None => format!("instance {instance}"),
    }
}

/// Runs `f`, returning `default` if it panics.
pub(crate) fn guard<T>(default: T, f: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or(default)
}

unsafe extern "C" fn nstate(m: *const MjModel, instance: c_int) -> c_int {
    guard(0, || {
        let Ok(i) = usize::try_from(instance) else {
            return 0;
        };
        // One state per cylinder: two actuators each under command="pressure" (init checks the count).
        let per = match ffi::api() {
            Some(api) => unsafe { per_cylinder(api, Model(m), instance) },
            None => 1,
        };
        let n = unsafe { bound(Model(m), i) }.len() / per * STATE_LEN;
        c_int::try_from(n).unwrap_or(0)
    })
}

/// Actuators per cylinder of `instance`: 2 when its `command` is "pressure", else 1.
///
/// # Safety
/// `m` is a live mjModel.
unsafe fn per_cylinder(api: &Api, m: Model, instance: c_int) -> usize {
    // SAFETY: m is live; MuJoCo returns NULL or a string owned by the model.
    let v = unsafe {
        ffi::text((api.mj_get_plugin_config)(
            m.0,
            instance,
            c"command".as_ptr(),
        ))
    };
    if v.is_some_and(|v| v.trim() == "pressure") {
        2
    } else {
        1
    }
}

/// Room for `init`'s message (MuJoCo's compiler keeps 500 bytes of an error; the key comes first).
pub(crate) const MESSAGE_LEN: usize = 1000;

unsafe extern "C-unwind" fn init(m: *const MjModel, d: *mut MjData, instance: c_int) -> c_int {
    let Some(api) = ffi::api() else { return -1 };
    // A plain array: nothing in this frame has a destructor when mju_error leaves it (below).
    let mut text = [0 as c_char; MESSAGE_LEN];
    // SAFETY: MuJoCo's call: m and d are live, instance < nplugin.
    if unsafe { set_up(api, m, d, instance, &mut text) } {
        return 0;
    }
    // SAFETY: "%s" with one NUL-terminated string. With a handler installed (the compiler's, a host's)
    // it does not return: it leaves by a longjmp or an exception, which the "C-unwind" ABI lets through
    // this frame, which holds nothing to drop. Without one, MuJoCo prints the message and exits, as it
    // does for -1.
    unsafe { (api.mju_error)(c"%s".as_ptr(), text.as_ptr()) };
    -1
}

/// Makes the instance and stores it in plugin_data (true), or writes the message naming what is wrong
/// into `text`, NUL-terminated (false). Every Rust value made here is dropped when it returns.
///
/// # Safety
/// `m`, `d` are live and `instance` one of the model's plugin instances.
unsafe fn set_up(
    api: &Api,
    m: *const MjModel,
    d: *mut MjData,
    instance: c_int,
    text: &mut [c_char; MESSAGE_LEN],
) -> bool {
    let r = catch_unwind(AssertUnwindSafe(|| unsafe {
        make(api, Model(m), instance)
    }));
    let msg = match r {
        Ok(Ok(inst)) => {
            let p = Box::into_raw(Box::new(inst));
            // SAFETY: d is live and instance < nplugin (MuJoCo's call).
            unsafe { Data(d).set_plugin_data(instance as usize, p.cast()) };
            return true;
        }
        Ok(Err(msg)) => msg,
        Err(_) => format!(
            "{}: instance {instance}: internal error (a panic) while reading the configuration",
            NAME.to_string_lossy()
        ),
    };
    c_text(&msg, text);
    false
}

/// `msg` as a NUL-terminated C string in `out`, cut at a character boundary if it is too long; an
/// interior NUL becomes a space.
pub(crate) fn c_text(msg: &str, out: &mut [c_char]) {
    let room = out.len() - 1;
    let mut end = msg.len().min(room);
    while !msg.is_char_boundary(end) {
        end -= 1;
    }
    for (o, b) in out.iter_mut().zip(msg[..end].bytes()) {
        *o = if b == 0 { b' ' } else { b } as c_char;
    }
    out[end] = 0;
}

/// The instance's configuration and actuators, or the message naming what is wrong.
///
/// # Safety
/// `m` is a live mjModel and `instance` one of its plugin instances.
unsafe fn make(api: &Api, m: Model, instance: c_int) -> Result<Instance, String> {
    let i = usize::try_from(instance).map_err(|_| format!("bad instance {instance}"))?;
    let acts = unsafe { bound(m, i) };
    let who = unsafe { who(api, m, instance, &acts) };
    let fail = |e: ConfigError| format!("{}: {who}: {e}", NAME.to_string_lossy());
    let get = |key: &str| {
        let k = std::ffi::CString::new(key).ok()?;
        // SAFETY: m is live; MuJoCo returns NULL or a string owned by the model.
        unsafe { ffi::text((api.mj_get_plugin_config)(m.0, instance, k.as_ptr())) }
    };
    let config = config::parse(get).map_err(fail)?;
    if unsafe { m.integrator() } == MJ_INT_RK4 {
        return Err(format!(
            "{}: {who}: option integrator=\"RK4\" is not supported: RK4 evaluates the actuator force at \
             four stages of a step while the chamber state advances once per step (use Euler, implicit, \
             implicitfast or discrete)",
            NAME.to_string_lossy()
        ));
    }
    // A configured cylinder nothing drives is a forgotten `instance=` on the actuator, not a model.
    if acts.is_empty() {
        return Err(format!(
            "{}: {who}: drives no actuator: name it on one, <actuator><plugin joint=\"...\" \
             plugin=\"{}\" instance=\"NAME\"/></actuator>",
            NAME.to_string_lossy(),
            NAME.to_string_lossy()
        ));
    }
    let per = config.command.actuators_per_cylinder();
    if acts.len() % per != 0 {
        return Err(format!(
            "{}: {who}: command=\"pressure\" takes two actuators per cylinder (chamber A's set-point, then \
             chamber B's), in actuator order; the instance drives {}",
            NAME.to_string_lossy(),
            acts.len()
        ));
    }
    let mut controls = Vec::with_capacity(acts.len());
    for &a in &acts {
        let (cn, on) = unsafe { (m.actuator_ctrlnum(a), m.actuator_outnum(a)) };
        if cn != 1 || on != 1 {
            let name = unsafe { ffi::text((api.mj_id2name)(m.0, MJ_OBJ_ACTUATOR, a as c_int)) };
            return Err(format!(
                "{}: {who}: actuator '{}' has {cn} controls and {on} force outputs; a cylinder needs one \
                 of each (a joint or tendon transmission)",
                NAME.to_string_lossy(),
                name.unwrap_or_default()
            ));
        }
        let (ctrl, out) = unsafe { (m.actuator_ctrladr(a), m.actuator_outadr(a)) };
        controls.push((
            usize::try_from(ctrl).map_err(|_| "bad control address".to_string())?,
            usize::try_from(out).map_err(|_| "bad output address".to_string())?,
        ));
    }
    let actuators: Vec<Bound> = acts
        .chunks_exact(per)
        .zip(controls.chunks_exact(per))
        .map(|(a, c)| Bound {
            id: a[0],
            ctrl: c[0].0,
            out: c[0].1,
            second: c.get(1).copied(),
            memo: None,
        })
        .collect();
    let (_, num) = unsafe { m.plugin_state_span(i) };
    if num != actuators.len() * STATE_LEN {
        return Err(format!(
            "{}: {who}: plugin_state holds {num} numbers, expected {} ({STATE_LEN} per cylinder)",
            NAME.to_string_lossy(),
            actuators.len() * STATE_LEN
        ));
    }
    Ok(Instance {
        who,
        cylinder: Cylinder::new(&config),
        actuators,
        warned: false,
    })
}

unsafe extern "C" fn destroy(d: *mut MjData, instance: c_int) {
    guard((), || unsafe {
        let Ok(i) = usize::try_from(instance) else {
            return;
        };
        let p = Data(d).plugin_data(i).cast::<Instance>();
        if !p.is_null() {
            drop(Box::from_raw(p));
            Data(d).set_plugin_data(i, std::ptr::null_mut());
        }
    })
}

unsafe extern "C" fn reset(
    m: *const MjModel,
    state: *mut f64,
    plugin_data: *mut c_void,
    instance: c_int,
) {
    guard((), || unsafe {
        let Ok(i) = usize::try_from(instance) else {
            return;
        };
        // MuJoCo never clears plugin_state: every slot is written here.
        let (_, num) = Model(m).plugin_state_span(i);
        let s = std::slice::from_raw_parts_mut(state, num);
        let inst = plugin_data.cast::<Instance>().cast_const();
        match inst.as_ref() {
            Some(inst) => {
                let s0 = inst.cylinder.initial_state();
                for chunk in s.chunks_exact_mut(STATE_LEN) {
                    chunk.copy_from_slice(&s0);
                }
            }
            None => s.fill(0.0),
        }
    })
}

/// The inputs of cylinder `b` for a step: x, v, its controls clamped (the second 0 under the valve
/// command), h.
///
/// # Safety
/// `m`, `d` are live and `b` one of the instance's cylinders.
unsafe fn inputs(m: Model, d: Data, b: &Bound) -> (f64, f64, [f64; 2], f64) {
    unsafe {
        let ctrl = |c: usize| {
            let u = d.ctrl(c);
            // MuJoCo clamps ctrl for its own actuators only, in a copy: a plugin clamps it itself.
            match m.ctrlrange(c).filter(|(lo, hi)| lo <= hi) {
                Some((lo, hi)) => u.clamp(lo, hi),
                None => u,
            }
        };
        (
            d.actuator_length(b.out),
            d.actuator_velocity(b.out),
            [ctrl(b.ctrl), b.second.map_or(0.0, |(c, _)| ctrl(c))],
            m.timestep(),
        )
    }
}

/// The instance's plugin_data and its actuators' states in plugin_state.
///
/// # Safety
/// `m`, `d` are live and `instance` one of the model's plugin instances.
unsafe fn parts<'a>(
    m: Model,
    d: Data,
    instance: c_int,
) -> Option<(&'a mut Instance, &'a mut [f64])> {
    unsafe {
        let i = usize::try_from(instance).ok()?;
        let inst = d.plugin_data(i).cast::<Instance>().as_mut()?;
        let (adr, num) = m.plugin_state_span(i);
        if num != inst.actuators.len() * STATE_LEN {
            return None;
        }
        let s = std::slice::from_raw_parts_mut(d.plugin_state().add(adr), num);
        Some((inst, s))
    }
}

/// Reports a refused step once per instance.
fn refused(inst: &mut Instance, a: usize, why: Refused) {
    if inst.warned {
        return;
    }
    inst.warned = true;
    if let Some(api) = ffi::api() {
        let what = match why {
            Refused::State => {
                "plugin_state holds numbers the cylinder cannot be in (set from outside?)"
            }
            Refused::Input => "the actuator length, velocity or the timestep is not finite",
        };
        ffi::warn(
            api,
            &format!(
                "{}: {}: actuator {a}: {what}; its force is 0 and its state is held until a reset \
                 (reported once)",
                NAME.to_string_lossy(),
                inst.who
            ),
        );
    }
}

unsafe extern "C" fn compute(m: *const MjModel, d: *mut MjData, instance: c_int, cap: c_int) {
    if cap & MJ_PLUGIN_ACTUATOR == 0 {
        return;
    }
    let (m, d) = (Model(m), Data(d));
    guard((), || unsafe {
        let Some((inst, states)) = parts(m, d, instance) else {
            return;
        };
        let disabled = m.disableactuator();
        for k in 0..inst.actuators.len() {
            let b = &mut inst.actuators[k];
            let (x, v, u, h) = inputs(m, d, b);
            let s: &State = states[k * STATE_LEN..(k + 1) * STATE_LEN]
                .try_into()
                .expect("chunk of STATE_LEN");
            let r = inst.cylinder.step(s, x, v, u, h, &mut b.memo);
            // An actuator in a group that opt.disableactuator turns off gives no force (as MuJoCo's own).
            let g = m.actuator_group(b.id);
            let off = (0..=30).contains(&g) && (disabled >> g) & 1 == 1;
            // Chamber B's set-point actuator carries no force of its own: the cylinder's is on the first.
            if let Some((_, out)) = b.second {
                d.set_actuator_force(out, 0.0);
            }
            let force = match r {
                Ok((_, f)) if !off => f,
                Ok(_) => 0.0,
                Err(why) => {
                    let (id, out) = (b.id, b.out);
                    d.set_actuator_force(out, 0.0);
                    refused(inst, id, why);
                    continue;
                }
            };
            d.set_actuator_force(b.out, force);
        }
    })
}

unsafe extern "C" fn advance(m: *const MjModel, d: *mut MjData, instance: c_int) {
    let (m, d) = (Model(m), Data(d));
    guard((), || unsafe {
        // No plugin_data: MuJoCo's length-range computation steps a data that was never init'ed.
        let Some((inst, states)) = parts(m, d, instance) else {
            return;
        };
        for k in 0..inst.actuators.len() {
            let b = &mut inst.actuators[k];
            // Under Euler and the implicit integrators the actuator length and velocity are still the
            // step-start values compute saw, and ctrl is the command of the step: the memo's inputs.
            let (x, v, u, h) = inputs(m, d, b);
            let chunk = &mut states[k * STATE_LEN..(k + 1) * STATE_LEN];
            let s: State = (&*chunk).try_into().expect("chunk of STATE_LEN");
            match inst.cylinder.step(&s, x, v, u, h, &mut b.memo) {
                Ok((next, _)) => chunk.copy_from_slice(&next),
                Err(why) => {
                    let id = b.id;
                    refused(inst, id, why);
                }
            }
        }
    })
}

/// Registers `pneuflex.cylinder` with the MuJoCo of this process.
pub fn register() -> Result<(), String> {
    let api = ffi::load_api()?;
    // SAFETY: a C string; MuJoCo returns NULL or its registered plugin.
    let existing = unsafe { (api.mjp_get_plugin)(NAME.as_ptr(), std::ptr::null_mut()) };
    if !existing.is_null() {
        // Registering a second copy (this library from another path) would be MuJoCo's fatal
        // "already registered" error; the first copy stays in use.
        ffi::warn(
            api,
            &format!(
                "{}: already registered by another copy of the plugin library; this copy is not used",
                NAME.to_string_lossy()
            ),
        );
        return Ok(());
    }
    let names: Vec<*const c_char> = config::KEYS.iter().map(|k| k.name.as_ptr()).collect();
    let mut p = std::mem::MaybeUninit::<MjpPlugin>::uninit();
    // SAFETY: mjp_defaultPlugin writes a whole mjpPlugin (zeros, so every unused callback is NULL).
    let mut p = unsafe {
        (api.mjp_default_plugin)(p.as_mut_ptr());
        p.assume_init()
    };
    p.name = NAME.as_ptr();
    p.capabilityflags |= MJ_PLUGIN_ACTUATOR;
    p.nattribute = c_int::try_from(names.len()).map_err(|_| "too many keys".to_string())?;
    // MuJoCo copies the name and the attribute strings into its registry.
    p.attributes = names.as_ptr();
    p.nstate = Some(nstate);
    p.init = Some(init);
    p.destroy = Some(destroy);
    p.reset = Some(reset);
    p.compute = Some(compute);
    p.advance = Some(advance);
    // SAFETY: a complete plugin struct; MuJoCo copies what it keeps.
    let slot = unsafe { (api.mjp_register_plugin)(&p) };
    if slot < 0 {
        return Err(format!("mjp_registerPlugin returned {slot}"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn back(out: &[c_char]) -> String {
        // SAFETY: c_text always writes a NUL.
        unsafe { std::ffi::CStr::from_ptr(out.as_ptr()) }
            .to_string_lossy()
            .into_owned()
    }

    #[test]
    fn a_message_reaches_mujoco_whole_or_cut_at_a_character() {
        let mut out = [1 as c_char; 8];
        c_text("key 'a'", &mut out);
        assert_eq!(back(&out), "key 'a'");
        // Too long: cut to 7 bytes and terminated, never split inside the 2-byte 'é'.
        c_text("cléf 'bore'", &mut out);
        assert_eq!(back(&out), "cléf '");
        c_text("abcdefé", &mut out);
        assert_eq!(back(&out), "abcdef");
        // A NUL inside would end the C string early: it becomes a space.
        c_text("a\0b", &mut out);
        assert_eq!(back(&out), "a b");
    }
}
