//! `pneuflex seal --data DIR` (or `--test FILE[=P]...`) and `pneuflex leak --log FILE...`: friction laws fitted to a seal's bench
//! tests and leaks fitted to closed-chamber pressure decays (docs/identification.md, "Real data"). The
//! fitting is `pneuflex_identify::seal` and `pneuflex_identify::leak`; this prints it.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::bail;
use pneuflex_identify::leak::{LeakFit, LeakOptions, RankStep, fit_leak, rank, read_decay_logs};
use pneuflex_identify::seal::{
    LawFit, MIN_GAUGE_PA, SealOptions, SealReport, Sensors, find_seal_tests, fit_seal,
    read_seal_list, seal_file_name,
};

/// Where a seal's tests are: a folder of `<seal>_<P>bar.csv`, or `--test FILE[=P]` each.
pub enum SealSource {
    /// `--data DIR [--seal NAME]`.
    Folder { dir: PathBuf, seal: Option<String> },
    /// `--test FILE[=P]`, as typed.
    List(Vec<String>),
}

/// The pressure sensor's range of `--max-pressure-bar`, refused when no sensor's.
fn sensors(max_pressure_bar: f64) -> anyhow::Result<Sensors> {
    if !(max_pressure_bar.is_finite() && max_pressure_bar > 0.0 && max_pressure_bar <= 1000.0) {
        bail!(
            "--max-pressure-bar {max_pressure_bar}: the sensor's full scale in bar gauge must be in (0, 1000]"
        );
    }
    Ok(Sensors {
        max_gauge_pa: max_pressure_bar * 1e5,
        ..Sensors::default()
    })
}

/// `--test FILE[=P]`: the file and its held pressure, Pa gauge (None: from the file's name or readings).
fn test_arg(arg: &str, s: &Sensors) -> anyhow::Result<(PathBuf, Option<f64>)> {
    let Some((file, p)) = arg.rsplit_once('=') else {
        let path = PathBuf::from(arg);
        let named = path
            .file_name()
            .and_then(|n| seal_file_name(&n.to_string_lossy()).map(|(_, p)| p));
        return Ok((path, named));
    };
    let bar: f64 = p
        .trim()
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
        .ok_or_else(|| {
            anyhow::anyhow!(
                "--test {arg}: `{p}` is not a pressure in bar gauge (FILE=P, e.g. circle.csv=3)"
            )
        })?;
    if !(MIN_GAUGE_PA / 1e5..=s.max_gauge_pa / 1e5).contains(&bar) {
        bail!(
            "--test {arg}: {} bar gauge is outside the sensor's range [{}, {}] bar (--max-pressure-bar)",
            p.trim(),
            MIN_GAUGE_PA / 1e5,
            s.max_gauge_pa / 1e5
        );
    }
    if file.is_empty() {
        bail!("--test {arg}: no file before the '='");
    }
    Ok((PathBuf::from(file), Some(bar * 1e5)))
}

/// The friction laws of a seal's tests: a table, or JSON.
pub fn seal(
    source: &SealSource,
    o: &SealOptions,
    max_pressure_bar: f64,
    json: bool,
) -> anyhow::Result<()> {
    o.check()?;
    let s = sensors(max_pressure_bar)?;
    let list: Vec<(PathBuf, Option<f64>)> = match source {
        SealSource::Folder { dir, seal } => find_seal_tests(dir, seal.as_deref())?
            .into_iter()
            .map(|(f, p)| (f, Some(p)))
            .collect(),
        SealSource::List(args) => args
            .iter()
            .map(|a| test_arg(a, &s))
            .collect::<anyhow::Result<_>>()?,
    };
    let tests = read_seal_list(&list, &s)?;
    let r = fit_seal(&tests, o)?;
    if json {
        outln!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        outln!("{}", seal_text(&r)?);
    }
    Ok(())
}

fn law_line(name: &str, f: &LawFit) -> String {
    let offsets = match f.offsets {
        pneuflex_identify::seal::Offsets::None => "no offset",
        pneuflex_identify::seal::Offsets::Common => "one offset",
        pneuflex_identify::seal::Offsets::PerTest => "an offset per test",
    };
    format!(
        "| {name}, {offsets} | {:.4} | {:.4} | {:.4} | {:.4} |",
        f.coulomb_n,
        f.coulomb_pressure_n_per_pa * 1e5,
        f.rms_cell_means_n,
        f.rms_samples_n
    )
}

