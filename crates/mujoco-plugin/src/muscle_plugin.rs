//! The MuJoCo callbacks of `pneuflex.muscle` and its registration: the McKibben muscle of
//! `pneuflex-muscle` (src/muscle.rs) as MuJoCo's own actuator, acting along a spatial tendon between its two
//! anchors (the actuator length is the muscle's length with gear 1, its force -tension along the tendon,
//! ctrl the valve command). The callbacks are `pneuflex.cylinder`'s (src/plugin.rs: the same error path
//! through `mju_error` in `init`, `catch_unwind` everywhere, the memo between `compute` and `advance`) with
//! the muscle's state and step.

use std::ffi::{c_char, c_int, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};

use crate::cylinder::Refused;
use crate::ffi::{self, Api, Data, MjData, MjModel, MjpPlugin, Model};
use crate::layout::{MJ_INT_RK4, MJ_OBJ_ACTUATOR, MJ_PLUGIN_ACTUATOR};
use crate::muscle::{self, Memo, Muscle, STATE_LEN, State};
use crate::plugin::{MESSAGE_LEN, bound, c_text, guard, who};

/// The name MJCF files use.
pub const NAME: &std::ffi::CStr = c"pneuflex.muscle";

fn name() -> std::borrow::Cow<'static, str> {
    NAME.to_string_lossy()
}

/// One actuator driven by an instance.
struct Bound {
    id: usize,
    ctrl: usize,
    out: usize,
    memo: Option<Memo>,
}

/// What `init` leaves in plugin_data.
struct Instance {
    who: String,
    muscle: Muscle,
    actuators: Vec<Bound>,
    warned: bool,
}

unsafe extern "C" fn nstate(m: *const MjModel, instance: c_int) -> c_int {
    guard(0, || {
        let Ok(i) = usize::try_from(instance) else {
            return 0;
        };
        let n = unsafe { bound(Model(m), i) }.len() * STATE_LEN;
        c_int::try_from(n).unwrap_or(0)
    })
}

unsafe extern "C-unwind" fn init(m: *const MjModel, d: *mut MjData, instance: c_int) -> c_int {
    let Some(api) = ffi::api() else { return -1 };
    // A plain array: nothing in this frame has a destructor when mju_error leaves it (plugin.rs's init).
    let mut text = [0 as c_char; MESSAGE_LEN];
    // SAFETY: MuJoCo's call: m and d are live, instance < nplugin.
    if unsafe { set_up(api, m, d, instance, &mut text) } {
        return 0;
    }
    // SAFETY: "%s" with one NUL-terminated string; see plugin.rs's init.
    unsafe { (api.mju_error)(c"%s".as_ptr(), text.as_ptr()) };
    -1
}

/// Makes the instance and stores it in plugin_data (true), or writes the message into `text` (false).
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
            name()
        ),
    };
    c_text(&msg, text);
    false
}

