//! The sheet set, scene and rig file a design becomes, as commented TOML: each file says what it holds,
//! which values were given and which assumed (the report lists the assumptions with the options that
//! replace them).

use crate::design::{Design, ValveKind, fmt_mm};
use crate::gains::Gains;

/// The files of a rig directory, relative to it.
pub const CYLINDER: &str = "pneumatics/cylinder.toml";
pub const VALVE: &str = "pneumatics/valve.toml";
pub const SUPPLY: &str = "pneumatics/supply.toml";
pub const PRESSURE_SENSOR: &str = "pneumatics/pressure-sensor.toml";
pub const POSITION_SENSOR: &str = "pneumatics/position-sensor.toml";
pub const ACTUATOR: &str = "pneumatics/actuator.toml";
pub const SCENE: &str = "scene.toml";
pub const RIG: &str = "rig.toml";
pub const REPORT: &str = "README.md";

fn given_or_assumed(d: &Design, key: &str) -> &'static str {
    if d.assumptions.iter().any(|a| a.key == key) {
        "ASSUMED"
    } else {
        "given"
    }
}

/// Every file but the report: (relative path, text).
pub fn files(d: &Design, gains: &Gains) -> Vec<(&'static str, String)> {
    vec![
        (CYLINDER, cylinder(d)),
        (VALVE, valve(d)),
        (SUPPLY, supply(d)),
        (PRESSURE_SENSOR, pressure_sensor(d)),
        (POSITION_SENSOR, position_sensor(d)),
        (ACTUATOR, actuator(d)),
        (SCENE, scene(d, gains)),
        (RIG, rig(d)),
    ]
}

fn cylinder(d: &Design) -> String {
    format!(
        "# {name}: double-acting cylinder, written by `pneuflex new rig` from datasheet values.\n\
         # bore {bore} mm ({gb}), rod {rod} mm ({gr}), stroke {stroke} mm ({gs}); dead volumes {gd}.\n\
         [cylinder]\n\
         name = \"{bore} mm bore x {stroke} mm stroke ({std} size nearest: {sb} mm, port {port})\"\n\
         bore_m = {bore_m}\n\
         rod_m = {rod_m}\n\
         stroke_m = {stroke_m}\n\
         dead_volume_a_m3 = {va:e}   # chamber A (cap side) at x = 0\n\
         dead_volume_b_m3 = {vb:e}   # chamber B (rod side) at x = stroke\n",
        name = d.name,
        bore = fmt_mm(d.bore_m),
        rod = fmt_mm(d.rod_m),
        stroke = fmt_mm(d.stroke_m),
        gb = given_or_assumed(d, "--bore"),
        gr = given_or_assumed(d, "--rod"),
        gs = given_or_assumed(d, "--stroke"),
        gd = given_or_assumed(d, "--dead-volume"),
        std = d.size.standard,
        sb = d.size.bore_mm,
        port = d.size.port,
        bore_m = d.bore_m,
        rod_m = d.rod_m,
        stroke_m = d.stroke_m,
        va = d.dead_volume_a_m3,
        vb = d.dead_volume_b_m3,
    )
}

fn valve(d: &Design) -> String {
    let head = format!(
        "# {name}: the valve, written by `pneuflex new rig`. Flow: {src}\n\
         # ({flow}; ISO 6358 conversions in docs/your-rig.md).\n\
         [valve]\n",
        name = d.name,
        src = d.flow_source,
        flow = given_or_assumed(d, "--valve-flow"),
    );
    match d.valve {
        ValveKind::Pwm => format!(
            "{head}name = \"5/2 on/off solenoid valve under PWM\"\n\
             kind = \"on_off_pwm\"\n\
             sonic_conductance_m3_per_s_pa = {c:e}\n\
             critical_pressure_ratio = {b}\n\
             pwm_frequency_hz = {f}          # {gf}\n\
             switching_delay_s = {t}        # {gt}\n",
            c = d.sonic_conductance_m3_per_s_pa,
            b = d.critical_pressure_ratio,
            f = d.pwm_frequency_hz,
            gf = given_or_assumed(d, "--pwm-frequency"),
            t = d.switching_delay_s,
            gt = given_or_assumed(d, "--switching-delay"),
        ),
        ValveKind::Proportional => format!(
            "{head}name = \"proportional 5/3 servo valve\"\n\
             kind = \"proportional\"\n\
             sonic_conductance_m3_per_s_pa = {c:e}\n\
             critical_pressure_ratio = {b}\n\
             response_time_s = {t}          # {gt}\n\
             underlap = 0.02                # ASSUMED: 2 % centre leakage\n",
            c = d.sonic_conductance_m3_per_s_pa,
            b = d.critical_pressure_ratio,
            t = d.response_time_s,
            gt = given_or_assumed(d, "--response-time"),
        ),
    }
}

