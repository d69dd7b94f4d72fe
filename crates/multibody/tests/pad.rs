//! The implicit pad (mechanism/contact.rs (P3)) against the closed-form mass–spring–damper: a block on a
//! slide pushed by a constant force into a fixed wall through a Kelvin–Voigt pad. From first touch
//! (δ = δ̇ = 0), m δ̈ = F0 − k δ − c δ̇ has the closed form
//! δ(t) = F0/k (1 − e^{−ζωt} (cos ω_d t + ζω/ω_d sin ω_d t)), ω² = k/m, ζ = c/(2 m ω), ω_d = ω √(1 − ζ²),
//! and the pad force is k δ + c δ̇.

use std::path::PathBuf;

use pneuflex_multibody::{ActuatorConfig, ContactConfig, Mechanism, MechanismConfig, Mount};

/// A fixed wall whose face is at x = 0.04 m and a block of `mass_kg` on a slide along x whose face
/// touches it at q = 0.
fn urdf(mass_kg: f64) -> PathBuf {
    let i = mass_kg * 0.02 * 0.02 / 6.0;
    let text = format!(
        r#"<?xml version="1.0"?>
<robot name="pad_test">
  <link name="wall">
    <collision><origin xyz="0.05 0 0"/><geometry><box size="0.02 0.05 0.05"/></geometry></collision>
  </link>
  <link name="block">
    <inertial><mass value="{mass_kg}"/><inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial>
    <collision><geometry><box size="0.02 0.02 0.02"/></geometry></collision>
  </link>
  <joint name="slide" type="prismatic">
    <parent link="wall"/><child link="block"/>
    <origin xyz="0.03 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-0.01" upper="0.01" effort="100" velocity="10"/>
  </joint>
</robot>
"#
    );
    let path = std::env::temp_dir().join(format!(
        "pneuflex-pad-{}-{mass_kg}.urdf",
        std::process::id()
    ));
    std::fs::write(&path, text).unwrap();
    path
}

struct Pad {
    mass_kg: f64,
    k: f64,
    c: f64,
}

impl Pad {
    /// The closed-form pad force at time t after first touch under a constant push f0 (underdamped).
    fn force(&self, f0: f64, t: f64) -> f64 {
        let w = (self.k / self.mass_kg).sqrt();
        let zeta = self.c / (2.0 * self.mass_kg * w);
        assert!(zeta < 1.0, "the closed form here is the underdamped one");
        let wd = w * (1.0 - zeta * zeta).sqrt();
        let decay = (-zeta * w * t).exp();
        let delta = f0 / self.k * (1.0 - decay * ((wd * t).cos() + zeta * w / wd * (wd * t).sin()));
        // δ̇ = F0/k e^{−ζωt} (ω²/ω_d) sin ω_d t.
        let delta_dot = f0 / self.k * decay * (w * w / wd) * (wd * t).sin();
        self.k * delta + self.c * delta_dot
    }

    /// Pushes the block into the wall with `f0` for `steps` steps of `dt_s`: each step's sensor reading
    /// and the block's velocity after it.
    fn run(&self, f0: f64, dt_s: f64, steps: usize) -> (Vec<f64>, Vec<f64>) {
        let (forces, speeds, _) = self.run_read(f0, dt_s, steps);
        (forces, speeds)
    }

    /// [`Pad::run`] with each step's ω h as the reading gives it.
    fn run_read(&self, f0: f64, dt_s: f64, steps: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut config = MechanismConfig::new(
            vec![ActuatorConfig {
                name: "push".into(),
                mount: Mount::Joint {
                    joint: "slide".into(),
                },
            }],
            vec![ContactConfig {
                name: "pad".into(),
                link_a: "wall".into(),
                link_b: "block".into(),
                stiffness_n_per_m: self.k,
                damping_n_s_per_m: self.c,
            }],
        );
        config.gravity_m_s2 = [0.0; 3];
        config.dt_s = dt_s;
        config.solver_iterations = 2;
        let path = urdf(self.mass_kg);
        let mut m = Mechanism::from_urdf(&path, &config).unwrap();
        std::fs::remove_file(path).ok();
        let pad = m.contact_index("pad").unwrap();
        let (mut forces, mut speeds, mut omega_h) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..steps {
            m.step_with_forces(&[f0]);
            forces.push(m.contact(pad).force_n);
            speeds.push(m.joint_position("slide").unwrap().1);
            omega_h.push(m.contact(pad).omega_h);
        }
        (forces, speeds, omega_h)
    }
}

