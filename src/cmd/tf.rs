//! `pneuflex tf <file>`: the linearised transfer function of eqs. (16)-(17) of an actuator sheet (or of
//! the sheet a scene names), at mid-stroke holding no external load.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context as _;
use pneuflex_pneumatics::load_actuator_sheet;

/// Computes K_n, omega_n, xi_n and the denominator of eq. (16) for the actuator in `path`; returns a
/// table, or one JSON object (SI units) when `json` is set.
pub fn tf(path: &Path, json: bool) -> anyhow::Result<String> {
    // Errors name the file, the line and the key (also the scene key or sheet key naming a missing file).
    let sheet = load_actuator_sheet(path)?;
    let sheet_path = sheet.path.clone();
    let model = sheet.model();
    let (op, tf) = model
        .transfer_function_mid_stroke()
        .with_context(|| format!("{}: no operating point at mid-stroke", sheet_path.display()))?;
    let lin = model.linearise(&op);
    let [a3, a2, a1, a0] = tf.den;
    if json {
        let v = serde_json::json!({
            "actuator": sheet_path.display().to_string(),
            "k_n": tf.k_n,
            "omega_n": tf.omega_n,
            "xi_n": tf.xi_n,
            "num": tf.num,
            "den": tf.den,
            "a3": a3, "a2": a2, "a1": a1, "a0": a0,
            "operating_point": {
                "x": op.x, "u": op.u, "p_a": op.p_a, "p_b": op.p_b, "temperature": op.temperature_k,
            },
            "k_pa": lin.k_pa, "k_pb": lin.k_pb, "k_ca": lin.k_ca, "k_cb": lin.k_cb,
        });
        return Ok(serde_json::to_string_pretty(&v)?);
    }
    let mut s = String::new();
    writeln!(
        s,
        "transfer function Y(s)/P_L(s), eqs. (16)-(17): {}",
        sheet_path.display()
    )?;
    writeln!(
        s,
        "operating point: x = {:.4} m (mid-stroke), u0 = {:+.4}, p_a = {:.0} Pa abs, p_b = {:.0} Pa abs, T = {:.2} K",
        op.x, op.u, op.p_a, op.p_b, op.temperature_k
    )?;
    let rows: [(&str, f64, &str); 12] = [
        ("K_n", tf.k_n, "m/(Pa s)"),
        ("omega_n", tf.omega_n, "rad/s"),
        ("f_n", tf.omega_n / (2.0 * std::f64::consts::PI), "Hz"),
        ("xi_n", tf.xi_n, "1"),
        ("a3 (s^3)", a3, "kg m^3"),
        ("a2 (s^2)", a2, "kg m^3/s"),
        ("a1 (s^1) = beta_n", a1, "kg m^3/s^2"),
        ("a0 (s^0)", a0, "kg m^3/s^3"),
        ("b0 (numerator)", tf.num, "m^5/s"),
        ("K_ca", lin.k_ca, "kg/(s Pa)"),
        ("K_cb", lin.k_cb, "kg/(s Pa)"),
        ("K_pa", lin.k_pa, "kg/s"),
    ];
    writeln!(s, "{:<20} {:>14}  unit", "quantity", "value")?;
    for (name, v, unit) in rows {
        writeln!(s, "{name:<20} {v:>14.6e}  {unit}")?;
    }
    Ok(s)
}