fn supply(d: &Design) -> String {
    format!(
        "# {name}: compressed-air supply ({g}), {gauge:.2} MPa gauge; absolute pressures below.\n\
         [supply]\n\
         pressure_abs_pa = {ps}\n\
         temperature_k = 293.15\n\n\
         [atmosphere]\n\
         pressure_abs_pa = {pa}\n\
         temperature_k = 293.15\n",
        name = d.name,
        g = given_or_assumed(d, "--supply"),
        gauge = (d.supply_abs_pa - d.atmosphere_pa) * 1e-6,
        ps = d.supply_abs_pa,
        pa = d.atmosphere_pa,
    )
}

fn pressure_sensor(d: &Design) -> String {
    format!(
        "# {name}: differential pressure transmitter p_a - p_b ({g}), 4-20 mA (12 mA = zero difference).\n\
         [sensor]\n\
         name = \"differential transmitter ±{r:.1} MPa\"\n\
         quantity = \"differential_pressure\"\n\
         range_min_si = {lo}   # Pa\n\
         range_max_si = {hi}   # Pa\n\
         signal = \"current_ma\"\n\
         signal_min = 4.0\n\
         signal_max = 20.0\n",
        name = d.name,
        g = given_or_assumed(d, "--pressure-range"),
        r = d.pressure_range_pa * 1e-6,
        lo = -d.pressure_range_pa,
        hi = d.pressure_range_pa,
    )
}

fn position_sensor(d: &Design) -> String {
    format!(
        "# {name}: linear position sensor on the flange ({g}), 0-10 V.\n\
         [sensor]\n\
         name = \"position sensor 0-{r} mm\"\n\
         quantity = \"position\"\n\
         range_min_si = 0.0     # m\n\
         range_max_si = {hi}   # m\n\
         signal = \"voltage_v\"\n\
         signal_min = 0.0\n\
         signal_max = 10.0\n",
        name = d.name,
        g = given_or_assumed(d, "--position-range"),
        r = fmt_mm(d.position_range_m),
        hi = d.position_range_m,
    )
}

fn actuator(d: &Design) -> String {
    format!(
        "# {name}: the actuator, written by `pneuflex new rig` (README.md beside lists every assumption).\n\
         # Component paths are relative to this file.\n\
         name = \"{name}\"\n\n\
         [components]\n\
         cylinder = \"cylinder.toml\"\n\
         valve = \"valve.toml\"\n\
         supply = \"supply.toml\"\n\
         pressure_sensor = \"pressure-sensor.toml\"\n\
         position_sensor = \"position-sensor.toml\"\n\n\
         [gas]\n\
         gas_constant_j_per_kg_k = 287.05\n\
         polytropic_exponent = 1.4        # adiabatic chambers (eq. 5)\n\n\
         [mechanics]\n\
         moving_mass_kg = {m}             # {gm}\n\
         viscous_n_s_per_m = {v}          # ASSUMED: the paper's, scaled by piston area\n\
         friction = \"smooth\"\n\
         coulomb_n = {fc}                 # {gc}\n\
         smooth_velocity_m_per_s = 0.002\n\
         # Incline of the axis below the horizontal, pointing downhill towards the environment ({ga}).\n\
         alpha_deg = {a}\n\
         gravity_m_per_s2 = 9.80665\n",
        name = d.name,
        m = d.moving_mass_kg,
        gm = given_or_assumed(d, "--mass"),
        v = d.viscous_n_s_per_m,
        fc = d.coulomb_n,
        gc = given_or_assumed(d, "--friction"),
        ga = given_or_assumed(d, "--incline"),
        a = d.incline_deg,
    )
}

