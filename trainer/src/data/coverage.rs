//! Which classes a training split can teach. A split whose sequences all
//! grasp one way trains to "100 %" on data of that one pre-shape and means
//! nothing, so training refuses it unless told otherwise.
//!
//! The classes counted are the sequences' grasp pre-shapes. `no_grasp` is a
//! frame label, not a kind of sequence: every generated or real sequence
//! ends (or starts) with it, so it would make any one-pre-shape split look
//! like two classes. It is checked on its own: with no `no_grasp` frame at
//! all the classifier can never answer it, which only deserves a warning.

use super::Dataset;
use crate::error::DataError;
use grasp_schema::taxonomy::{Class, Preshape};
use std::collections::BTreeSet;

/// The pre-shapes with and without training sequences.
#[derive(Debug, Clone, PartialEq)]
pub struct Coverage {
    pub present: Vec<Preshape>,
    pub missing: Vec<Preshape>,
    /// Frames labelled `no_grasp`.
    pub no_grasp_frames: usize,
}

pub fn coverage(train: &Dataset) -> Coverage {
    let seen: BTreeSet<Preshape> = train.sequences.iter().map(|s| s.preshape).collect();
    let (present, missing) = Preshape::ALL.iter().partition(|p| seen.contains(p));
    Coverage {
        present,
        missing,
        no_grasp_frames: train
            .sequences
            .iter()
            .flat_map(|s| &s.labels)
            .filter(|c| **c == Class::NoGrasp)
            .count(),
    }
}

fn names(p: &[Preshape]) -> String {
    p.iter().map(|p| p.name()).collect::<Vec<_>>().join(", ")
}

/// Refuses a training split missing a pre-shape (unless `allow`, then a
/// loud warning), and warns when no frame is `no_grasp`.
pub fn check_training_classes(train: &Dataset, allow: bool) -> Result<Coverage, DataError> {
    let c = coverage(train);
    if !c.missing.is_empty() {
        let what = format!(
            "the training split ({} sequences of {}) has sequences of {} only: no training \
             sequence of {}. The classifier could never predict {}, and its accuracy on data \
             without them would say nothing",
            train.sequences.len(),
            train.root.display(),
            names(&c.present),
            names(&c.missing),
            if c.missing.len() == 1 { "it" } else { "them" }
        );
        if !allow {
            return Err(DataError::MissingClasses {
                missing: c.missing,
                reason: what,
            });
        }
        tracing::warn!("{what} (allow_missing_classes)");
    }
    if c.no_grasp_frames == 0 && !train.sequences.is_empty() {
        tracing::warn!(
            "no training frame is labelled no_grasp: the classifier will never answer no_grasp"
        );
    }
    Ok(c)
}
