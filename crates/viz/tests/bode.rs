//! The Bode plot of `pneuflex tf <scene> --loop --bode`: drawn from the loop analyses of a scene, as PNG or
//! SVG by the file's extension, one line per distinct loop, with the margins in the legend.

use std::path::Path;

fn scene(name: &str) -> pneuflex_scene::Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    pneuflex_scene::Scene::load(&path).unwrap()
}

#[test]
fn the_bode_plot_of_the_linear_scene_is_written() {
    let s = scene("paper-fig3-linear.toml");
    let a = pneuflex_scene::analysis::loop_margins::analyse(&s, 0, 6.0).unwrap();
    assert!(a.margins.iter().all(|m| m.bode.len() > 100));
    let out = std::env::temp_dir().join(format!("pneuflex-bode-{}.png", std::process::id()));
    pneuflex_viz::write_bode(&out, &s, &[a]).unwrap();
    let png = std::fs::read(&out).unwrap();
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 10_000,
        "{} bytes",
        png.len()
    );
    let _ = std::fs::remove_file(&out);
    // Nothing to draw is an error, not an empty picture.
    assert!(pneuflex_viz::write_bode(&out, &s, &[]).is_err());
}

#[test]
fn runs_with_the_same_loop_share_a_line_and_the_margins_are_in_the_legend() {
    // paper-fig3's impedance and adaptive runs have the same inner loop: two stiffnesses, two lines.
    let s = scene("paper-fig3.toml");
    let analyses: Vec<_> = [0, 1]
        .map(|i| pneuflex_scene::analysis::loop_margins::analyse(&s, i, 6.0).unwrap())
        .into();
    let out = std::env::temp_dir().join(format!("pneuflex-bode-{}.svg", std::process::id()));
    pneuflex_viz::write_bode(&out, &s, &analyses).unwrap();
    let svg = std::fs::read_to_string(&out).unwrap();
    let _ = std::fs::remove_file(&out);
    assert!(svg.starts_with("<svg"), "{}", &svg[..80.min(svg.len())]);
    assert!(svg.contains("paper-fig3: "), "the title names the scene");
    for k_e in [700, 1400] {
        let label = format!("impedance, adaptive (kp 10 /m), k_e {k_e} N/m");
        // In the legend of both panels, once each.
        assert_eq!(svg.matches(&label).count(), 2, "{label}");
    }
    let m = &analyses[0].margins[0];
    let gm = format!(
        "GM {:.1} dB at {:.2} Hz",
        m.gain_margin_db.unwrap(),
        m.phase_crossover_hz.unwrap()
    );
    let pm = format!(
        "PM {:.1} deg at {:.2} Hz",
        m.phase_margin_deg.unwrap(),
        m.crossover_hz.unwrap()
    );
    assert!(svg.contains(&gm) && svg.contains(&pm), "{gm}, {pm}");
}