/// The adaptive law's units: the paper's gains read on this rig's force and position scale (its contact
/// force against the paper's 10 N, its compression against the paper's 10 N / 700 N/m).
pub fn adaptive_units(d: &Design) -> (f64, f64) {
    let force_unit = d.force_n / 10.0;
    let position_unit = (d.force_n / d.stiffness_n_per_m) / (10.0 / 700.0);
    (force_unit, position_unit)
}

fn scene(d: &Design, g: &Gains) -> String {
    let (fu, pu) = adaptive_units(d);
    let p_max = 1.0 / (2.0 * d.stiffness_after_n_per_m);
    let d_max = 0.2 / d.pwm_frequency_hz;
    let inner = format!(
        "inner = {{ kp_per_m = {kp}, ki_per_m_s = {ki}, kd_s_per_m = 0.0 }}",
        kp = g.kp_per_m,
        ki = g.ki_per_m_s
    );
    let impedance = format!(
        "impedance = {{ m_d_kg = {}, b_d_ns_per_m = {}, k_d_n_per_m = 0.0 }}",
        g.m_d_kg, g.b_d_ns_per_m
    );
    let runs_note = g
        .note
        .lines()
        .map(|l| format!("# {l}\n"))
        .collect::<String>();
    format!(
        "# {name}: the paper's Fig. 3/4 experiment (Section III-E) on this rig, written by `pneuflex new rig`.\n\
         # A {f} N step for 3 s, then {f} + {s} sin(2π(t - 3)) N; k_e {k1} -> {k2} N/m at t = 6 s. The forces are the\n\
         # paper's ratios to this rig's force range, the impedance filter keeps the paper's frequency and damping on\n\
         # this environment (docs/your-rig.md). Schema: docs/scenes.md.\n\
         name = \"{name}\"\n\
         description = \"Impedance vs adaptive impedance control on {name}, stiffness {k1} -> {k2} N/m at 6 s\"\n\
         duration_s = 10.0\n\
         dt_s = 0.001\n\
         integrator = \"rk4\"\n\n\
         [plant]\n\
         kind = \"pneumatic\"\n\
         actuator = \"pneumatics/actuator.toml\"\n\
         substeps = {sub}             # RK4 steps per control tick: the fastest chamber pole resolved\n\n\
         [environment]\n\
         stiffness_n_per_m = {k1}\n\
         x_e_m = {xe}                 # surface at 40 % of the stroke\n\n\
         [reference]\n\
         x_d_m = {xe}\n\n\
         [[reference.force]]\n\
         kind = \"step\"\n\
         start_s = 0.0\n\
         value_n = {f}\n\n\
         [[reference.force]]\n\
         kind = \"sine\"\n\
         start_s = 3.0\n\
         bias_n = {f}\n\
         amplitude_n = {s}\n\
         frequency_hz = 1.0\n\
         phase_rad = 0.0\n\n\
         [[events]]\n\
         kind = \"stiffness\"\n\
         t_s = 6.0\n\
         stiffness_n_per_m = {k2}\n\n\
         {runs_note}\
         [[runs]]\n\
         name = \"impedance\"\n\
         controller = \"impedance\"\n\
         {impedance}\n\
         {inner}\n\n\
         [[runs]]\n\
         name = \"adaptive\"\n\
         controller = \"adaptive\"\n\
         {impedance}\n\
         {inner}\n\
         # The paper's adaptive gains (Section III-E) read on this rig's scale; p in [0, 1/(2 k_e,max)], d within a\n\
         # fifth of the PWM period (docs/control.md).\n\
         adaptive = {{ position_unit_m = {pu}, force_unit_n = {fu}, lambda_d_sign = \"from_edot\", sigma1_sign = \"leakage\", lambda_p = 1.0, lambda_d = 8.0, mu1 = 0.01, mu2 = 0.0001, mu3 = 0.01, sigma1 = 0.1, sigma2 = 0.1, sigma3 = 0.1, p_max_m_per_n = {pmax}, d_max_s = {dmax} }}\n\n\
         [[metrics]]\nname = \"step\"\nt0_s = 2.5\nt1_s = 3.0\nkind = \"step\"\n\n\
         [[metrics]]\nname = \"sine\"\nt0_s = 3.0\nt1_s = 6.0\nkind = \"sine\"\n\n\
         [[metrics]]\nname = \"stiffness_change\"\nt0_s = 6.0\nt1_s = 10.0\nkind = \"event\"\n\n\
         [[metrics]]\nname = \"sine_stiff\"\nt0_s = 8.0\nt1_s = 10.0\nkind = \"sine\"\n\n\
         # The paper's claims (Section III-E): adaptive impedance control against impedance control.\n\
         {claims}",
        name = d.name,
        f = d.force_n,
        s = d.sine_amplitude_n,
        k1 = d.stiffness_n_per_m,
        k2 = d.stiffness_after_n_per_m,
        sub = g.substeps,
        xe = d.surface_m,
        pu = crate::design::round2(pu),
        fu = crate::design::round2(fu),
        pmax = crate::design::round2(p_max),
        dmax = d_max,
        claims = CLAIMS,
    )
}