/// The instance's configuration and actuators, or the message naming what is wrong.
///
/// # Safety
/// `m` is a live mjModel and `instance` one of its plugin instances.
unsafe fn make(api: &Api, m: Model, instance: c_int) -> Result<Instance, String> {
    let i = usize::try_from(instance).map_err(|_| format!("bad instance {instance}"))?;
    let acts = unsafe { bound(m, i) };
    let who = unsafe { who(api, m, instance, &acts) };
    let get = |key: &str| {
        let k = std::ffi::CString::new(key).ok()?;
        // SAFETY: m is live; MuJoCo returns NULL or a string owned by the model.
        unsafe { ffi::text((api.mj_get_plugin_config)(m.0, instance, k.as_ptr())) }
    };
    let muscle = muscle::parse(get).map_err(|e| format!("{}: {who}: {e}", name()))?;
    if unsafe { m.integrator() } == MJ_INT_RK4 {
        return Err(format!(
            "{}: {who}: option integrator=\"RK4\" is not supported: RK4 evaluates the actuator force at \
             four stages of a step while the muscle's chamber advances once per step (use Euler, \
             implicit, implicitfast or discrete)",
            name()
        ));
    }
    if acts.is_empty() {
        return Err(format!(
            "{}: {who}: drives no actuator: name it on one, <actuator><plugin tendon=\"...\" \
             plugin=\"{}\" instance=\"NAME\"/></actuator>",
            name(),
            name()
        ));
    }
    let mut actuators = Vec::with_capacity(acts.len());
    for &a in &acts {
        let (cn, on) = unsafe { (m.actuator_ctrlnum(a), m.actuator_outnum(a)) };
        if cn != 1 || on != 1 {
            let n = unsafe { ffi::text((api.mj_id2name)(m.0, MJ_OBJ_ACTUATOR, a as c_int)) };
            return Err(format!(
                "{}: {who}: actuator '{}' has {cn} controls and {on} force outputs; a muscle needs one of \
                 each (a spatial tendon between its anchors)",
                name(),
                n.unwrap_or_default()
            ));
        }
        let (ctrl, out) = unsafe { (m.actuator_ctrladr(a), m.actuator_outadr(a)) };
        actuators.push(Bound {
            id: a,
            ctrl: usize::try_from(ctrl).map_err(|_| "bad control address".to_string())?,
            out: usize::try_from(out).map_err(|_| "bad output address".to_string())?,
            memo: None,
        });
    }
    let (_, num) = unsafe { m.plugin_state_span(i) };
    if num != actuators.len() * STATE_LEN {
        return Err(format!(
            "{}: {who}: plugin_state holds {num} numbers, expected {} ({STATE_LEN} per actuator)",
            name(),
            actuators.len() * STATE_LEN
        ));
    }
    Ok(Instance {
        who,
        muscle,
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
        match plugin_data.cast::<Instance>().cast_const().as_ref() {
            Some(inst) => {
                let s0 = inst.muscle.initial_state();
                for chunk in s.chunks_exact_mut(STATE_LEN) {
                    chunk.copy_from_slice(&s0);
                }
            }
            None => s.fill(0.0),
        }
    })
}

/// The inputs of actuator `b` for a step: length, rate, clamped u, h.
///
/// # Safety
/// `m`, `d` are live and `b` one of the instance's actuators.
unsafe fn inputs(m: Model, d: Data, b: &Bound) -> (f64, f64, f64, f64) {
    unsafe {
        let mut u = d.ctrl(b.ctrl);
        // MuJoCo clamps ctrl for its own actuators only, in a copy: a plugin clamps it itself.
        if let Some((lo, hi)) = m.ctrlrange(b.ctrl).filter(|(lo, hi)| lo <= hi) {
            u = u.clamp(lo, hi);
        }
        (
            d.actuator_length(b.out),
            d.actuator_velocity(b.out),
            u,
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
                "plugin_state holds numbers the muscle cannot be in (set from outside?)"
            }
            Refused::Input => "the actuator length, velocity or the timestep is not finite",
        };
        ffi::warn(
            api,
            &format!(
                "{}: {}: actuator {a}: {what}; its force is 0 and its state is held until a reset \
                 (reported once)",
                name(),
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
            let (l, rate, u, h) = inputs(m, d, b);
            let s: &State = states[k * STATE_LEN..(k + 1) * STATE_LEN]
                .try_into()
                .expect("chunk of STATE_LEN");
            let r = inst.muscle.step(s, l, rate, u, h, &mut b.memo);
            // An actuator in a group that opt.disableactuator turns off gives no force (as MuJoCo's own).
            let g = m.actuator_group(b.id);
            let off = (0..=30).contains(&g) && (disabled >> g) & 1 == 1;
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
            let (l, rate, u, h) = inputs(m, d, b);
            let chunk = &mut states[k * STATE_LEN..(k + 1) * STATE_LEN];
            let s: State = (&*chunk).try_into().expect("chunk of STATE_LEN");
            match inst.muscle.step(&s, l, rate, u, h, &mut b.memo) {
                Ok((next, _)) => chunk.copy_from_slice(&next),
                Err(why) => {
                    let id = b.id;
                    refused(inst, id, why);
                }
            }
        }
    })
}

/// Registers `pneuflex.muscle` with the MuJoCo of this process.
pub fn register() -> Result<(), String> {
    let api = ffi::load_api()?;
    // SAFETY: a C string; MuJoCo returns NULL or its registered plugin.
    let existing = unsafe { (api.mjp_get_plugin)(NAME.as_ptr(), std::ptr::null_mut()) };
    if !existing.is_null() {
        ffi::warn(
            api,
            &format!(
                "{}: already registered by another copy of the plugin library; this copy is not used",
                name()
            ),
        );
        return Ok(());
    }
    let names: Vec<*const c_char> = muscle::KEYS.iter().map(|k| k.as_ptr()).collect();
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
