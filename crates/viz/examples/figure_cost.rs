//! What a scene's figures cost to draw, apart from the simulation: runs the scene once, then draws its
//! figures N times into a temporary directory and prints the time per round (min / median / max).
//!
//!     cargo run --release -p pneuflex-viz --example figure_cost -- scenes/paper-fig7-wood-to-iron.toml 20
//!
//! A benchmark, not a test: nothing is asserted. The figures are drawn as `pneuflex run` draws them (in
//! parallel on the rayon pool), so with `RAYON_NUM_THREADS=1` the time is their CPU cost.

use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(path), rounds) = (args.get(1), args.get(2).map_or(Ok(20), |n| n.parse())?) else {
        return Err("usage: figure_cost SCENE.toml [ROUNDS]".into());
    };
    let scene = pneuflex_scene::Scene::load(std::path::Path::new(path))?;
    let results = pneuflex_scene::run_scene(&scene, &mut |_| {})?;
    let dir = std::env::temp_dir().join(format!("pneuflex-figure-cost-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mut ms = Vec::with_capacity(rounds);
    let mut files = 0;
    for _ in 0..rounds {
        let t0 = Instant::now();
        files =
            pneuflex_viz::write_figures(&dir, &scene, &results, pneuflex_viz::Format::Png)?.len();
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    let bytes: u64 = std::fs::read_dir(&dir)?
        .map(|e| e.unwrap().metadata().unwrap().len())
        .sum();
    println!("{bytes} bytes of figures");
    std::fs::remove_dir_all(&dir)?;
    ms.sort_by(f64::total_cmp);
    println!(
        "{}: {files} figures, {rounds} rounds, {:.2} / {:.2} / {:.2} ms per round (min / median / max), {} rayon threads",
        scene.name,
        ms[0],
        ms[ms.len() / 2],
        ms[ms.len() - 1],
        rayon::current_num_threads()
    );
    Ok(())
}