fn seal_text(r: &SealReport) -> anyhow::Result<String> {
    let mut s = String::new();
    writeln!(
        s,
        "seal friction f = F - p A (A = {:.6e} m^2), {} moving samples\n",
        r.area_m2, r.moving_samples
    )?;
    writeln!(
        s,
        "| test | dir | n | mean f [N] | std [N] | mean p [bar g] | mean v [mm/s] | drift [N/min] |"
    )?;
    writeln!(s, "|---|---|---|---|---|---|---|---|")?;
    for c in &r.cells {
        writeln!(
            s,
            "| {} | {:+} | {} | {:.4} | {:.4} | {:.4} | {:.2} | {:+.3} |",
            c.file,
            c.direction,
            c.samples,
            c.mean_friction_n,
            c.std_friction_n,
            c.mean_gauge_pa / 1e5,
            c.mean_velocity_m_per_s * 1e3,
            c.drift_n_per_s * 60.0
        )?;
    }
    let rest: Vec<String> = r
        .rest_minus_midline_n
        .iter()
        .map(|v| format!("{v:+.2}"))
        .collect();
    writeln!(
        s,
        "\nrest reading (first row, before any motion) minus the midline of the two directions, per test [N]: {}",
        rest.join(", ")
    )?;
    writeln!(
        s,
        "\nlaws f = s (F_c0 + k_p p) + offset, s the direction, p gauge (fitted on the cell means)\n"
    )?;
    writeln!(
        s,
        "| law | F_c0 [N] | k_p [N/bar] | RMS cell means [N] | RMS samples [N] |"
    )?;
    writeln!(s, "|---|---|---|---|---|")?;
    writeln!(s, "{}", law_line("constant Coulomb", &r.constant_no_offset))?;
    writeln!(s, "{}", law_line("pressure term", &r.pressure_no_offset))?;
    writeln!(s, "{}", law_line("constant Coulomb", &r.constant))?;
    writeln!(s, "{}", law_line("pressure term", &r.pressure))?;
    writeln!(
        s,
        "\nthe pressure term buys {:.1} % of the RMS on the cell means, {:.1} % on the samples (with an offset per test)",
        100.0 * r.pressure_term_rms_reduction,
        100.0 * r.pressure_term_rms_reduction_samples
    )?;
    writeln!(
        s,
        "\nresiduals of the pressure law / the constant law, per test and direction [N]: mean | RMS of the samples\n"
    )?;
    writeln!(s, "| p [bar] | dir | pressure law | constant law |")?;
    writeln!(s, "|---|---|---|---|")?;
    for (a, b) in r.pressure.residuals.iter().zip(&r.constant.residuals) {
        writeln!(
            s,
            "| {:.0} | {:+} | {:+.3} \\| {:.3} | {:+.3} \\| {:.3} |",
            a.nominal_pa / 1e5,
            a.direction,
            a.mean_residual_n,
            a.rms_samples_n,
            b.mean_residual_n,
            b.rms_samples_n
        )?;
    }
    let d = &r.direction;
    writeln!(
        s,
        "\nper direction, each test's zero its rest reading: f - r_i = F_c+ + k_p p (+), -(F_c- + k_p p) (-)\n"
    )?;
    writeln!(
        s,
        "| law | F_c+ [N] | F_c- [N] | k_p [N/bar] | RMS cell means [N] |"
    )?;
    writeln!(s, "|---|---|---|---|---|")?;
    writeln!(
        s,
        "| symmetric | {:.4} | {:.4} | {:.4} | {:.4} |",
        d.symmetric[0],
        d.symmetric[0],
        d.symmetric[1] * 1e5,
        d.rms_cell_means_symmetric_n
    )?;
    writeln!(
        s,
        "| per direction | {:.4} | {:.4} | {:.4} | {:.4} |",
        d.coulomb_positive_n,
        d.coulomb_negative_n,
        d.coulomb_pressure_n_per_pa * 1e5,
        d.rms_cell_means_n
    )?;
    let per_test: Vec<String> = d
        .asymmetry_per_test_n
        .iter()
        .map(|a| format!("{a:+.2}"))
        .collect();
    writeln!(
        s,
        "asymmetry F_c+ - F_c- = {:+.3} N +- {:.3} N (standard error over {} tests: {}); {}",
        d.asymmetry_n,
        d.asymmetry_standard_error_n,
        per_test.len(),
        per_test.join(", "),
        if d.shown {
            format!(
                "shown (|mean| > {:.3} standard errors, Student's t at 95 %): the sheet gets both directions",
                d.t_quantile
            )
        } else {
            format!(
                "not shown (|mean| <= {:.3} standard errors, Student's t at 95 %): the sheet stays symmetric",
                d.t_quantile
            )
        }
    )?;
    let p = &r.pressure;
    if d.shown {
        writeln!(
            s,
            "\nfitted law: f = {:.4} N (+) / -{:.4} N (-) + s {:.4e} N/Pa |p_a - p_b| (sheet: coulomb_n = {:.4}, coulomb_negative_n = {:.4}, coulomb_pressure_n_per_pa = {:.4e})",
            d.coulomb_positive_n,
            d.coulomb_negative_n,
            d.coulomb_pressure_n_per_pa,
            d.coulomb_positive_n,
            d.coulomb_negative_n,
            d.coulomb_pressure_n_per_pa,
        )?;
    } else {
        writeln!(
            s,
            "\nfitted law: f = s ({:.4} N + {:.4e} N/Pa |p_a - p_b|) (sheet: coulomb_n = {:.4}, coulomb_pressure_n_per_pa = {:.4e}); Coulomb {:.2} N at 1 bar, {:.2} N at 7 bar",
            p.coulomb_n,
            p.coulomb_pressure_n_per_pa,
            p.coulomb_n,
            p.coulomb_pressure_n_per_pa,
            p.coulomb_at(1e5),
            p.coulomb_at(7e5)
        )?;
    }
    write!(
        s,
        "adequate: {} - {}",
        r.adequacy.adequate, r.adequacy.verdict
    )?;
    Ok(s)
}

