//! The Bode plot of `pneuflex tf <scene> --loop --bode`: drawn from the loop analysis of the linear scene.

use std::path::Path;

#[test]
fn the_bode_plot_of_the_linear_scene_is_written() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-linear.toml");
    let scene = pneuflex_scene::Scene::load(&path).unwrap();
    let a = pneuflex_scene::analysis::loop_margins::analyse(&scene, 0, 6.0).unwrap();
    assert!(a.margins.iter().all(|m| m.bode.len() > 100));
    let out = std::env::temp_dir().join(format!("pneuflex-bode-{}.png", std::process::id()));
    pneuflex_viz::write_bode(&out, &[a]).unwrap();
    let png = std::fs::read(&out).unwrap();
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 10_000,
        "{} bytes",
        png.len()
    );
    let _ = std::fs::remove_file(&out);
    // Nothing to draw is an error, not an empty picture.
    assert!(pneuflex_viz::write_bode(&out, &[]).is_err());
}
