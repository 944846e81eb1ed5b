//! The trained checkpoint (`grasp-model`) as a [`FrameClassifier`], on the
//! CPU.

use crate::classifier::FrameClassifier;
use anyhow::Result;
use grasp_model::checkpoint::Classifier;
use grasp_model::heads::HeadKind;
use grasp_model::input::{InputSpec, Lens};
use grasp_schema::taxonomy::Class;
use image::RgbImage;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What every report of `run` and `replay` says about the model: the
/// checkpoint, its input record, and the lens its crop was cut through.
#[derive(Debug, Clone, Serialize)]
pub struct ModelRecord {
    pub checkpoint: PathBuf,
    pub input: InputSpec,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lens: Option<Lens>,
    /// Where the lens came from: `sequence.json`, or the command line's
    /// lens flags (which replace a recording's own).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lens_from: Option<&'static str>,
}

impl ModelRecord {
    /// `lens_flags`: whether the lens came from the command line.
    pub fn of(classifier: &Classifier, checkpoint: &Path, lens_flags: bool) -> ModelRecord {
        let lens = classifier.lens().copied();
        ModelRecord {
            checkpoint: checkpoint.to_path_buf(),
            input: classifier.input().clone(),
            lens,
            lens_from: lens.map(|_| if lens_flags { "flags" } else { "sequence.json" }),
        }
    }
}

/// Loads a checkpoint directory (or its `best.json`) for per-frame use.
///
/// Only FC heads classify frames independently, as the streaming loop
/// needs; an LSTM head would have to re-read the whole window for every new
/// frame, so it is refused with an explanation.
pub fn load(path: &Path) -> Result<Classifier> {
    let classifier = Classifier::load(path, &candle_core::Device::Cpu).map_err(|e| {
        let what = if e.is_missing() {
            "no checkpoint at"
        } else if e.is_corrupt() {
            "corrupt checkpoint"
        } else {
            "cannot load checkpoint"
        };
        anyhow::Error::new(e).context(format!("{what} {}", path.display()))
    })?;
    check(&classifier, path)?;
    Ok(classifier)
}

fn check(c: &Classifier, path: &Path) -> Result<()> {
    anyhow::ensure!(
        c.meta.head.kind == HeadKind::Fc,
        "checkpoint {} has an {} head; hannes-run classifies frame by frame and needs an FC head \
         (train with --head fc)",
        path.display(),
        c.meta.head.kind.name()
    );
    anyhow::ensure!(
        c.classes() == Class::ALL,
        "checkpoint {}: classes {:?} are not the runtime's {:?} in index order",
        path.display(),
        c.classes(),
        Class::names()
    );
    Ok(())
}

impl FrameClassifier for Classifier {
    fn classify(&mut self, frame: &RgbImage) -> Result<[f32; Class::COUNT]> {
        let mut out = self.predict(std::slice::from_ref(frame))?;
        anyhow::ensure!(
            out.len() == 1,
            "classifier returned {} outputs for one frame",
            out.len()
        );
        Ok(out.remove(0))
    }
}
