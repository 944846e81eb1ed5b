//! Adaptation to a user's own camera without labels (`grasp-train adapt`):
//! the checkpoint reads the user's recorded approaches, takes on each the
//! decision `hannes-run`'s policy would (`grasp_policy`), and is refitted
//! from its own recipe with those approaches added to its training set, one
//! pseudo-label per approach. Only approaches the vote decided count (a
//! fallback or no command is not evidence); the recordings' own labels,
//! where they have any, are never read.
//!
//! The frames of an approach are labelled with its pre-shape, except its
//! final run of frames the checkpoint reads as `no_grasp` (the contact the
//! training set labels so too).

use crate::config::TrainConfig;
use crate::data::{BadData, Dataset, Sequence};
use crate::error::{EvalError, Result, TrainError};
use crate::eval::metrics::{frame_class, HandDecision};
use crate::features::FeatureCache;
use crate::train::{self, TrainOutcome};
use grasp_model::checkpoint::{Classifier, TrainMode};
use grasp_policy::{OutcomeKind, PolicyConfig};
use grasp_schema::taxonomy::{Class, Preshape};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What one adaptation needs besides the recordings.
#[derive(Debug, Clone)]
pub struct AdaptConfig {
    /// The checkpoint to adapt: its recipe (`train_config`) and data are
    /// refitted with the pseudo-labelled approaches added.
    pub checkpoint: PathBuf,
    /// The folder the adapted checkpoint is written to.
    pub out: PathBuf,
    /// The policy whose decision is each approach's pseudo-label.
    pub policy: PolicyConfig,
    /// Copies of each pseudo-labelled approach in the training set (each
    /// with its own views): the user's few approaches against the
    /// generator's many.
    pub copies: usize,
}

/// One recorded approach's pseudo-label.
#[derive(Debug, Clone, Serialize)]
pub struct PseudoLabel {
    pub id: String,
    /// The decision's pre-shape; None: nothing commanded.
    pub preshape: Option<Preshape>,
    pub how: OutcomeKind,
    /// Whether the approach trains the adapted model (decided by the vote).
    pub used: bool,
    /// Frames labelled with the pre-shape, and `no_grasp` at the end.
    pub preshape_frames: usize,
    pub no_grasp_frames: usize,
}

/// `OUT/adapt.json`: what the adapted checkpoint was refitted with.
#[derive(Debug, Clone, Serialize)]
pub struct AdaptRecord {
    pub source_checkpoint: PathBuf,
    pub recordings: PathBuf,
    pub policy: PolicyConfig,
    pub copies: usize,
    pub approaches: usize,
    pub used: usize,
    pub pseudo_labels: Vec<PseudoLabel>,
}

pub const RECORD_FILE: &str = "adapt.json";

pub struct AdaptOutcome {
    pub train: TrainOutcome,
    pub record: AdaptRecord,
}

