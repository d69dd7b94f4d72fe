//! Issue 14 item 4: the simulation allocates nothing per step. For every plant kind (ideal, linear,
//! pneumatic, multibody: the shipped scenes) and every controller of the scene, the product's loop
//! (`simulate_observed`: `sense → control_tick → record → trace → sinks → checks → actuate → advance`) is
//! warmed up, then run for a few hundred ticks under a counting global allocator (this test binary only),
//! and must not allocate, reallocate or free.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;

use pneuflex_control::{Sensors, Signal, Sink, Telemetry, ValveCommand};
use pneuflex_scene::plants::PlantError;
use pneuflex_scene::{EventSpec, Plant, Scene, build_plant, simulate_observed};

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

/// Turns the counting on when tick `WARM_UP` ends and off when tick `WARM_UP + COUNTED` ends.
struct Window {
    k: usize,
}

impl<W: ?Sized> Sink<W> for Window {
    fn row(&mut self, _values: &[f64], _world: &W) {
        if self.k == WARM_UP {
            CALLS.with(|c| c.set(0));
            COUNTING.with(|c| c.set(true));
        } else if self.k == WARM_UP + COUNTED {
            COUNTING.with(|c| c.set(false));
        }
        self.k += 1;
    }
}

/// The scene's plant, counting the allocator calls made inside its `advance` (Rapier's, for the
/// multibody plant) apart from the rest of the tick.
struct Counted<'a> {
    plant: &'a mut dyn Plant,
    in_advance: u64,
}

impl Plant for Counted<'_> {
    fn sense(&self) -> Sensors {
        self.plant.sense()
    }
    fn actuate(&mut self, command: ValveCommand, telemetry: &Telemetry) {
        self.plant.actuate(command, telemetry)
    }
    fn advance(&mut self, dt: f64) {
        let before = CALLS.with(Cell::get);
        self.plant.advance(dt);
        if COUNTING.with(Cell::get) {
            self.in_advance += CALLS.with(Cell::get) - before;
        }
    }
    fn apply(&mut self, event: &EventSpec) -> Result<(), PlantError> {
        self.plant.apply(event)
    }
    fn reset(&mut self) {
        self.plant.reset()
    }
    fn check_invariants(&self) -> Result<(), PlantError> {
        self.plant.check_invariants()
    }
    fn signals(&self) -> &'static [Signal] {
        self.plant.signals()
    }
    fn record(&self, out: &mut [f64]) {
        self.plant.record(out)
    }
}

/// Allocator calls over `COUNTED` ticks of each run of the scene through the product's loop
/// (`simulate_observed`: the host's events, trace, sinks, divergence and invariant checks), after
/// `WARM_UP` ticks: (run, calls outside `Plant::advance`, calls inside it).
fn per_step_allocations(scene_file: &str) -> Vec<(String, u64, u64)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(scene_file);
    let mut scene = Scene::load(&path).unwrap();
    // Ticks 0..=WARM_UP + COUNTED: the run ends with the counted window.
    scene.duration_s = (WARM_UP + COUNTED) as f64 * scene.dt_s;
    let setpoints = scene.setpoints().unwrap();
    (0..scene.runs.len())
        .map(|i| {
            let mut plant = build_plant(&scene).unwrap();
            let mut counted = Counted {
                plant: plant.as_mut(),
                in_advance: 0,
            };
            // A frozen run holds values its source's run gives; any held values allocate the same.
            let held = scene.runs[i]
                .frozen
                .as_ref()
                .map(|_| pneuflex_scene::FrozenValues {
                    g_m: 1e-3,
                    p_m_per_n: 1e-4,
                    d_s: -1e-3,
                });
            let mut controller = scene.run_controller(i, held).unwrap();
            let mut window = Window { k: 0 };
            let r = simulate_observed(
                &scene,
                i,
                &mut counted,
                controller.as_mut(),
                &setpoints,
                &mut |_| {},
                &mut window,
            )
            .unwrap();
            COUNTING.with(|c| c.set(false));
            assert!(r.diverged.is_none(), "{scene_file}: {:?}", r.diverged);
            assert_eq!(window.k, WARM_UP + COUNTED + 1, "{scene_file}: ticks");
            let calls = CALLS.with(Cell::get);
            (
                scene.runs[i].name.clone(),
                calls - counted.in_advance,
                counted.in_advance,
            )
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
/// `CarriageRig::step_with_force`, and it cannot be configured away: in a release build 7.1 allocator calls
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
