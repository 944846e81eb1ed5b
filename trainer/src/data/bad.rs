//! Bad-data policy: unreadable images and missing labels are reported with
//! their path; the run either skips them or stops.

use crate::error::DataError;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// What to do with an unreadable image or a sequence without labels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum, Default)]
#[serde(rename_all = "snake_case")]
pub enum OnBadData {
    /// Report it, leave it out and go on.
    #[default]
    Skip,
    /// Stop the run with an error naming the file.
    Fail,
}

/// One reported problem.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Problem {
    pub path: PathBuf,
    pub reason: String,
}

/// Collects problems under a policy. Shared by the reader, the feature cache
/// and the image loader, so one run reports every problem in one place.
#[derive(Debug, Default)]
pub struct BadData {
    pub policy: OnBadData,
    problems: Mutex<Vec<Problem>>,
}

impl BadData {
    pub fn new(policy: OnBadData) -> Self {
        BadData {
            policy,
            problems: Mutex::new(Vec::new()),
        }
    }

    /// Records a problem; under `fail` returns it as an error.
    pub fn report(&self, path: &Path, reason: impl Into<String>) -> Result<(), DataError> {
        let problem = Problem {
            path: path.to_path_buf(),
            reason: reason.into(),
        };
        match self.policy {
            OnBadData::Fail => Err(DataError::Bad {
                path: problem.path,
                reason: problem.reason,
            }),
            OnBadData::Skip => {
                tracing::warn!("skipping {}: {}", problem.path.display(), problem.reason);
                self.problems.lock().expect("problem list").push(problem);
                Ok(())
            }
        }
    }

    pub fn problems(&self) -> Vec<Problem> {
        self.problems.lock().expect("problem list").clone()
    }
}