/// Refits `cfg.checkpoint` with `recordings` pseudo-labelled by it.
pub fn adapt(cfg: &AdaptConfig, recordings: &Dataset, bad: &BadData) -> Result<AdaptOutcome> {
    cfg.policy
        .validate()
        .map_err(|e| crate::error::ConfigError::invalid("policy", e.to_string()))?;
    let clf = Classifier::load(&cfg.checkpoint, &candle_core::Device::Cpu)?;
    let mut recipe = recipe_of(&clf, &cfg.checkpoint)?;
    recipe.out = cfg.out.clone();
    let cache = FeatureCache::new(&recipe.cache_dir, recipe.feature_batch);
    let videos = crate::eval::predict::predict_dataset(&clf, recordings, &cache, bad)?;
    let mut pseudo = Vec::new();
    let mut labels = Vec::new();
    for (seq, video) in recordings.sequences.iter().zip(&videos) {
        let (label, sequence) = pseudo_label(seq, video, &cfg.policy);
        labels.push(label);
        pseudo.extend(sequence);
    }
    let used = pseudo.len();
    tracing::info!(
        "{used} of {} approaches decided by the vote: each labels its frames ({} copies)",
        videos.len(),
        cfg.copies
    );
    if used == 0 {
        let why = "no recorded approach was decided by the vote: nothing to adapt to";
        return Err(TrainError::Inconsistent(why));
    }
    let bad_train = BadData::new(recipe.on_bad_data);
    let mut splits = train::load_splits(&recipe, &bad_train)?;
    for copy in 0..cfg.copies.max(1) {
        splits
            .train
            .sequences
            .extend(pseudo.iter().cloned().map(|mut s| {
                s.id = format!("adapt/{copy}/{}", s.id);
                s
            }));
    }
    std::fs::create_dir_all(&cfg.out).map_err(|source| TrainError::Create {
        path: cfg.out.clone(),
        source,
    })?;
    let prep = train::prepare(&recipe, &splits, &bad_train, &candle_core::Device::Cpu)?;
    let outcome = train::train(&recipe, &prep, clf.meta.seed, &cfg.out)?;
    let record = AdaptRecord {
        source_checkpoint: cfg.checkpoint.clone(),
        recordings: recordings.root.clone(),
        policy: cfg.policy.clone(),
        copies: cfg.copies.max(1),
        approaches: videos.len(),
        used,
        pseudo_labels: labels,
    };
    grasp_support::atomic::write_atomic(
        &cfg.out.join(RECORD_FILE),
        serde_json::to_string_pretty(&record)?.as_bytes(),
    )?;
    Ok(AdaptOutcome {
        train: outcome,
        record,
    })
}

/// The recipe a frozen checkpoint was trained with.
fn recipe_of(clf: &Classifier, checkpoint: &Path) -> Result<TrainConfig> {
    if clf.meta.mode != TrainMode::FrozenPretrained {
        let why = "adaptation refits a head on cached features: a frozen-pretrained checkpoint";
        return Err(TrainError::Inconsistent(why));
    }
    let recipe: TrainConfig =
        serde_json::from_value(clf.meta.train_config.clone()).map_err(|source| {
            EvalError::TrainConfig {
                checkpoint: checkpoint.to_path_buf(),
                source,
            }
        })?;
    recipe.validate()?;
    Ok(recipe)
}

/// The approach's pseudo-label, and the sequence it trains with when the
/// vote decided it: every frame the approach's pre-shape but the final run
/// the checkpoint reads as `no_grasp`. The recording's own labels, part
/// and test world are dropped.
fn pseudo_label(
    seq: &Sequence,
    video: &crate::eval::metrics::VideoPrediction,
    policy: &PolicyConfig,
) -> (PseudoLabel, Option<Sequence>) {
    let hand = HandDecision::of(video, policy);
    let decided = matches!(hand.how, OutcomeKind::Majority | OutcomeKind::Early);
    let mut label = PseudoLabel {
        id: seq.id.clone(),
        preshape: hand.preshape,
        how: hand.how,
        used: false,
        preshape_frames: 0,
        no_grasp_frames: 0,
    };
    let Some(preshape) = hand.preshape.filter(|_| decided) else {
        return (label, None);
    };
    let tail = video
        .probs
        .iter()
        .rev()
        .take_while(|p| frame_class(p) == Class::NoGrasp.index())
        .count();
    // The time from which the checkpoint reads contact to the end.
    let contact_s = match tail {
        0 => f64::INFINITY,
        n => video.times_s[video.times_s.len() - n],
    };
    let mut s = seq.clone();
    s.preshape = preshape;
    s.part = None;
    s.test_world = None;
    s.labels = (0..s.frames.len())
        .map(|i| match s.time_s(i) >= contact_s - 1e-9 {
            true => Class::NoGrasp,
            false => Class::from(preshape),
        })
        .collect();
    label.no_grasp_frames = s.labels.iter().filter(|c| **c == Class::NoGrasp).count();
    label.preshape_frames = s.labels.len() - label.no_grasp_frames;
    label.used = true;
    (label, Some(s))
}
