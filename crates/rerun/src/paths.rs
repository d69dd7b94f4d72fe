//! Entity paths and timeline names shared by simulation and rig recordings.

/// Duration timeline of simulated runs (seconds since start).
pub const SIM_TIME: &str = "sim_time";
/// Timestamp timeline of real-rig runs (wall clock).
pub const WALL_TIME: &str = "wall_time";

/// Force set-point f_ref (N).
pub const F_REF: &str = "signals/force/f_ref";
/// Measured environment force f_e (N).
pub const F_E: &str = "signals/force/f_e";
/// Piston position x (m; `SceneRecorder` logs mm).
pub const X: &str = "signals/position/x";
/// Position reference x_r (m; `SceneRecorder` logs mm).
pub const X_R: &str = "signals/position/x_r";
/// Absolute pressure in chamber A (Pa; `SceneRecorder` logs kPa).
pub const P_A: &str = "signals/pressure/p_a";
/// Absolute pressure in chamber B (Pa; `SceneRecorder` logs kPa).
pub const P_B: &str = "signals/pressure/p_b";
/// Continuous valve command u.
pub const VALVE_U: &str = "signals/valve/u";
/// Valve spool (under PWM the energised side, +1 / -1), declared by the pneumatic plants.
pub const VALVE_SPOOL: &str = "signals/valve/spool";
/// Adaptive impedance gain g.
pub const ADAPTIVE_G: &str = "signals/adaptive/g";
/// Adaptive impedance stiffness-like term p.
pub const ADAPTIVE_P: &str = "signals/adaptive/p";
/// Adaptive impedance damping-like term d.
pub const ADAPTIVE_D: &str = "signals/adaptive/d";

/// The signals registered (entity path and series name) when a recorder opens.
pub const SIGNALS: [&str; 11] = [
    F_REF,
    F_E,
    X,
    X_R,
    P_A,
    P_B,
    VALVE_U,
    VALVE_SPOOL,
    ADAPTIVE_G,
    ADAPTIVE_P,
    ADAPTIVE_D,
];

/// SI unit of a signal of [`SIGNALS`] as its producer declares it (`""` for another path).
pub fn unit_of(path: &str) -> &'static str {
    match path {
        F_REF | F_E => "N",
        X | X_R | ADAPTIVE_G => "m",
        P_A | P_B => "Pa",
        VALVE_U | VALVE_SPOOL => "1",
        ADAPTIVE_P => "m/N",
        ADAPTIVE_D => "s",
        _ => "",
    }
}

/// Path of the PWM-period average recorded beside a chattering signal (`signals/force/f_e_avg`).
pub fn average(path: &str) -> String {
    format!("{path}_avg")
}

/// Root of the 3D scene.
pub const WORLD: &str = "world";
/// Prefix of link entities (`world/links/<name>`).
pub const LINKS: &str = "world/links";
/// Contact point (Points3D).
pub const CONTACT_POINT: &str = "world/contact/point";
/// Contact force arrow (Arrows3D) beside the contact, with its value as label.
pub const CONTACT_FORCE: &str = "world/contact/force";
/// Leader line (LineStrips3D) from the force arrow's start to the contact point.
pub const CONTACT_LEADER: &str = "world/contact/leader";
/// Frame of the cylinder chambers: its z axis is the cylinder axis.
pub const CHAMBERS: &str = "world/chambers";
/// Chamber A cylinder, coloured by p_a.
pub const CHAMBER_A: &str = "world/chambers/a";
/// Chamber B cylinder, coloured by p_b.
pub const CHAMBER_B: &str = "world/chambers/b";
/// Piston rod (Cylinders3D along its z, static) from the piston to the flange; its pose over time.
pub const ROD: &str = "world/rod";
/// Scene events (TextLog).
pub const EVENTS: &str = "events";

/// Entity path of a URDF link: `world/links/<name>`.
pub fn link(name: &str) -> String {
    format!("{LINKS}/{name}")
}

/// Which timeline the per-step samples go on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clock {
    /// `sim_time`: a duration timeline; `t_s` is seconds since the simulation start.
    Sim,
    /// `wall_time`: a timestamp timeline for real-rig runs; `t_s` is seconds since the Unix epoch
    /// (see [`crate::recorder::wall_clock_s`]).
    Wall,
}

impl Clock {
    /// Name of the Rerun timeline for this clock.
    pub fn timeline(self) -> &'static str {
        match self {
            Clock::Sim => SIM_TIME,
            Clock::Wall => WALL_TIME,
        }
    }
}
