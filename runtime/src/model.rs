//! The trained checkpoint (`grasp-model`) as a [`FrameClassifier`], on the
//! CPU.

use crate::classifier::{ClassifyError, FrameClassifier};
use grasp_model::checkpoint::Classifier;
use grasp_model::error::ModelError;
use grasp_model::input::{InputSpec, Lens};
use grasp_schema::taxonomy::Class;
use image::RgbImage;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Why a checkpoint cannot drive the hand.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    // The model's error is boxed to keep this `Err` small (it is large).
    /// Nothing there: train first, or fix the path.
    #[error("no checkpoint at {}", path.display())]
    Missing {
        path: PathBuf,
        #[source]
        source: Box<ModelError>,
    },
    /// Something there that cannot be used: re-create it.
    #[error("corrupt checkpoint {}", path.display())]
    Corrupt {
        path: PathBuf,
        #[source]
        source: Box<ModelError>,
    },
    #[error("cannot load checkpoint {}", path.display())]
    Load {
        path: PathBuf,
        #[source]
        source: Box<ModelError>,
    },
    #[error(
        "checkpoint {} has an {head} head; hannes-run classifies frame by frame and needs an FC \
         or trace head (train with --set head=fc)",
        path.display()
    )]
    NotFc { path: PathBuf, head: &'static str },
    #[error(
        "checkpoint {}: classes {classes:?} are not the runtime's {:?} in index order",
        path.display(),
        Class::names()
    )]
    Classes { path: PathBuf, classes: Vec<Class> },
}

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
/// Only FC and trace heads classify frames as they come, as the streaming
/// loop needs; an LSTM head would have to re-read the whole window for
/// every new frame, so it is refused with an explanation.
pub fn load(path: &Path) -> Result<Classifier, CheckpointError> {
    let classifier = Classifier::load(path, &candle_core::Device::Cpu).map_err(|e| {
        let path = path.to_path_buf();
        let source = Box::new(e);
        if source.is_missing() {
            CheckpointError::Missing { path, source }
        } else if source.is_corrupt() {
            CheckpointError::Corrupt { path, source }
        } else {
            CheckpointError::Load { path, source }
        }
    })?;
    check(&classifier, path)?;
    Ok(classifier)
}

fn check(c: &Classifier, path: &Path) -> Result<(), CheckpointError> {
    if !c.meta.head.kind.classifies_frames() {
        return Err(CheckpointError::NotFc {
            path: path.to_path_buf(),
            head: c.meta.head.kind.name(),
        });
    }
    if c.classes() != Class::ALL {
        return Err(CheckpointError::Classes {
            path: path.to_path_buf(),
            classes: c.classes().to_vec(),
        });
    }
    Ok(())
}

impl FrameClassifier for Classifier {
    fn classify(
        &mut self,
        frame: &RgbImage,
        time_s: f64,
    ) -> Result<[f32; Class::COUNT], ClassifyError> {
        Ok(self.predict_at(frame, time_s)?)
    }

    fn begin_approach(&mut self) {
        Classifier::begin_approach(self)
    }
}

#[cfg(test)]
mod text_tests {
    use super::*;

    #[test]
    fn the_lstm_refusal_hints_a_flag_that_exists() {
        // Issue 60, case 15: `--head fc` is no flag of grasp-train train.
        let e = CheckpointError::NotFc {
            path: PathBuf::from("runs/lstm/seed-0"),
            head: "lstm",
        };
        let text = e.to_string();
        assert!(text.contains("--set head=fc"), "{text}");
        assert!(!text.contains("--head fc"), "{text}");
    }
}
