//! Other people's logs (`identify --log-format`): a data-logger export with `;` separators, decimal commas,
//! a thousands mark, a preamble, time in ms, position in mm, pressures in bar gauge, the command in percent
//! and the force in kN with the opposite sign reads as the same SI log as pneuflex's own trace; a bad format
//! or a log that does not match it is refused with the file, the line and the key or column.

use std::path::Path;

use pneuflex_identify::log::{Log, LogLimits, parse_log, parse_log_formatted};
use pneuflex_identify::log_format::LogFormat;

const ATM: f64 = 101_325.0;

/// Row k of the test signal, SI: t, u, x, p_a, p_b (absolute), f_e.
fn row(k: usize) -> [f64; 6] {
    let t = 0.5 + 0.001 * k as f64;
    [
        t,
        (0.37 * k as f64).sin(),
        0.012 + 0.0004 * k as f64,
        ATM + 1.5e5 + 2.1e3 * k as f64,
        ATM + 2.0e5 - 1.3e3 * k as f64,
        12.5 + 0.75 * k as f64,
    ]
}

const ROWS: usize = 40;

fn own_trace() -> String {
    let mut s = String::from("# pneuflex trace\nt,u,x,p_a,p_b,f_e,fault\n");
    for k in 0..ROWS {
        let r = row(k);
        s += &format!(
            "{:?},{:?},{:?},{:?},{:?},{:?},\n",
            r[0], r[1], r[2], r[3], r[4], r[5]
        );
    }
    s + "# end: complete\n"
}

/// `v` with `decimals` digits, a decimal comma and '.' between thousands.
fn german(v: f64, decimals: usize) -> String {
    let s = format!("{:.*}", decimals, v.abs());
    let (int, frac) = s.split_once('.').unwrap_or((&s, ""));
    let mut grouped = String::new();
    for (i, ch) in int.chars().enumerate() {
        if i > 0 && (int.len() - i) % 3 == 0 {
            grouped.push('.');
        }
        grouped.push(ch);
    }
    let sign = if v < 0.0 { "-" } else { "" };
    if frac.is_empty() {
        format!("{sign}{grouped}")
    } else {
        format!("{sign}{grouped},{frac}")
    }
}

fn logger_export() -> String {
    let mut s = String::from(
        "Messung vom 03.12.2026\nPrüfstand 2\nAbtastung 1 kHz\nZeit;Ventil;Weg;pA;pB;Kraft;Temp\n",
    );
    for k in 0..ROWS {
        let r = row(k);
        s += &format!(
            "{};{};{};{};{};{};21,5\n",
            german(r[0] * 1e3, 3),
            german(r[1] * 100.0, 9),
            german(r[2] * 1e3, 6),
            german((r[3] - ATM) / 1e5, 6),
            german((r[4] - ATM) / 1e5, 6),
            german(-r[5] / 1e3, 9),
        );
    }
    s
}

const FORMAT: &str = r#"separator = ";"
decimal = ","
thousands = "."
skip_lines = 3
[columns]
t = { name = "Zeit", unit = "ms" }
u = { name = "Ventil", unit = "percent" }
x = { name = "Weg", unit = "mm" }
p_a = { name = "pA", unit = "bar", gauge = true }
p_b = { name = "pB", unit = "bar", gauge = true }
f_e = { name = "Kraft", unit = "kN", scale = -1.0 }
"#;

fn format(text: &str) -> Result<LogFormat, String> {
    LogFormat::parse(Path::new("formats/logger.toml"), text).map_err(|e| e.to_string())
}

fn columns(l: &Log) -> [&[f64]; 6] {
    [&l.t, &l.u, &l.x, &l.p_a, &l.p_b, &l.f_e]
}

