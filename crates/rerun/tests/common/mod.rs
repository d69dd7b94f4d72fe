//! Shared by the integration tests: temp directories and a recording read back with Rerun's own decoder.
#![allow(dead_code)]

use std::collections::HashMap;
use std::io::BufReader;
use std::path::Path;

use re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};

/// Fresh empty directory under the system temp dir, unique per test, removed when the guard drops.
pub fn temp_dir(tag: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("pneuflex-rerun-{tag}-"))
        .tempdir()
        .unwrap()
}

/// What a decoded recording holds: rows per entity on a timeline, static entities, and whether
/// the file ended with Rerun's footer (written only when the file sink is closed).
pub struct Readback {
    /// Rows per (entity path, timeline name).
    pub rows_on: HashMap<(String, String), usize>,
    /// Entities with static data (shapes, series styles).
    pub static_entities: Vec<String>,
    /// Whether the file ends with Rerun's footer.
    pub has_footer: bool,
    /// Blueprint stores with data in the file.
    pub blueprints: Vec<rerun::StoreId>,
    /// Blueprint activation commands in file order: (blueprint, make_active, make_default, whether
    /// that blueprint's data came before the command).
    pub activations: Vec<(rerun::StoreId, bool, bool, bool)>,
    /// File size.
    pub bytes: u64,
}

impl Readback {
    /// Whether the file's layout is what a viewer shows first: a blueprint whose data is in the file,
    /// then the command that makes it active and the default.
    pub fn has_active_blueprint(&self) -> bool {
        self.activations
            .iter()
            .any(|(id, active, default, sent_before)| {
                *active && *default && *sent_before && self.blueprints.contains(id)
            })
    }

    /// Rows of `entity` (with its leading `/`) on `timeline`, 0 when absent.
    pub fn rows(&self, entity: &str, timeline: &str) -> usize {
        self.rows_on
            .get(&(entity.to_owned(), timeline.to_owned()))
            .copied()
            .unwrap_or(0)
    }
}

/// Decodes an .rrd file with Rerun's decoder (every message must decode).
pub fn read_back(path: &Path) -> Readback {
    let file = std::fs::File::open(path).unwrap();
    let bytes = file.metadata().unwrap().len();
    let mut it = DecoderApp::decode_eager(BufReader::new(file)).expect("a valid .rrd stream");
    let mut rows_on = HashMap::new();
    let mut static_entities = Vec::new();
    let mut blueprints = Vec::new();
    let mut activations = Vec::new();
    for msg in &mut it {
        let msg = msg.expect("every message decodes");
        let (store, arrow) = match msg {
            LogMsg::ArrowMsg(store, arrow) => (store, arrow),
            LogMsg::BlueprintActivationCommand(cmd) => {
                let sent_before = blueprints.contains(&cmd.blueprint_id);
                activations.push((
                    cmd.blueprint_id,
                    cmd.make_active,
                    cmd.make_default,
                    sent_before,
                ));
                continue;
            }
            LogMsg::SetStoreInfo(_) => continue,
        };
        if !store.is_recording() {
            if !blueprints.contains(&store) {
                blueprints.push(store);
            }
            continue; // blueprint store
        }
        let chunk = Chunk::from_arrow_msg(&arrow).unwrap();
        let entity = chunk.entity_path().to_string();
        if chunk.is_static() {
            static_entities.push(entity.clone());
        }
        for name in chunk.timelines().keys() {
            *rows_on
                .entry((entity.clone(), name.to_string()))
                .or_insert(0) += chunk.num_rows();
        }
    }
    let has_footer = !it.rrd_manifests().unwrap().is_empty();
    Readback {
        rows_on,
        static_entities,
        has_footer,
        blueprints,
        activations,
        bytes,
    }
}
