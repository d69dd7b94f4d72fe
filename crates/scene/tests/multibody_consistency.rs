//! The multibody rig reproduces the 1-DOF pneumatic plant on the Fig. 3 schedule when both describe the
//! same system: the same actuator sheet, incline, environment stiffness and surface, controller and
//! chamber step, with the 1-DOF mechanics set to the URDF's flange (mass, K_v). The rig is the shipped
//! `urdf/rig.urdf` with the shipped `scenes/paper-fig3-multibody.toml` (wood mount 700 N/m, 2 N·s/m).
//!
//! Two valves, two claims (docs/scenes.md, "Consistency with the 1-DOF plant"):
//! - with a proportional valve the closed loop is smooth and deterministic, and the bound holds on
//!   raw samples: RMS f_e difference <= 2 % of the 10 N level;
//! - with the rig's 40 Hz PWM on/off valve, whose edges the integrators locate inside the step (issue 13
//!   item 1; docs/pneumatics.md, "Convergence of the PWM valve"), the 1-DOF plant is converged (it differs
//!   from itself by ~0.001 N PWM-averaged when its step is halved) and the rig matches it PWM-averaged to
//!   1 % of the 10 N level. Before the valve's edges were located, the spool was sampled once per substep,
//!   the loop wandered by ~0.22 N with any perturbation, and the claim was only "no more than that floor".

use std::path::{Path, PathBuf};

use pneuflex_scene::schema::PlantSpec;
use pneuflex_scene::{LinearSpring, MultibodyPlant, OneDofPneumatic, RunResult, Scene, simulate};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn load(rel: &str) -> Scene {
    Scene::load(&repo(rel)).unwrap_or_else(|e| panic!("{e}"))
}

fn rms_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    (a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64).sqrt()
}

