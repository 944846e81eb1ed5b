//! What a render writes besides the frames: the meshes handed to the
//! workers, each sequence's record of settings and cost, and the manifest
//! at the end.

use super::shared::Job;
use crate::dataset::lock::{self, OutputLock};
use crate::dataset::DatasetDir;
use crate::render::error::{RenderError, Result};
use crate::render::protocol::MeshFiles;
use crate::render::source::RenderSource;
use crate::render::Shard;
use grasp_schema::dataset::{RenderCost, PART_LABELS_KEY, RENDER_COST_KEY};
use grasp_support::atomic::write_atomic;
use std::collections::{BTreeMap, VecDeque};

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

/// Writes each needed object's mesh once, as raw little-endian arrays the
/// workers pass to Blender without parsing.
pub(super) fn write_meshes(
    source: &dyn RenderSource,
    dataset: &DatasetDir,
    todo: &VecDeque<Job>,
) -> Result<BTreeMap<String, MeshFiles>> {
    let dir = dataset.work_dir().join("meshes");
    std::fs::create_dir_all(&dir).map_err(|e| RenderError::io("cannot create", &dir, e))?;
    let mut out = BTreeMap::new();
    for job in todo {
        let object = &job.assigned.planned.key.object;
        if out.contains_key(object) {
            continue;
        }
        let mesh = source.mesh(object).map_err(|e| RenderError::Mesh {
            object: object.clone(),
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
            object: object.clone(),
            vertices: dir.join(format!("{object}.vertices.f64")),
            faces: dir.join(format!("{object}.faces.u32")),
        };
        write_atomic(&files.vertices, &vertices)?;
        write_atomic(&files.faces, &faces)?;
        out.insert(object.clone(), files);
    }
    Ok(out)
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
