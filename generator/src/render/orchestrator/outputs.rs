//! What a render writes besides the frames: the meshes handed to the
//! workers, each sequence's record of settings and cost, and the manifest
//! at the end.

use super::Job;
use crate::dataset::lock::{self, OutputLock};
use crate::dataset::DatasetDir;
use crate::render::error::{RenderError, Result};
use crate::render::protocol::MeshFiles;
use crate::render::source::{mesh_key, RenderSource};
use crate::render::Shard;
use grasp_schema::dataset::{RenderCost, PART_LABELS_KEY, RENDER_COST_KEY};
use grasp_support::atomic::write_atomic;
use std::collections::{BTreeMap, VecDeque};
use std::path::PathBuf;
use std::sync::Mutex;

/// Rewrites the manifest from the folders. A shard sharing its folder with
/// other running shards leaves it to the last one to finish (each appended
/// its lines as it went): the lock is released first, then the manifest is
/// rebuilt if no other run holds a lock.
pub(super) fn finish_manifest(dataset: &DatasetDir, shard: Shard, lock: OutputLock) -> Result<()> {
    if shard == Shard::ALL {
        dataset.rebuild_manifest()?;
        return Ok(());
    }
    drop(lock);
    let others = lock::holders(&dataset.work_dir());
    if others.is_empty() {
        dataset.rebuild_manifest()?;
    } else {
        tracing::info!(
            "{} other run(s) still write into {}: the last one rewrites the manifest",
            others.len(),
            dataset.root.display()
        );
    }
    Ok(())
}

/// The meshes handed to the workers, each written once as raw
/// little-endian arrays the workers pass to Blender without parsing. The
/// objects' models are written before any worker starts (a mesh the source
/// cannot give stops the run there); another member of a family of shapes
/// (`[randomize.profiles]`) when a sequence first places it.
pub(super) struct MeshStore {
    dir: PathBuf,
    written: Mutex<BTreeMap<String, MeshFiles>>,
}

impl MeshStore {
    pub(super) fn new(
        source: &dyn RenderSource,
        dataset: &DatasetDir,
        todo: &VecDeque<Job>,
    ) -> Result<MeshStore> {
        let dir = dataset.work_dir().join("meshes");
        std::fs::create_dir_all(&dir).map_err(|e| RenderError::io("cannot create", &dir, e))?;
        let store = MeshStore {
            dir,
            written: Mutex::default(),
        };
        for job in todo {
            store.files(source, &job.assigned.planned.key.object, 0)?;
        }
        Ok(store)
    }

    /// The files of member `member` of `object`'s family, written if new.
    pub(super) fn files(
        &self,
        source: &dyn RenderSource,
        object: &str,
        member: u32,
    ) -> Result<MeshFiles> {
        let key = mesh_key(object, member);
        let mut written = self.written.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(files) = written.get(&key) {
            return Ok(files.clone());
        }
        let mesh = source.mesh(object, member).map_err(|e| RenderError::Mesh {
            object: object.to_string(),
            source: Box::new(e),
        })?;
        let vertices: Vec<u8> = mesh
            .vertices
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let faces: Vec<u8> = mesh
            .faces
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let files = MeshFiles {
            vertices: self.dir.join(format!("{key}.vertices.f64")),
            faces: self.dir.join(format!("{key}.faces.u32")),
            key: key.clone(),
        };
        write_atomic(&files.vertices, &vertices)?;
        write_atomic(&files.faces, &faces)?;
        written.insert(key, files.clone());
        Ok(files)
    }
}

/// The render settings plus this sequence's cost and part names, as stored
/// in its record.
pub(super) fn record_settings(
    settings: &serde_json::Value,
    cost: &RenderCost,
    part_labels: &[String],
) -> serde_json::Value {
    let mut v = settings.clone();
    if let (Some(map), Ok(c)) = (v.as_object_mut(), serde_json::to_value(cost)) {
        map.insert(RENDER_COST_KEY.to_string(), c);
        if !part_labels.is_empty() {
            map.insert(PART_LABELS_KEY.to_string(), serde_json::json!(part_labels));
        }
    }
    v
}
