//! A sheet with effects beyond the paper (docs/pneumatics.md, issue 26): the 1-DOF plant runs it, the
//! multibody plant (whose force element has the paper's chambers only) refuses it at `plant.actuator`,
//! naming the effect.

use std::path::{Path, PathBuf};

use pneuflex_scene::schema::PlantSpec;
use pneuflex_scene::{LinearSpring, MultibodyPlant, OneDofPneumatic, Scene};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// The shipped sheets copied into `dir`, the cylinder given a piston leak; the actuator sheet's path.
fn leaky_sheets(dir: &Path) -> PathBuf {
    for e in std::fs::read_dir(repo("pneumatics")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
        }
    }
    let cyl = dir.join("smc-mqm16-cylinder.toml");
    let text = std::fs::read_to_string(&cyl).unwrap();
    std::fs::write(
        &cyl,
        format!("{text}\n[cylinder.leaks.piston]\nsonic_conductance_m3_per_s_pa = 1e-11\n"),
    )
    .unwrap();
    dir.join("paper-actuator.toml")
}

#[test]
fn multibody_refuses_a_sheet_with_effects_and_the_one_dof_plant_runs_it() {
    let g = tempfile::tempdir().unwrap();
    let sheet = leaky_sheets(g.path());
    let mut scene = Scene::load(&repo("scenes/paper-fig3-multibody.toml")).unwrap();
    let PlantSpec::Multibody(mb) = &mut scene.plant else {
        panic!("not a multibody scene")
    };
    mb.actuator = sheet.clone();
    let Err(err) = MultibodyPlant::from_scene(&scene) else {
        panic!("the multibody plant accepted a sheet with a leak")
    };
    let err = err.to_string();
    assert!(
        err.contains("plant.actuator") && err.contains("[cylinder.leaks.piston]"),
        "{err}"
    );
    let model = pneuflex_pneumatics::ActuatorSheet::load(&sheet)
        .unwrap()
        .model();
    assert!(!model.is_paper_model());
    let env = LinearSpring {
        stiffness_n_per_m: 700.0,
        x_e_m: 0.02,
    };
    let mut one = OneDofPneumatic::new(model, 0.02, env, 10);
    let (pa0, pb0) = (one.state().chambers.p_a, one.state().chambers.p_b);
    {
        use pneuflex_scene::Plant as _;
        // The valve at 50 % duty: both chambers alternately filled and vented; the leak joins them.
        one.actuate(
            pneuflex_control::ValveCommand { u: 0.0 },
            &pneuflex_control::Telemetry::default(),
        );
        for _ in 0..100 {
            one.advance(1e-3);
        }
        one.check_invariants().unwrap();
    }
    let c = one.state().chambers;
    assert!(c.p_a != pa0 && c.p_b != pb0, "{c:?}");
}
