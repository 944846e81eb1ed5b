//! `grasp-gen dataset merge OUT SHARD...`: joins shard outputs. Folder
//! numbers come from the full key order, so shards never collide; a folder
//! present in two inputs must hold the same record.

use super::error::{DatasetError, Result};
use super::lock;
use super::shard::Shard;
use super::writer::{read_record, sequence_dirs, visit_sequences, DatasetDir, WORK_DIR};
use grasp_schema::dataset::{head_sequence_dir, SEQUENCE_FILE};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

#[derive(Debug, Default)]
pub struct MergeSummary {
    pub copied: usize,
    pub already_present: usize,
}

pub fn merge(out: &Path, shards: &[PathBuf]) -> Result<MergeSummary> {
    let dataset = DatasetDir::create(out)?;
    let _lock = lock::acquire(&dataset.work_dir(), Shard::ALL, "merge", false)?;
    // Folder names only: records are read one at a time.
    let mut existing: BTreeSet<String> = sequence_dirs(out, false)?.into_iter().collect();
    let mut summary = MergeSummary::default();
    let mut damaged = Vec::new();
    for shard in shards {
        for holder in lock::holders(&shard.join(WORK_DIR)) {
            tracing::warn!(
                "{} is still locked ({}): only its finished sequences are merged",
                shard.display(),
                holder.describe()
            );
        }
        let source = DatasetDir {
            root: shard.clone(),
        };
        visit_sequences(shard, false, |rel, record| {
            let record = record?;
            if existing.contains(rel) {
                let present = read_record(&out.join(rel).join(SEQUENCE_FILE))?;
                if present.plan != record.plan {
                    return Err(DatasetError::Differs {
                        rel: rel.to_string(),
                        shard: shard.clone(),
                        out: out.to_path_buf(),
                    });
                }
                summary.already_present += 1;
                return Ok(());
            }
            if let Err(reason) = source.check_finished(rel) {
                damaged.push(reason);
                return Ok(());
            }
            // The head folder first: the wrist folder marks the sequence done.
            if record.has_head_camera() {
                let head = head_sequence_dir(rel).ok_or_else(|| DatasetError::NoHeadFolder {
                    rel: rel.to_string(),
                    reason: "head camera poses outside Wrist_d435".into(),
                })?;
                copy_sequence(&dataset, &shard.join(&head), &out.join(&head))?;
            }
            copy_sequence(&dataset, &shard.join(rel), &out.join(rel))?;
            existing.insert(rel.to_string());
            summary.copied += 1;
            Ok(())
        })
        .map_err(|e| DatasetError::Shard {
            shard: shard.clone(),
            source: Box::new(e),
        })?;
    }
    dataset.clean_partials(Shard::ALL)?;
    dataset.rebuild_manifest()?;
    if !damaged.is_empty() {
        return Err(DatasetError::Damaged { reasons: damaged });
    }
    Ok(summary)
}

/// Copies (hard-links when possible) a sequence folder through a temporary
/// folder and a rename, so an interrupted merge leaves no half sequence.
fn copy_sequence(dataset: &DatasetDir, from: &Path, to: &Path) -> Result<()> {
    let tmp = dataset.partial_dir(0, 0)?;
    let cannot_read = |e| DatasetError::io("cannot read", from, e);
    for entry in std::fs::read_dir(from).map_err(cannot_read)? {
        let src = entry.map_err(cannot_read)?.path();
        let dst = tmp.join(src.file_name().unwrap_or_default());
        if std::fs::hard_link(&src, &dst).is_err() {
            std::fs::copy(&src, &dst).map_err(|e| DatasetError::io("cannot copy", &src, e))?;
        }
    }
    if let Some(parent) = to.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| DatasetError::io("cannot create", parent, e))?;
    }
    if to.exists() {
        // A head folder left by an interrupted merge or run.
        std::fs::remove_dir_all(to).map_err(|e| DatasetError::io("cannot replace", to, e))?;
    }
    std::fs::rename(&tmp, to).map_err(|source| DatasetError::Move {
        from: tmp.clone(),
        to: to.to_path_buf(),
        source,
    })
}