/// The leaks of the decay logs, tightest first: a table, or JSON.
pub fn leak(
    logs: &[PathBuf],
    o: &LeakOptions,
    max_pressure_bar: f64,
    json: bool,
) -> anyhow::Result<()> {
    o.check()?;
    let s = sensors(max_pressure_bar)?;
    let mut fits = Vec::new();
    for l in read_decay_logs(logs, &s)? {
        fits.push(fit_leak(&l, o)?);
    }
    let steps = rank(&mut fits);
    if json {
        let v = serde_json::json!({ "chambers": fits, "ranking": steps });
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        outln!("{}", leak_text(&fits, &steps)?);
    }
    Ok(())
}

fn leak_text(fits: &[LeakFit], steps: &[RankStep]) -> anyhow::Result<String> {
    let mut s = String::new();
    writeln!(
        s,
        "ISO 6358 leak, isothermal: p' = -k p phi(p_atm / p), p = p0 exp(-k t) while choked (p_atm / p <= b), \
         C/V = k / (rho0 R sqrt(T T0)), tightest first\n"
    )?;
    writeln!(
        s,
        "| chamber | rows | span [s] | p0 [bar abs] | k [1/s] | C/V [1/(s Pa)] | RMS [Pa] | noise [Pa] | k first / second half [1/s] | t10 [s] | adequate |"
    )?;
    writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|")?;
    for f in fits {
        writeln!(
            s,
            "| {} | {} | {:.1} | {:.5} | {:.6e} | {:.6e} | {:.0} | {:.0} | {:.3e} / {:.3e} | {:.0} | {} |",
            f.chamber,
            f.rows,
            f.span_s,
            f.decay.p0_pa / 1e5,
            f.decay.rate_per_s,
            f.conductance_per_volume,
            f.decay.rms_pa,
            f.noise_pa,
            f.halves[0].rate_per_s,
            f.halves[1].rate_per_s,
            f.t10_s,
            f.adequate
        )?;
    }
    writeln!(s, "\nfitted:")?;
    for f in fits {
        write!(
            s,
            "  {}: {}, {} (b = {} assumed)",
            f.chamber,
            f.fitted.shown(),
            f.regime.words(),
            f.critical_pressure_ratio
        )?;
        if let (Some(c), Some(u)) = (f.choked, f.subsonic) {
            write!(s, ": choked {}, subsonic {}", c.shown(), u.shown())?;
        }
        if let Some(out) = f.left_out {
            write!(
                s,
                "; left out {} (the chamber reads atmosphere)",
                out.shown()
            )?;
        }
        writeln!(s)?;
    }
    let names: Vec<&str> = fits.iter().map(|f| f.chamber.as_str()).collect();
    writeln!(s, "\nranking, tightest to leakiest: {}", names.join(" < "))?;
    for r in steps {
        writeln!(
            s,
            "  {} < {}: C/V x {:.3}, {}",
            r.tighter,
            r.leakier,
            r.ratio,
            if r.settled {
                "settled (the rates of the whole logs and of their halves do not overlap)"
            } else {
                "not settled (the rates of the whole logs and of their halves overlap)"
            }
        )?;
    }
    for f in fits {
        write!(s, "\n{}: {}", f.chamber, f.verdict)?;
    }
    Ok(s)
}
