//! What `--resume` finds in the output folder: the finished sequences it
//! keeps, the damaged ones it redoes, and the refusal to mix two renders
//! (other folders, other settings, another plan) in one dataset.

use super::shared::{Job, RenderSummary};
use crate::dataset::{Assigned, DatasetDir};
use crate::render::error::{RenderError, Result};
use crate::render::source::RenderSource;
use crate::render::RenderConfig;
use grasp_schema::SequencePlan;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// Fails when a finished folder holds another sequence than the one this
/// config plans there: the folder was rendered with other settings (more or
/// fewer sequences per pair, other objects, parts or conditions), which
/// number the folders differently. Keeping it would leave one sequence
/// twice and another missing; rendering over it would destroy it.
/// Fails too when a finished sequence was rendered with other `[render]`
/// settings that change pixels ([`crate::render::consistency`]), or when the first
/// finished sequence differs from a fresh plan (another resolution, seed or
/// planning setting; one plan, not all: planning every finished sequence
/// would slow each resume): resuming would mix two renders in one dataset.
pub(super) fn refuse_other_sequences(
    source: &dyn RenderSource,
    dataset: &DatasetDir,
    in_shard: &[Assigned],
    finished: &[bool],
    config: &RenderConfig,
) -> Result<()> {
    // One record at a time: a large dataset's records do not fit in memory.
    let mut other_key = Mismatches::default();
    let mut other_render = Mismatches::default();
    let mut sample: Option<(PathBuf, SequencePlan)> = None;
    for (a, _) in in_shard.iter().zip(finished).filter(|(_, done)| **done) {
        let path = dataset
            .root
            .join(&a.rel_dir)
            .join(grasp_schema::dataset::SEQUENCE_FILE);
        let Ok(record) = crate::dataset::writer::read_record(&path) else {
            continue;
        };
        if record.plan.key == a.planned.key && sample.is_none() {
            sample = Some((dataset.root.join(&a.rel_dir), record.plan.clone()));
        }
        if record.plan.key != a.planned.key {
            other_key.add(|| {
                format!(
                    "{} holds sequence {}, but this config plans {} there",
                    dataset.root.join(&a.rel_dir).display(),
                    record.plan.key.id(),
                    a.planned.key.id()
                )
            });
        }
        let changes = crate::render::consistency::changed_settings(config, &record.render);
        if !changes.is_empty() {
            other_render.add(|| {
                format!(
                    "{}: {}",
                    dataset.root.join(&a.rel_dir).display(),
                    crate::render::consistency::describe(&changes)
                )
            });
        }
    }
    if let Some(first) = other_key.first {
        return Err(RenderError::OtherSequences {
            first,
            more: other_key.count - 1,
        });
    }
    if let Some(first) = other_render.first {
        return Err(RenderError::OtherRender {
            first,
            more: other_render.count - 1,
        });
    }
    match sample {
        Some((dir, recorded)) => refuse_other_plan(source, &dir, &recorded),
        None => Ok(()),
    }
}

/// Fails when a finished sequence's plan is not what the config plans for
/// it now, naming `[plan.camera] resolution` when that is what changed.
fn refuse_other_plan(source: &dyn RenderSource, dir: &Path, recorded: &SequencePlan) -> Result<()> {
    let id = recorded.key.id();
    // The same JSON round trip as the record, so floats compare exactly.
    let fresh = source
        .plan(&recorded.key)
        .map_err(RenderError::from)
        .and_then(|p| {
            let json = |source| RenderError::Json {
                what: "the JSON round trip of a plan",
                source,
            };
            let text = serde_json::to_string(&p).map_err(json)?;
            serde_json::from_str::<SequencePlan>(&text).map_err(json)
        });
    let fresh = fresh.map_err(|e| RenderError::Replan {
        id: id.clone(),
        source: Box::new(e),
    })?;
    if &fresh == recorded {
        return Ok(());
    }
    let size = |p: &SequencePlan| format!("{}x{}", p.intrinsics.width, p.intrinsics.height);
    let what = match size(&fresh) == size(recorded) {
        true => format!(
            "its sequence.json differs from a fresh plan of {id} (another seed, code, or \
             [dataset], [plan], [appearance] or [randomize] setting)"
        ),
        false => format!(
            "[plan.camera] resolution: rendered at {}, the config plans {}",
            size(recorded),
            size(&fresh)
        ),
    };
    Err(RenderError::OtherPlan {
        dir: dir.to_path_buf(),
        what,
    })
}

/// The first of a kind of mismatch, described, and how many there are.
#[derive(Default)]
struct Mismatches {
    first: Option<String>,
    count: usize,
}

impl Mismatches {
    fn add(&mut self, describe: impl FnOnce() -> String) {
        if self.first.is_none() {
            self.first = Some(describe());
        }
        self.count += 1;
    }
}

/// The jobs of this run: the unfinished sequences of the shard, and the
/// finished-looking ones whose files are missing or damaged (re-rendered,
/// with a message).
pub(super) fn unfinished_jobs(
    dataset: &DatasetDir,
    in_shard: &[Assigned],
    finished: &[bool],
    summary: &mut RenderSummary,
) -> VecDeque<Job> {
    let mut todo = VecDeque::new();
    for (a, done) in in_shard.iter().zip(finished) {
        if *done {
            match dataset.check_finished(&a.rel_dir) {
                Ok(()) => {
                    summary.skipped += 1;
                    continue;
                }
                Err(reason) => {
                    tracing::warn!("re-rendering {}: {reason}", a.rel_dir);
                    summary.redone += 1;
                }
            }
        }
        todo.push_back(Job {
            assigned: a.clone(),
            attempt: 0,
        });
    }
    todo
}
