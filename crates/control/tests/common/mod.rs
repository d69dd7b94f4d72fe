//! Test plant: an ideal inner position loop (x follows x_r through ω = 60 rad/s, ζ = 1) pushing
//! a linear spring f_e = k_e (x - x_e), contact lost when x < x_e; and the paper's Fig. 3 run.
#![allow(dead_code)]

use pneuflex_control::{Controller, Sensors, SetpointSchedule};

/// Ideal-loop plant state.
pub struct IdealPlant {
    pub x: f64,
    pub v: f64,
    pub omega: f64,
    pub zeta: f64,
    pub x_e: f64,
    pub k_e: f64,
}

impl IdealPlant {
    pub fn new(k_e: f64) -> Self {
        Self {
            x: 0.0,
            v: 0.0,
            omega: 60.0,
            zeta: 1.0,
            x_e: 0.0,
            k_e,
        }
    }
    pub fn force(&self) -> f64 {
        if self.x > self.x_e {
            self.k_e * (self.x - self.x_e)
        } else {
            0.0
        }
    }
    /// RK4 over dt with x_r held.
    pub fn advance(&mut self, x_r: f64, dt: f64) {
        let (w, z) = (self.omega, self.zeta);
        let f = |x: f64, v: f64| (v, w * w * (x_r - x) - 2.0 * z * w * v);
        let (k1x, k1v) = f(self.x, self.v);
        let (k2x, k2v) = f(self.x + 0.5 * dt * k1x, self.v + 0.5 * dt * k1v);
        let (k3x, k3v) = f(self.x + 0.5 * dt * k2x, self.v + 0.5 * dt * k2v);
        let (k4x, k4v) = f(self.x + dt * k3x, self.v + dt * k3v);
        self.x += dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        self.v += dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
    }
}

/// One sample of a run.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub t: f64,
    pub f_ref: f64,
    pub f_e: f64,
    pub x: f64,
    pub x_r: f64,
    pub g: f64,
    pub p: f64,
    pub d: f64,
}

/// Runs a schedule on the ideal plant: stiffness k_e0, switched to k_e1 at t_switch.
pub fn run<C: Controller>(
    c: &mut C,
    sched: &SetpointSchedule,
    k_e0: f64,
    k_e1: f64,
    t_switch: f64,
    t_end: f64,
    dt: f64,
) -> Vec<Sample> {
    let mut plant = IdealPlant::new(k_e0);
    let n = (t_end / dt).round() as usize;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let t = i as f64 * dt;
        if t >= t_switch - 1e-12 {
            plant.k_e = k_e1;
        }
        let sp = sched.at(t);
        let f_e = plant.force();
        let s = Sensors {
            t,
            x: plant.x,
            x_dot: plant.v,
            f_e,
            p_a: 0.0,
            p_b: 0.0,
        };
        c.update(&s, &sp, dt);
        let tel = c.telemetry();
        // The controller's own signals (the adaptive law's g, p, d), by their declared names.
        let mut own = [0.0; 8];
        let names = c.signals();
        c.record(&mut own[..names.len()]);
        let signal = |n: &str| {
            names
                .iter()
                .position(|s| s.name == n)
                .map_or(0.0, |i| own[i])
        };
        out.push(Sample {
            t,
            f_ref: sp.f_ref,
            f_e,
            x: plant.x,
            x_r: tel.x_r,
            g: signal("g"),
            p: signal("p"),
            d: signal("d"),
        });
        plant.advance(tel.x_r, dt);
    }
    out
}

/// RMS of f_ref - f_e over [t0, t1).
pub fn rms_error(tr: &[Sample], t0: f64, t1: f64) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for p in tr.iter().filter(|p| p.t >= t0 && p.t < t1) {
        s += (p.f_ref - p.f_e).powi(2);
        n += 1;
    }
    (s / n as f64).sqrt()
}

/// Least-squares fit of y = c + a sin(ωt) + b cos(ωt) over [t0, t1); returns (amplitude, phase rad).
pub fn fit_sine(tr: &[Sample], t0: f64, t1: f64, freq_hz: f64, force: bool) -> (f64, f64) {
    let w = std::f64::consts::TAU * freq_hz;
    // Normal equations of the 3-parameter fit.
    let mut m = [[0.0f64; 3]; 3];
    let mut r = [0.0f64; 3];
    for p in tr.iter().filter(|p| p.t >= t0 && p.t < t1) {
        let y = if force { p.f_e } else { p.f_ref };
        let phi = [1.0, (w * p.t).sin(), (w * p.t).cos()];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += phi[i] * phi[j];
            }
            r[i] += phi[i] * y;
        }
    }
    let sol = solve3(m, r);
    let (a, b) = (sol[1], sol[2]);
    ((a * a + b * b).sqrt(), b.atan2(a))
}

fn solve3(mut m: [[f64; 3]; 3], mut r: [f64; 3]) -> [f64; 3] {
    #[allow(clippy::needless_range_loop)]
    for k in 0..3 {
        let piv = (k..3)
            .max_by(|&a, &b| m[a][k].abs().total_cmp(&m[b][k].abs()))
            .unwrap();
        m.swap(k, piv);
        r.swap(k, piv);
        for i in k + 1..3 {
            let f = m[i][k] / m[k][k];
            for j in k..3 {
                m[i][j] -= f * m[k][j];
            }
            r[i] -= f * r[k];
        }
    }
    let mut x = [0.0; 3];
    for i in (0..3).rev() {
        let mut s = r[i];
        for j in i + 1..3 {
            s -= m[i][j] * x[j];
        }
        x[i] = s / m[i][i];
    }
    x
}

/// Phase lag of f_e behind f_ref at `freq_hz` over [t0, t1), degrees.
pub fn lag_deg(tr: &[Sample], t0: f64, t1: f64, freq_hz: f64) -> f64 {
    let (_, ph_ref) = fit_sine(tr, t0, t1, freq_hz, false);
    let (_, ph_f) = fit_sine(tr, t0, t1, freq_hz, true);
    let mut d = (ph_ref - ph_f).to_degrees();
    while d > 180.0 {
        d -= 360.0;
    }
    while d < -180.0 {
        d += 360.0;
    }
    d
}

/// Largest f_e - f_ref over [t0, t1), N (the recovery overshoot after an event).
pub fn max_overshoot(tr: &[Sample], t0: f64, t1: f64) -> f64 {
    tr.iter()
        .filter(|p| p.t >= t0 && p.t < t1)
        .map(|p| p.f_e - p.f_ref)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Time after t0 from which |f_e - f_ref| stays within `band` N until t1 (None if never).
pub fn settle_time(tr: &[Sample], t0: f64, t1: f64, band: f64) -> Option<f64> {
    let win: Vec<_> = tr.iter().filter(|p| p.t >= t0 && p.t < t1).collect();
    let last_out = win.iter().rposition(|p| (p.f_e - p.f_ref).abs() > band);
    match last_out {
        None => Some(0.0),
        Some(i) if i + 1 < win.len() => Some(win[i + 1].t - t0),
        _ => None,
    }
}

/// Whether every sample is finite and |x| stays below 1 m.
pub fn bounded(tr: &[Sample]) -> bool {
    tr.iter()
        .all(|p| p.f_e.is_finite() && p.x.is_finite() && p.x.abs() < 1.0)
}
