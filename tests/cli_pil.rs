//! `pneuflex rig pil` without what it needs: a clear error, a non-zero exit, and no output directory.
//! (The runs themselves are checked on the emulated board by scripts/ci_firmware.)

use std::path::Path;
use std::process::Command;

fn pil(args: &[&str], qemu: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["rig", "pil", "--scene", "scenes/paper-fig3.toml"])
        .args(args)
        .env("PNEUFLEX_QEMU", qemu)
        .output()
        .expect("the CLI runs")
}

#[test]
fn without_qemu_it_says_how_to_install_it_and_writes_nothing() {
    let out = tempdir("pil-no-qemu");
    let o = pil(
        &["--out", out.to_str().unwrap()],
        "/nonexistent/qemu-system-arm",
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("apt-get install qemu-system-arm"), "{err}");
    assert!(!out.exists(), "no output directory");
}

#[test]
fn without_the_firmware_image_it_says_how_to_build_it_and_writes_nothing() {
    let out = tempdir("pil-no-elf");
    // Any existing file passes the QEMU lookup; the missing image is found before QEMU starts.
    let o = pil(
        &[
            "--firmware",
            "/nonexistent/pneuflex-firmware",
            "--out",
            out.to_str().unwrap(),
        ],
        env!("CARGO_BIN_EXE_pneuflex"),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("/nonexistent/pneuflex-firmware"), "{err}");
    assert!(err.contains("cargo build --release"), "{err}");
    assert!(!out.exists(), "no output directory");
}

#[test]
fn an_unknown_run_is_named_with_the_runs_there_are() {
    let o = pil(&["--run", "pid"], "/nonexistent/qemu-system-arm");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("\"pid\"") && err.contains("impedance"),
        "{err}"
    );
}

/// A fresh path under the target directory (not created).
fn tempdir(name: &str) -> std::path::PathBuf {
    let p = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&p);
    p
}
