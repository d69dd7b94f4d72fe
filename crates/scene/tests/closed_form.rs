//! Impedance control on the ideal plant against the closed form of its linear force loop.
//!
//! With the ideal inner loop x = G(s) x_r, G = ω²/(s² + 2ζωs + ω²), the impedance filter
//! x_f = e / Z(s), Z = m_d s² + b_d s + k_d (eq. (22)), x_r = x_d + x_f (eq. (23)), e = f_r - f_e and the
//! environment f_e = k_e (x - x_e) (eq. (21)) with x_d = x_e and contact kept:
//!     f_e = k_e G x_f = k_e G (f_r - f_e) / Z   ⇒   f_e / f_r = k_e G / (Z + k_e G).
//! At s = 0 (G = 1): f_e / f_r = k_e / (k_d + k_e), i.e. a static force error f_r k_d / (k_d + k_e).
//! The sampled controller holds e over a period (delay dt/2) but applies x_f(t_{k+1}) over [t_k, t_{k+1}]
//! (advance dt, then hold: delay dt/2): the net delay is zero to first order in dt.

use std::path::Path;

use pneuflex_scene::{PlantSpec, Scene, run_scene};

#[derive(Clone, Copy)]
struct C(f64, f64);
impl C {
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    fn abs(self) -> f64 {
        self.0.hypot(self.1)
    }
    fn arg(self) -> f64 {
        self.1.atan2(self.0)
    }
}

/// f_e / f_r of the linear loop at s = jw.
fn h(w: f64, m_d: f64, b_d: f64, k_d: f64, k_e: f64, omega: f64, zeta: f64) -> C {
    let s = C(0.0, w);
    let s2 = s.mul(s);
    let z = C(m_d, 0.0).mul(s2).add(C(b_d, 0.0).mul(s)).add(C(k_d, 0.0));
    let g = C(omega * omega, 0.0).div(
        s2.add(C(2.0 * zeta * omega, 0.0).mul(s))
            .add(C(omega * omega, 0.0)),
    );
    let keg = C(k_e, 0.0).mul(g);
    keg.div(z.add(keg))
}

fn fig2_on_ideal_plant(k_d: f64) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig2.toml");
    let mut scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    scene.plant = PlantSpec::Ideal {
        omega_rad_per_s: 200.0,
        zeta: 1.0,
        x0_m: scene.environment.x_e_m,
    };
    scene.runs[0].impedance.k_d_n_per_m = k_d;
    scene.validate().unwrap_or_else(|e| panic!("{e}"));
    scene
}

fn check(k_d: f64) {
    let scene = fig2_on_ideal_plant(k_d);
    assert_eq!(
        scene.reference.x_d_m, scene.environment.x_e_m,
        "closed form assumes x_d = x_e"
    );
    let res = run_scene(&scene, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    let r = &res[0];
    assert!(r.diverged.is_none(), "{:?}", r.diverged);
    let imp = scene.runs[0].impedance;
    let k_e = scene.environment.stiffness_n_per_m;
    let (omega, zeta) = (200.0, 1.0);
    let f = 0.8;
    let w = std::f64::consts::TAU * f;
    let hw = h(
        w,
        imp.m_d_kg,
        imp.b_d_ns_per_m,
        imp.k_d_n_per_m,
        k_e,
        omega,
        zeta,
    );
    let lag_cf = -hw.arg().to_degrees();
    let win = r.window("sine").expect("sine window");
    let lag = win.phase_lag_deg.unwrap();
    assert!(
        (lag - lag_cf).abs() < 0.5,
        "k_d = {k_d}: phase lag {lag:.3}° vs closed form {lag_cf:.3}°"
    );
    let ratio = win.amplitude_ratio.unwrap();
    assert!(
        (ratio - hw.abs()).abs() < 0.01 * hw.abs(),
        "k_d = {k_d}: amplitude ratio {ratio:.4} vs {:.4}",
        hw.abs()
    );
    // Static force error: the bias of f_e against the bias of f_r (10 N), from the same least-squares fit.
    let (i0, i1) = pneuflex_scene::analysis::metrics::window_indices(r.trace.t(), 5.0, 10.0);
    let (_, _, bias) = pneuflex_scene::analysis::metrics::fit_sine(
        &r.trace.t()[i0..i1],
        &r.trace.f_e()[i0..i1],
        w,
    )
    .unwrap();
    let static_err = 10.0 - bias;
    let static_cf = 10.0 * k_d / (k_d + k_e);
    assert!(
        (static_err - static_cf).abs() < 0.02,
        "k_d = {k_d}: static error {static_err:.4} N vs closed form {static_cf:.4} N"
    );
    eprintln!(
        "k_d = {k_d}: lag {lag:.3}° (closed form {lag_cf:.3}°), static error {static_err:.4} N ({static_cf:.4} N)"
    );
}

#[test]
fn impedance_on_ideal_plant_matches_closed_form_with_scene_k_d() {
    check(fig2_on_ideal_plant(0.0).runs[0].impedance.k_d_n_per_m);
}

#[test]
fn impedance_on_ideal_plant_matches_closed_form_with_nonzero_k_d() {
    check(200.0);
}
