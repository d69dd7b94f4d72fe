//! Issue 13 item 2: the paper's linear plant (eqs. (16)/(17)). On paper-fig3-linear the impedance loop's
//! phase lag and RMS force error on the sine equal the closed form from the loop's transfer function
//! (within 0.1° and 1 %), evaluated from the same K_n, ω_n, ξ_n the plant uses.

use std::path::Path;

use pneuflex_scene::plants::LinearPlant;
use pneuflex_scene::{LinearSpring, Plant, PlantSpec, Scene, run_scene};

/// A complex number, enough for a transfer function at s = jω.
#[derive(Clone, Copy, Debug)]
struct C(f64, f64);
impl std::ops::Add for C {
    type Output = C;
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
}
impl std::ops::Sub for C {
    type Output = C;
    fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
}
impl std::ops::Mul for C {
    type Output = C;
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
}
impl std::ops::Div for C {
    type Output = C;
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
}
fn r(x: f64) -> C {
    C(x, 0.0)
}

fn scene(dt_s: f64) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-linear.toml");
    let text = std::fs::read_to_string(&path).unwrap().replacen(
        "dt_s = 0.001",
        &format!("dt_s = {dt_s:e}"),
        1,
    );
    let mut s = Scene::from_toml_str(&text, &path, path.parent().unwrap()).unwrap();
    // Two whole periods of the 1 Hz sine, after the transient of the step-to-sine change at 3 s.
    let w = s.metrics.iter_mut().find(|w| w.name == "sine").unwrap();
    (w.t0_s, w.t1_s) = (4.0, 6.0);
    s
}

#[test]
fn impedance_on_the_linear_plant_matches_the_closed_form_loop() {
    // 0.1 ms ticks: the controller's zero-order hold (half a tick of delay, 0.018° at 1 Hz) is below the
    // tolerance; the closed form is the continuous loop.
    let s = scene(1e-4);
    let res = run_scene(&s, &mut |_| {}).unwrap();
    let imp = res.iter().find(|r| r.name == "impedance").unwrap();
    let sine = imp.window("sine").unwrap();

    // The plant's own parameters (from the sheet's linearisation), and the run's gains.
    let env = LinearSpring {
        stiffness_n_per_m: s.environment.stiffness_n_per_m,
        x_e_m: s.environment.x_e_m,
    };
    let plant = LinearPlant::from_scene(&s, env).unwrap();
    let m = *plant.model();
    assert!(matches!(s.plant, PlantSpec::Linear { .. }));
    let run = &s.runs[0];
    let (md, bd, kd) = (
        run.impedance.m_d_kg,
        run.impedance.b_d_ns_per_m,
        run.impedance.k_d_n_per_m,
    );
    let (kp, ki) = (run.inner.kp_per_m, run.inner.ki_per_m_s);
    assert_eq!(
        run.inner.kd_s_per_m, 0.0,
        "the closed form below has no derivative term"
    );
    let k_e = s.environment.stiffness_n_per_m;

    // s = jω at the reference frequency (1 Hz).
    let w = std::f64::consts::TAU * sine.frequency_hz.unwrap();
    let s_ = C(0.0, w);
    // Plant, eq. (17): H = K_n / (s (s²/ω_n² + 2 ξ_n s/ω_n + 1)).
    let h = r(m.k_n)
        / (s_ * (s_ * s_ / r(m.omega_n * m.omega_n) + r(2.0 * m.zeta_n / m.omega_n) * s_ + r(1.0)));
    // Inner PI, load pressure per unit command, contact as load-pressure disturbance -f_e/S_a:
    // x = H (P C (x_r - x) - k_e x / S_a)  =>  x / x_r = H P C / (1 + H P C + H k_e / S_a).
    let c = r(kp) + r(ki) / s_;
    let hpc = h * r(m.p_range) * c;
    let a = hpc / (r(1.0) + hpc + h * r(k_e / m.area_a));
    // Impedance filter, eq. (22): x_f = (f_r - f_e) / Z; f_e = k_e x  =>  f_e / f_r = k_e A / (Z + k_e A).
    let z = r(md) * s_ * s_ + r(bd) * s_ + r(kd);
    let t = r(k_e) * a / (z + r(k_e) * a);
    let lag_deg = -t.1.atan2(t.0).to_degrees();
    let err = r(1.0) - t;
    let amp = 2.0; // the scene's sine amplitude, N
    let rms = amp * (err.0 * err.0 + err.1 * err.1).sqrt() / 2f64.sqrt();

    let sim_lag = sine.phase_lag_deg.unwrap();
    eprintln!(
        "paper-fig3-linear impedance sine: lag {sim_lag:.4}° (closed form {lag_deg:.4}°), RMS {:.5} N (closed form {rms:.5} N)",
        sine.rms_force_error_n
    );
    assert!(
        (sim_lag - lag_deg).abs() < 0.1,
        "lag: simulated {sim_lag:.3}°, closed form {lag_deg:.3}°"
    );
    let sim_rms = sine.rms_force_error_n;
    assert!(
        (sim_rms - rms).abs() < 0.01 * rms,
        "RMS: simulated {sim_rms:.5} N, closed form {rms:.5} N"
    );
}

#[test]
fn a_linear_plant_needs_a_sheet_or_every_number() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-linear.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let bad = text.replacen(
        "actuator = \"../pneumatics/paper-actuator.toml\"",
        "k_n_m_per_pa_s = 5e-6",
        1,
    );
    let e = Scene::from_toml_str(&bad, &path, path.parent().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("plant.omega_n_rad_per_s: missing"), "{e}");
    let given = text.replacen(
        "actuator = \"../pneumatics/paper-actuator.toml\"",
        "k_n_m_per_pa_s = 5.28e-6\nomega_n_rad_per_s = 110.0\nzeta_n = 0.531\narea_a_m2 = 2.0e-4\nload_pressure_range_pa = 5.0e5",
        1,
    );
    let s = Scene::from_toml_str(&given, &path, path.parent().unwrap()).unwrap();
    let res = run_scene(&s, &mut |_| {}).unwrap();
    assert!(res.iter().all(|r| r.diverged.is_none()));
    let p = LinearPlant::from_scene(
        &s,
        LinearSpring {
            stiffness_n_per_m: 700.0,
            x_e_m: 0.0,
        },
    )
    .unwrap();
    assert_eq!(p.model().omega_n, 110.0);
    let _ = p.sense();
}
