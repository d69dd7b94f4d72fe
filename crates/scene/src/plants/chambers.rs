//! What the plants with a pneumatic actuator share: the valve's recorded signal and the physical invariants of
//! the two chambers.

use super::PlantError;

/// The valve's recorded signal, for plants with a pneumatic valve: its spool, which under PWM is the
/// energised side (+1 / -1) — the valve's PWM state.
pub const VALVE_SIGNALS: [pneuflex_control::Signal; 1] = [pneuflex_control::Signal::new(
    "spool",
    "1",
    "valve",
    "valve spool position in [-1, 1] (on/off valve under PWM: the energised side, +1 or -1)",
)];

/// How far above the supply pressure a chamber may go before the state is impossible: a closed chamber
/// compressed by the piston can exceed supply, but not double it in any case the model is meant for.
pub const PRESSURE_MARGIN: f64 = 2.0;

/// The physical invariants of a two-chamber actuator: 0 < p <= PRESSURE_MARGIN · p_supply (absolute),
/// 0 < T < 2000 K, and the piston within the stroke plus 1 mm + 1 % (the end stops are inelastic).
pub fn chamber_invariants(
    ch: &pneuflex_pneumatics::ChamberState,
    supply: &pneuflex_pneumatics::Supply,
    x_m: f64,
    stroke_m: f64,
) -> Result<(), PlantError> {
    let p_max = PRESSURE_MARGIN * supply.supply_pressure_pa;
    for (name, p) in [("p_a", ch.p_a), ("p_b", ch.p_b)] {
        if !(p > 0.0 && p <= p_max) {
            return Err(PlantError::invariant(format!(
                "chamber pressure {name} = {p:.6e} Pa (absolute) outside (0, {p_max:.3e}] Pa \
                 ({PRESSURE_MARGIN} x supply)"
            )));
        }
    }
    for (name, t) in [("T_a", ch.t_a), ("T_b", ch.t_b)] {
        if !(t > 0.0 && t < 2000.0) {
            return Err(PlantError::invariant(format!(
                "chamber temperature {name} = {t:.6e} K outside (0, 2000) K"
            )));
        }
    }
    let tol = 1e-3 + 0.01 * stroke_m;
    if !(x_m >= -tol && x_m <= stroke_m + tol) {
        return Err(PlantError::invariant(format!(
            "piston position x = {x_m:.6e} m outside the stroke [0, {stroke_m}] m (+/- {tol:.4} m)"
        )));
    }
    Ok(())
}
