//! Issue 14 item 4: the simulation allocates nothing per step. For every plant kind (ideal, linear,
//! pneumatic, multibody: the shipped scenes) and every controller of the scene, the runner's loop body
//! (`sense → control_tick → record → trace.push → check_invariants → actuate → advance`) is warmed up,
//! then run for a few hundred ticks under a counting global allocator (this test binary only), and must
//! not allocate, reallocate or free.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;

use pneuflex_scene::{Scene, Trace, build_plant};

/// The system allocator, counting the calls made on a thread while that thread's counting is on (the test
/// harness allocates on its own threads meanwhile).
struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static CALLS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    if COUNTING.with(Cell::get) {
        CALLS.with(|c| c.set(c.get() + 1));
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        count();
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// Allocator calls made by `f` on this thread.
fn allocations(f: impl FnOnce()) -> u64 {
    CALLS.with(|c| c.set(0));
    COUNTING.with(|c| c.set(true));
    f();
    COUNTING.with(|c| c.set(false));
    CALLS.with(Cell::get)
}

const WARM_UP: usize = 50;
const COUNTED: usize = 300;

/// Allocator calls over `COUNTED` ticks of each run of the scene, after `WARM_UP` ticks: (run, calls
/// outside `Plant::advance`, calls inside it).
fn per_step_allocations(scene_file: &str) -> Vec<(String, u64, u64)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(scene_file);
    let scene = Scene::load(&path).unwrap();
    let setpoints = scene.setpoints().unwrap();
    let dt = scene.dt_s;
    let n_loop = pneuflex_control::LOOP_SIGNALS.len();
    (0..scene.runs.len())
        .map(|i| {
            let mut plant = build_plant(&scene).unwrap();
            let mut controller = scene.controller(i).unwrap();
            let (c_sig, p_sig) = (controller.signals(), plant.signals());
            let columns = Trace::loop_columns(&[c_sig, p_sig]);
            let mut values = vec![0.0; columns.len()];
            let mut trace = Trace::with_capacity(WARM_UP + COUNTED, columns);
            let mut in_advance = 0;
            let calls = {
                // The runner's loop body, as in runner::simulate_loop (events aside: they are not per step).
                let mut tick = |k: usize| {
                    let t = k as f64 * dt;
                    let mut s = plant.sense();
                    s.t = t;
                    let sp = setpoints.at(t);
                    let (ctl_row, plant_row) = values.split_at_mut(n_loop + c_sig.len());
                    let (cmd, tel) =
                        pneuflex_control::control_tick(controller.as_mut(), &s, &sp, dt, ctl_row);
                    plant.record(plant_row);
                    trace.push(&values);
                    assert!(plant.check_invariants().is_ok(), "{scene_file} at t = {t}");
                    plant.actuate(cmd, &tel);
                    let before = CALLS.with(Cell::get);
                    plant.advance(dt);
                    in_advance += CALLS.with(Cell::get) - before;
                };
                for k in 0..WARM_UP {
                    tick(k);
                }
                allocations(|| {
                    for k in WARM_UP..WARM_UP + COUNTED {
                        tick(k);
                    }
                })
            };
            (scene.runs[i].name.clone(), calls - in_advance, in_advance)
        })
        .collect()
}

fn assert_none(scene_file: &str) {
    for (run, outside, inside) in per_step_allocations(scene_file) {
        assert_eq!(
            (outside, inside),
            (0, 0),
            "{scene_file}, run `{run}`: allocator calls in {COUNTED} ticks (outside advance, inside)"
        );
    }
}

#[test]
fn the_counter_counts() {
    let calls = allocations(|| drop(std::hint::black_box(vec![1u8; 16])));
    assert_eq!(calls, 2, "one allocation and one free");
}

#[test]
fn the_ideal_loop_allocates_nothing_per_step() {
    assert_none("paper-fig3-ideal.toml");
}

#[test]
fn the_linear_plant_allocates_nothing_per_step() {
    assert_none("paper-fig3-linear.toml");
}

#[test]
fn the_pneumatic_plant_allocates_nothing_per_step() {
    assert_none("paper-fig3.toml");
    assert_none("paper-fig3-proportional.toml");
}

/// The multibody plant: nothing of ours allocates, but Rapier 0.36's step does, inside
/// `RigWorld::step_with_force`, and it cannot be configured away: in a release build 7.1 allocator calls
/// (alloc or free) per tick on these scenes: 1 from `RigidBodySet::index_mut` (it pushes the handle onto
/// the modified-bodies list, which the pipeline takes and drops each step), 2 in parry's cuboid-cuboid
/// contact manifold, 2 in `PhysicsPipeline::step_inner`, 2 in the staged island solver's
/// `init_and_solve`; in the test profile (debug assertions on) 13.1. Bounded at 16 per tick so that a
/// new allocation of ours, or a larger one of Rapier's, shows.
#[test]
fn the_multibody_plant_allocates_only_inside_rapier() {
    for scene_file in ["paper-fig7-wood-to-iron.toml", "paper-fig3-multibody.toml"] {
        for (run, outside, inside) in per_step_allocations(scene_file) {
            eprintln!(
                "{scene_file}, run `{run}`: {inside} allocator calls in {COUNTED} ticks inside advance"
            );
            assert_eq!(outside, 0, "{scene_file}, run `{run}`: outside advance");
            assert!(
                inside <= 16 * COUNTED as u64,
                "{scene_file}, run `{run}`: {inside} allocator calls in {COUNTED} ticks inside advance"
            );
        }
    }
}
