//! Python bindings of pneuflex (the native module `pneuflex._native`, re-exported by the `pneuflex` package).
//!
//! What Python gets: the pneumatic actuator model of `pneuflex-pneumatics` (an actuator sheet, the 1-DOF
//! model, the axial force element that an external physics engine couples to, the transfer function of
//! eqs. (16)-(17)), the controllers of `pneuflex-control`, scene files, `run(scene)` through the scene
//! crate's runner with the traces as numpy arrays, `run_plant(scene, run, plant)`: the same loop driving a
//! plant written in Python (MuJoCo in crossval/), the metrics and summary.json of arbitrary traces, the
//! figures of `pneuflex-viz`, and a Rapier step-rate probe. SI units throughout, pressures absolute.

mod controller;
mod errors;
mod gym;
mod identify;
mod model;
mod plant;
mod scene;
mod shipped;
mod sweep;

use pyo3::prelude::*;

/// Native part of the `pneuflex` Python package.
#[pymodule]
mod _native {
    use pyo3::prelude::*;

    #[pymodule_export]
    use crate::model::{PyActuator, PyForceElement, PyOneDof};

    #[pymodule_export]
    use crate::controller::{PyController, PySetpoints};

    #[pymodule_export]
    use crate::plant::run_plant;

    #[pymodule_export]
    use crate::gym::PyForceControlBatch;

    #[pymodule_export]
    use crate::scene::{
        bench_rapier, bench_scene_ticks, initial_state, load_scene, loop_signals, run,
        run_mechanism, run_results, run_with_summary, summarize,
    };

    #[pymodule_export]
    use crate::sweep::{sweep_plan, sweep_rows, tune_evaluate, tune_run};

    #[pymodule_export]
    use crate::identify::identify_json;

    #[cfg(feature = "figures")]
    #[pymodule_export]
    use crate::scene::{run_to, write_figures};

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        m.add(
            "PneuflexError",
            m.py().get_type::<crate::errors::PneuflexError>(),
        )?;
        m.add("__version__", env!("CARGO_PKG_VERSION"))?;
        // The workspace these bindings were built in: where `pneuflex.mujoco_plugin_path()` looks for
        // the MuJoCo plugin built beside them (target/release, target/debug).
        m.add(
            "_workspace_dir",
            concat!(env!("CARGO_MANIFEST_DIR"), "/../.."),
        )?;
        Ok(())
    }
}