#[test]
fn the_pad_follows_the_closed_form_spring_damper_response_from_first_touch() {
    // A rubber pad on a 0.1 kg block: ω = 447 rad/s, ζ = 0.11, 3.5 periods.
    let pad = Pad {
        mass_kg: 0.1,
        k: 2.0e4,
        c: 10.0,
    };
    let f0 = 10.0;
    // The force held over step n is the pad's force at the step's end (backward Euler, (P2)): first-order
    // accurate, so the error to the closed form halves with the step.
    let worst = |h: f64| {
        let (forces, _) = pad.run(f0, h, (0.05 / h).round() as usize);
        forces
            .iter()
            .enumerate()
            .map(|(n, f)| (f - pad.force(f0, (n + 1) as f64 * h)).abs())
            .fold(0.0, f64::max)
    };
    let (coarse, fine) = (worst(5.0e-5), worst(2.5e-5));
    assert!(
        fine < 0.02 * f0,
        "pad force off the closed form by up to {fine} N at ω h = 0.011 (F0 = {f0} N)"
    );
    let order = coarse / fine;
    assert!(
        (1.7..2.3).contains(&order),
        "halving the step divided the error by {order} ({coarse} N, {fine} N), not 2"
    );
}

#[test]
fn a_stiff_pad_on_a_light_body_is_stable_at_the_control_step_and_reads_the_force_applied() {
    // The paper rig's pad on its 9 g face: ω = 3333 rad/s, ζ = 0.92; at h = 1 ms, ω h = 3.3 and
    // c h / m = 6.1, where the explicit pad F = k δ + c δ̇ diverges.
    let pad = Pad {
        mass_kg: 0.009,
        k: 1.0e5,
        c: 55.0,
    };
    let (f0, h) = (10.0, 1.0e-3);
    let (forces, speeds) = pad.run(f0, h, 200);
    // Stable: after the first touch (one free step puts the block 1.1 mm deep at 1.1 m/s) the force
    // settles on F0 within 10 steps, with no oscillation left.
    let settled = |from: usize, to: usize| {
        forces[from..to]
            .iter()
            .map(|f| (f - f0).abs())
            .fold(0.0, f64::max)
    };
    assert!(
        settled(10, 20) < 0.01 * f0,
        "still {} N off F0 after 10 steps",
        settled(10, 20)
    );
    assert!(
        settled(30, 200) < 1e-6 * f0,
        "{} N off F0 after 30 steps",
        settled(30, 200)
    );
    // The sensor reads the force the block got: its momentum is the impulse of the push less the pad's.
    for (n, v) in speeds.iter().enumerate() {
        let impulse: f64 = forces[..=n].iter().map(|f| (f0 - f) * h).sum();
        assert!(
            (pad.mass_kg * v - impulse).abs() < 1e-9 + 1e-6 * f0 * h,
            "step {n}: momentum {} N s, impulse of the forces read {impulse} N s",
            pad.mass_kg * v
        );
    }
}

#[test]
fn a_touching_pad_reads_its_natural_frequency_times_the_step() {
    // The block on its slide against the fixed wall: W = 1/m, so ω h = h √(k/m) while it touches, 0 apart.
    // The plant stops a run whose pad is far beyond 1 (crates/scene, MAX_PAD_OMEGA_H).
    for (k, h) in [(2.0e4, 1.0e-3), (1.0e12, 5.0e-4)] {
        let pad = Pad {
            mass_kg: 0.1,
            k,
            c: 0.0,
        };
        let (forces, _, omega_h) = pad.run_read(10.0, h, 40);
        let expected = h * (k / pad.mass_kg).sqrt();
        let touching: Vec<f64> = forces
            .iter()
            .zip(&omega_h)
            .filter(|(f, _)| **f > 0.0)
            .map(|(_, w)| *w)
            .collect();
        assert!(!touching.is_empty(), "k = {k}: the block never touched");
        for w in touching {
            assert!(
                (w - expected).abs() <= 1e-9 * expected,
                "k = {k}, h = {h}: ω h read {w}, h √(k/m) = {expected}"
            );
        }
        assert_eq!(omega_h[0], 0.0, "apart at the first step: 0");
    }
}
