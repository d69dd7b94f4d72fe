//! Every shipped scene (`scenes/*.toml`) recorded through [`SceneRecorder`] to `.rrd` files, read back
//! with Rerun's decoder: the file is complete, every tick of the force signals is there, multibody scenes
//! carry their links (the flange among them), pneumatic plants their chambers, and the ideal loop (no
//! actuator) is drawn without chambers; every file carries its layout made active (not only a default).

use std::path::{Path, PathBuf};

use pneuflex_rerun::{SceneRecorder, Sink, paths, sink_for_run};
use pneuflex_scene::{PlantSpec, Scene, run_scene_observed};

mod common;
use common::{read_back, temp_dir};

fn shipped_scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // Scenes with [[actuators]] have their own recorder (CI checks cross-slide's .rrd in scripts/test).
        .filter(|p| {
            !pneuflex_scene::mechanism::MechanismScene::is_mechanism(
                &std::fs::read_to_string(p).unwrap(),
            )
        })
        .collect();
    v.sort();
    assert!(v.len() >= 5, "scenes in {}: {v:?}", dir.display());
    v
}

#[test]
fn every_shipped_scene_records_to_a_readable_rrd() {
    let dir = temp_dir("scenes");
    let dir = dir.path().to_path_buf();
    for path in shipped_scenes() {
        let scene = Scene::load(&path).unwrap();
        let stem = path.file_stem().unwrap().to_str().unwrap();
        let sink = Sink::Save(dir.join(format!("{stem}.rrd")));
        let mut rec = SceneRecorder::new(sink.clone(), &scene).unwrap();
        let results = run_scene_observed(&scene, &mut |_| {}, &mut rec)
            .unwrap_or_else(|e| panic!("{stem}: {e}"));
        assert!(rec.steps() > 0, "{stem}");
        rec.finish()
            .unwrap_or_else(|e| panic!("{stem}: recording failed: {e}"));

        let multibody = matches!(scene.plant, PlantSpec::Multibody(_));
        let pwm = pneuflex_scene::build_plant(&scene)
            .unwrap()
            .actuator_geometry()
            .and_then(|g| g.pwm_period_s)
            .is_some();
        // Plants without chambers (the ideal loop, the linear model of eqs. (16)/(17)) log no pressures.
        let ideal = matches!(
            scene.plant,
            PlantSpec::Ideal { .. } | PlantSpec::Linear { .. }
        );
        for r in &results {
            let Sink::Save(file) = sink_for_run(&sink, &r.name, results.len()) else {
                unreachable!()
            };
            let what = format!("{stem}/{}: {}", r.name, file.display());
            let back = read_back(&file);
            assert!(back.has_footer, "{what}: no footer (unfinished file)");
            assert!(
                back.has_active_blueprint(),
                "{what}: no active blueprint (activations {:?}, blueprints {:?})",
                back.activations,
                back.blueprints
            );
            let n = r.trace.len();
            for p in [
                paths::F_REF,
                paths::F_E,
                paths::X,
                paths::X_R,
                paths::VALVE_U,
            ] {
                assert_eq!(
                    back.rows(&format!("/{p}"), paths::SIM_TIME),
                    n,
                    "{what}: {p}"
                );
            }
            let flange = format!("/{}", paths::link("flange"));
            assert!(
                back.static_entities.contains(&flange),
                "{what}: no flange shape"
            );
            assert_eq!(
                back.rows(&flange, paths::SIM_TIME),
                n,
                "{what}: flange poses"
            );
            if multibody {
                for link in ["cylinder", "wood_face", "iron_face"] {
                    let e = format!("/{}", paths::link(link));
                    assert!(back.static_entities.contains(&e), "{what}: no {e}");
                }
            }
            // The PWM-period means beside the chattering signals, one per tick.
            let avg = back.rows(&format!("/{}", paths::average(paths::F_E)), paths::SIM_TIME);
            assert_eq!(avg, if pwm { n } else { 0 }, "{what}: f_e mean");
            let chambers = back.rows(&format!("/{}", paths::CHAMBER_A), paths::SIM_TIME);
            if ideal {
                assert_eq!(chambers, 0, "{what}: the ideal loop has no chambers");
                assert_eq!(back.rows(&format!("/{}", paths::P_A), paths::SIM_TIME), 0);
            } else {
                assert_eq!(chambers, n, "{what}: chambers");
                assert_eq!(back.rows(&format!("/{}", paths::P_A), paths::SIM_TIME), n);
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_save_into_a_missing_directory_is_refused_before_the_run() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-ideal.toml");
    let scene = Scene::load(&path).unwrap();
    let dir = temp_dir("scene-missing");
    let dir = dir.path().to_path_buf();
    let missing = dir.join("no/such");
    let err = SceneRecorder::new(Sink::Save(missing.join("a.rrd")), &scene)
        .err()
        .expect("must fail");
    assert!(
        err.to_string().contains(&missing.display().to_string()),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