/// Moving average over one PWM period of the valve (centred; shorter at the ends).
fn pwm_average(v: &[f64], n: usize) -> Vec<f64> {
    let h = n / 2;
    (0..v.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(h), (i + h + 1).min(v.len()));
            v[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect()
}

/// The fig3-multibody scene (actuator sheet replaced by `sheet` if given), its plant, and the 1-DOF plant
/// of the same system with as many RK4 substeps per tick as the rig has chamber substeps.
fn plants(sheet: Option<&str>) -> (Scene, MultibodyPlant, OneDofPneumatic) {
    let mut scene = load("scenes/paper-fig3-multibody.toml");
    let PlantSpec::Multibody(mb) = &mut scene.plant else {
        panic!("paper-fig3-multibody is not a multibody scene")
    };
    if let Some(s) = sheet {
        mb.actuator = repo(s);
    }
    let (actuator, substeps_per_tick) = (
        mb.actuator.clone(),
        mb.chamber_substeps * mb.steps_per_tick(scene.dt_s),
    );
    let sheet_path = scene.resolve(&actuator);
    let rig = MultibodyPlant::from_scene(&scene).unwrap_or_else(|e| panic!("{e}"));
    let env = LinearSpring {
        stiffness_n_per_m: scene.environment.stiffness_n_per_m,
        x_e_m: scene.environment.x_e_m,
    };
    let mut model = pneuflex_pneumatics::ActuatorSheet::load(&sheet_path)
        .unwrap_or_else(|e| panic!("{e}"))
        .model();
    model.mechanics.moving_mass_kg = rig.flange_mass_kg();
    model.mechanics.viscous_n_s_per_m = rig.flange_damping_n_s_per_m();
    model.mechanics.alpha_rad = rig.config().alpha_rad;
    let one = OneDofPneumatic::new(model, env.x_e_m, env, substeps_per_tick);
    (scene, rig, one)
}

fn run(scene: &Scene, name: &str, plant: &mut dyn pneuflex_scene::Plant) -> RunResult {
    let i = scene.runs.iter().position(|r| r.name == name).expect("run");
    let sp = scene.setpoints().unwrap();
    let mut c = scene.controller(i).unwrap();
    let r = simulate(scene, i, plant, c.as_mut(), &sp, &mut |_| {}).unwrap();
    assert!(r.diverged.is_none(), "{:?}", r.diverged);
    r
}

/// Largest |mean f_e difference| over the scene's metric windows, N.
fn window_mean_diff(scene: &Scene, a: &RunResult, b: &RunResult) -> f64 {
    let mean = |v: &[f64], i: usize, j: usize| v[i..j].iter().sum::<f64>() / (j - i) as f64;
    scene
        .metrics
        .iter()
        .map(|w| {
            let i = (w.t0_s / scene.dt_s).round() as usize;
            let j = ((w.t1_s / scene.dt_s).round() as usize).min(a.trace.t().len());
            (mean(a.trace.f_e(), i, j) - mean(b.trace.f_e(), i, j)).abs()
        })
        .fold(0.0, f64::max)
}

/// The consistency claim: with the proportional valve sheet, impedance control on the Fig. 3
/// schedule, the Rapier rig's load cell and the 1-DOF plant's f_e differ by at most 2 % of the 10 N level
/// (0.2 N RMS) on raw samples. Measured 0.108 N, most of it one sample: at the stiffness change (6 s) the
/// 1-DOF spring reads the doubled force at once and the load cell (the contact impulse over the last
/// physics step) one step later. Without that sample the difference is 1 % or less (measured 0.061 N).
/// The adaptive run is not compared: with this valve the paper's gains limit-cycle at ~14 Hz on the 1-DOF
/// plant (docs/control.md), and a limit cycle's phase is not reproducible across models.
#[test]
fn multibody_reproduces_the_one_dof_plant_within_two_percent() {
    let (scene, mut rig, mut one) = plants(Some("pneumatics/paper-actuator-proportional.toml"));
    let r_rig = run(&scene, "impedance", &mut rig);
    let r_one = run(&scene, "impedance", &mut one);
    let raw = rms_diff(r_rig.trace.f_e(), r_one.trace.f_e());
    let windows = window_mean_diff(&scene, &r_rig, &r_one);
    // The sample at the stiffness event, where the load cell lags the massless spring by one step.
    let i_event = (scene.events[0].t_s() / scene.dt_s).round() as usize;
    let without = |v: &[f64]| {
        v.iter()
            .enumerate()
            .filter(|&(i, _)| i != i_event)
            .map(|(_, &x)| x)
            .collect::<Vec<f64>>()
    };
    let rest = rms_diff(&without(r_rig.trace.f_e()), &without(r_one.trace.f_e()));
    println!(
        "proportional valve, impedance: RMS f_e difference {raw:.3} N ({rest:.3} N without the sample at the stiffness change); window means within {windows:.3} N"
    );
    assert!(
        raw <= 0.2,
        "RMS f_e difference {raw:.3} N > 0.2 N (2 % of 10 N)"
    );
    assert!(
        rest <= 0.1,
        "RMS f_e difference without the event sample {rest:.3} N > 0.1 N (1 % of 10 N)"
    );
    assert!(
        windows <= 0.01,
        "window mean difference {windows:.3} N > 0.01 N"
    );
}

/// With the rig's 40 Hz PWM valve (the shipped scene as it is): the 1-DOF plant is converged in its step
/// (PWM-averaged f_e with the RK4 step halved within 0.01 N RMS), the PWM-averaged f_e of the rig differs
/// from the 1-DOF plant's by at most 0.1 N RMS (1 % of 10 N), and the mean force over every metric window
/// agrees to 0.01 N. Measured: rig vs 1-DOF 0.047 N, floor 0.001 N, window means within 0.001 N.
/// (Before the PWM edges were located inside the step, issue 13 item 1: 0.238 N, floor 0.219 N, window
/// means 0.018 N, and the bounds were 1.5 x the floor, 0.35 N and 0.05 N.) Raw samples differ by ~1.1 N:
/// the 9 g wood face resonates on its mount at 44 Hz, next to the PWM carrier, and the load cell reads
/// k q + c q' + m_face q'' where the massless 1-DOF spring reads k q.
#[test]
fn pwm_rig_matches_the_converged_one_dof_plant_within_one_percent() {
    let (scene, mut rig, mut one) = plants(None);
    let mut one_fine = OneDofPneumatic::new(
        *one.model(),
        scene.environment.x_e_m,
        one.environment(),
        2 * rig.drive().element.substeps() * rig.steps_per_tick(),
    );
    let r_rig = run(&scene, "impedance", &mut rig);
    let r_one = run(&scene, "impedance", &mut one);
    let r_fine = run(&scene, "impedance", &mut one_fine);
    // 40 Hz PWM of the actuator sheet's valve at a 1 ms control period: 25 samples.
    let n_pwm = (1.0 / (40.0 * scene.dt_s)).round() as usize;
    let avg = |r: &RunResult| pwm_average(r.trace.f_e(), n_pwm);
    let rig_vs_one = rms_diff(&avg(&r_rig), &avg(&r_one));
    let floor = rms_diff(&avg(&r_fine), &avg(&r_one));
    let windows = window_mean_diff(&scene, &r_rig, &r_one);
    println!(
        "PWM valve, impedance: PWM-averaged RMS f_e difference rig vs 1-DOF {rig_vs_one:.3} N, 1-DOF vs 1-DOF at half the step {floor:.3} N; window means within {windows:.3} N; raw rig vs 1-DOF {:.3} N",
        rms_diff(r_rig.trace.f_e(), r_one.trace.f_e())
    );
    assert!(
        floor <= 0.01,
        "1-DOF vs 1-DOF at half the step {floor:.3} N > 0.01 N: the PWM valve is not converged"
    );
    assert!(
        rig_vs_one <= 0.1,
        "rig vs 1-DOF {rig_vs_one:.3} N > 0.1 N (1 % of 10 N)"
    );
    assert!(
        windows <= 0.01,
        "window mean difference {windows:.3} N > 0.01 N"
    );
}