const CLAIMS: &str = "[[claims]]
statement = \"adaptive tracks the sine with less phase lag\"
window = \"sine\"
metric = \"phase_lag_deg\"
better = \"adaptive\"
than = \"impedance\"

[[claims]]
statement = \"adaptive tracks the sine with a lower RMS force error\"
window = \"sine\"
metric = \"rms_force_error_n\"
better = \"adaptive\"
than = \"impedance\"

[[claims]]
statement = \"after the stiffness change, adaptive recovers with less overshoot (% of the jump)\"
window = \"stiffness_change\"
metric = \"recovery_overshoot_pct\"
better = \"adaptive\"
than = \"impedance\"

[[claims]]
statement = \"after the stiffness change, adaptive settles faster\"
window = \"stiffness_change\"
metric = \"settling_time_s\"
better = \"adaptive\"
than = \"impedance\"

[[claims]]
statement = \"on the stiffer environment, adaptive tracks the sine with a lower RMS force error\"
window = \"sine_stiff\"
metric = \"rms_force_error_n\"
better = \"adaptive\"
than = \"impedance\"
";

fn rig(d: &Design) -> String {
    let gauge = d.supply_abs_pa - d.atmosphere_pa;
    // A 24-bit bridge ADC spanning twice the force range each way.
    let n_per_count = -crate::design::round2(2.0 * d.force_range_n() / 8_388_608.0);
    // The gauge transmitters of chamber B and the supply: 4-20 mA over the pressure range, across 150 Ω.
    let q = d.pressure_range_pa.max(gauge);
    let transmitter = format!(
        "sensor = \"gauge transmitter 0-{qr:.1} MPa\"\n\
         adc_bits = 12\n\
         adc_ref_v = 3.3\n\
         signal = \"current\"\n\
         shunt_ohm = 150.0\n\
         signal_min = 4.0\n\
         signal_max = 20.0\n\
         quantity_min = 0.0\n\
         quantity_max = {q}\n\n",
        qr = q * 1e-6,
    );
    format!(
        "# {name}: the rig file for rig run and rig emulate (docs/rig.md), written by new rig. From this folder:\n\
         #   `pneuflex rig emulate --rig rig.toml` emulates the rig (blocks: rig run connects from a second terminal);\n\
         #   `pneuflex rig run --rig rig.toml --scene scene.toml --lockstep-truth pneumatics/actuator.toml` runs the\n\
         #   scene's first run on it in lockstep, without a second terminal (out/rig/{name}/).\n\
         # Calibration: the position sensor's 0-10 V through a 10 V -> 3.2 V divider into a 12-bit\n\
         # 3.3 V ADC; 4-20 mA transmitters across 150 Ω shunts; a load cell on a 24-bit bridge ADC. Edit the\n\
         # [link] port and the calibration to your board.\n\
         name = \"{name}\"\n\n\
         [link]\n\
         port = \"/dev/ttyACM0\"\n\
         baud = 921600\n\
         handshake_timeout_ms = 500\n\n\
         [loop]\n\
         rate_hz = 1000.0\n\
         spin_us = 150\n\
         trace_flush_every = 100\n\
         post_fault_s = 0.2\n\
         velocity_cutoff_hz = 50.0\n\n\
         [calibration]\n\
         atmosphere_pa = {atm}\n\n\
         [calibration.position]\n\
         sensor = \"position sensor 0-{pr} mm\"\n\
         sheet = \"pneumatics/position-sensor.toml\"\n\
         adc_bits = 12\n\
         adc_ref_v = 3.3\n\
         divider_ratio = 3.125\n\n\
         [calibration.differential]\n\
         sensor = \"differential transmitter\"\n\
         sheet = \"pneumatics/pressure-sensor.toml\"\n\
         adc_bits = 12\n\
         adc_ref_v = 3.3\n\
         shunt_ohm = 150.0\n\n\
         [calibration.pressure_b]\n\
         {transmitter}\
         [calibration.supply]\n\
         {transmitter}\
         [calibration.load_cell]\n\
         sensor = \"load cell\"\n\
         n_per_count = {npc:e}\n\
         offset_counts = 0.0\n\n\
         [limits]\n\
         position_m = [-0.001, {xmax}]\n\
         force_n = [{fmin}, {fmax}]\n\
         pressure_pa = [60000.0, {pmax}]\n\
         supply_min_pa = {smin}\n\n\
         [watchdog]\n\
         timeout_ms = 20.0         # a desktop without real-time scheduling; 5 ms on a real-time host\n\
         stale_ms = 50.0\n\
         crc_errors_max = 5\n\
         crc_window_ms = 1000.0\n\
         board_watchdog_ms = 50\n\n\
         [valve]\n\
         model = \"{valve}\"\n\
         safe_state = \"vent\"\n\n\
         # The emulated rig (`pneuflex rig emulate --rig rig.toml`): this actuator pushing the scene's environment.\n\
         [emulator]\n\
         sample_rate_hz = 1000.0\n\
         plant_dt_s = 0.0001\n\
         actuator = \"pneumatics/actuator.toml\"\n\
         x0_m = {xe}                 # at the environment's surface, where the scene's simulation starts\n\
         adc_noise_counts = 1\n\
         seed = 7\n\
         supply_pa = {ps}\n\
         faults = []\n\n\
         [emulator.environment]\n\
         x_e_m = {xe}\n\
         k_e_n_per_m = {k1}\n\
         k_e_after_n_per_m = {k2}\n\
         change_at_s = 6.0\n",
        name = d.name,
        atm = d.atmosphere_pa,
        pr = fmt_mm(d.position_range_m),
        npc = n_per_count,
        xmax = d.stroke_m - 0.001,
        fmin = -crate::design::round2(0.5 * d.force_n),
        fmax = crate::design::round2(3.0 * d.force_n),
        pmax = (1.3 * d.supply_abs_pa).round(),
        smin = crate::design::round2(0.7 * gauge),
        valve = match d.valve {
            ValveKind::Pwm => "5/2 on/off solenoid valve",
            ValveKind::Proportional => "proportional 5/3 valve",
        },
        ps = d.supply_abs_pa,
        xe = d.surface_m,
        k1 = d.stiffness_n_per_m,
        k2 = d.stiffness_after_n_per_m,
    )
}
