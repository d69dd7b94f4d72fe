//! A spring-damper on a joint: Rapier's force-based motor, with its implicit damping taken back.

use rapier3d_f64::prelude::*;

/// Makes `joint`'s `axis` a spring-damper F = k (q0 - q) - c q' (N or N m).
///
/// Rapier integrates a force-based motor implicitly over each solver substep h (the physics step over
/// the solver iterations): F = k (q0 - q - h q'⁺) - c q'⁺, a damping of c + k h. On the paper's iron
/// (1400 N/m, 2 N s/m) at h = 1 ms that is 70 % more damping than the material's, and the PWM ripple of the
/// contact force grew with h (iron 0.90 / 0.95 / 1.06 / 1.27 N at h = 0.125 / 0.25 / 0.5 / 1 ms against
/// MuJoCo's 0.86 N; docs/performance.md). The motor is given c - k h, so the spring acts on the substep's
/// start position (semi-implicit Euler, stable for ω h < 2) and the damping is the one asked for: the
/// ripple is then 0.87 / 0.86 N at h = 1 / 0.125 ms. Where c < 1.1 k h only part of k h can be taken back
/// (c - k h would leave the motor too little damping to be well posed): c / 10 is the floor.
pub fn set_joint_spring(
    world: &mut PhysicsWorld,
    joint: ImpulseJointHandle,
    axis: JointAxis,
    q0: f64,
    k: f64,
    c: f64,
) {
    let ip = &world.integration_parameters;
    let h = ip.dt / ip.num_solver_iterations as f64;
    let c_motor = (c - k * h).max(0.1 * c);
    if let Some(j) = world.impulse_joints.get_mut(joint, true) {
        j.data.set_motor_model(axis, MotorModel::ForceBased);
        j.data.set_motor(axis, q0, 0.0, k, c_motor);
    }
}