#[test]
fn a_logger_export_reads_as_the_same_si_log_as_the_own_trace() {
    let own = parse_log(Path::new("trace.csv"), &own_trace(), String::new()).unwrap();
    let f = format(FORMAT).unwrap();
    let theirs = parse_log_formatted(
        Path::new("export.csv"),
        &logger_export(),
        String::new(),
        &LogLimits::default(),
        &f,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(theirs.len(), ROWS);
    // The export rounds to its printed digits: 1e-6 of a ms, mm and bar, 1e-9 of a kN.
    let tol = [1e-9, 1e-10, 1e-9, 1e-1, 1e-1, 1e-6];
    for (c, ((a, b), tol)) in columns(&own)
        .iter()
        .zip(columns(&theirs))
        .zip(tol)
        .enumerate()
    {
        for (k, (x, y)) in a.iter().zip(b).enumerate() {
            assert!((x - y).abs() <= tol, "column {c}, row {k}: {x} vs {y}");
        }
    }
    // A foreign log has no end marker to miss.
    assert_eq!(theirs.note, None);
    assert!(own.note.is_none());
}

#[test]
fn whitespace_separated_columns_in_any_order_are_read() {
    let fmt = r#"separator = "whitespace"
[columns]
f_e = { name = "F", unit = "N" }
t = { name = "time", unit = "s" }
u = { name = "cmd", unit = "1" }
x = { name = "pos", unit = "m" }
p_a = { name = "PA", unit = "kPa" }
p_b = { name = "PB", unit = "psi" }
"#;
    let mut text = String::from("time   F  cmd pos  PB    PA\n");
    for k in 0..ROWS {
        let r = row(k);
        text += &format!(
            "{:?}\t{:?}  {:?} {:?}   {:?} {:?}\n",
            r[0],
            r[5],
            r[1],
            r[2],
            r[4] / 6_894.757_293_168,
            r[3] / 1e3
        );
    }
    let l = parse_log_formatted(
        Path::new("w.txt"),
        &text,
        String::new(),
        &LogLimits::default(),
        &format(fmt).unwrap(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let want = row(7);
    let got = [l.t[7], l.u[7], l.x[7], l.p_a[7], l.p_b[7], l.f_e[7]];
    for (w, g) in want.iter().zip(got) {
        assert!(
            (w - g).abs() <= 1e-9 * w.abs().max(1.0),
            "{want:?} vs {got:?}"
        );
    }
}

/// The error of a bad format, checked to name the file, a line and `key`.
fn refused(text: &str, key: &str) -> String {
    let e = format(text).expect_err("the format is refused");
    assert!(e.starts_with("formats/logger.toml:"), "no file: {e}");
    assert!(
        e.split(':')
            .nth(1)
            .is_some_and(|l| l.parse::<usize>().is_ok()),
        "no line: {e}"
    );
    assert!(e.contains(key), "{key} not named: {e}");
    e
}

#[test]
fn a_bad_format_is_refused_with_its_file_line_and_key() {
    let e = refused(
        &FORMAT.replace("unit = \"ms\"", "unit = \"min\""),
        "columns.t.unit",
    );
    assert!(e.contains("\"ms\""), "the units it takes are listed: {e}");
    refused(&FORMAT.replace("skip_lines", "skip_rows"), "skip_rows");
    refused(
        &FORMAT.replace("decimal = \",\"", "decimal = \";\""),
        "decimal",
    );
    refused(
        &format!("{FORMAT}temp = {{ name = \"Temp\", unit = \"K\" }}\n"),
        "columns.temp",
    );
    refused(
        &FORMAT.replace(
            "f_e = { name = \"Kraft\", unit = \"kN\", scale = -1.0 }\n",
            "",
        ),
        "f_e",
    );
    refused(
        &FORMAT.replace(
            "name = \"Weg\", unit = \"mm\"",
            "name = \"Weg\", unit = \"mm\", gauge = true",
        ),
        "columns.x.gauge",
    );
    refused(
        &FORMAT.replace("scale = -1.0", "scale = 0.0"),
        "columns.f_e.scale",
    );
    refused(
        &FORMAT.replace("name = \"pB\"", "name = \"pA\""),
        "columns.p_b.name",
    );
    refused(
        &FORMAT.replace("thousands = \".\"", "thousands = \",\""),
        "thousands",
    );
}

#[test]
fn a_log_that_does_not_match_its_format_names_the_line_and_the_column() {
    let f = format(FORMAT).unwrap();
    let read = |text: &str| {
        parse_log_formatted(
            Path::new("export.csv"),
            text,
            String::new(),
            &LogLimits::default(),
            &f,
        )
        .expect_err("refused")
        .to_string()
    };
    // The preamble one line longer than the format says: the header is not where it looks.
    let e = read(&format!("one more line\n{}", logger_export()));
    assert!(
        e.starts_with("export.csv:4:") && e.contains("columns.t.name"),
        "{e}"
    );
    // A field that is not a number in the file's marks.
    let export = logger_export();
    let line = export.lines().nth(10).unwrap().to_string();
    let mut fields: Vec<&str> = line.split(';').collect();
    fields[2] = "1,2,3";
    let e = read(&export.replace(&line, &fields.join(";")));
    assert!(e.starts_with("export.csv:11:") && e.contains("`x`"), "{e}");
    // A gauge pressure below a vacuum is not a reading.
    let line = logger_export().lines().nth(6).unwrap().to_string();
    let fields: Vec<&str> = line.split(';').collect();
    let vacuum = line.replacen(fields[3], "-2,0", 1);
    let e = read(&logger_export().replace(&line, &vacuum));
    assert!(e.starts_with("export.csv:7:") && e.contains("p_a"), "{e}");
}
