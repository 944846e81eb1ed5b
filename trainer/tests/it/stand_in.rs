//! The frozen-mode setup of the end-to-end trainer tests: a tiny generated
//! image set and a random MobileNetV2 (width 0.25, 32 px) standing in for
//! pretrained weights, its batch-norm statistics adapted to frames like
//! the set's.

use grasp_model::checkpoint::TrainMode;
use std::path::Path;
use trainer::config::TrainConfig;
use trainer::data::synthetic::{class_image, write_synthetic, Layout, SyntheticSpec};

/// Writes the set (`sequences_per_part` per part) and the stand-in
/// (calibrated on `calibration` generated frames) under `dir`; a config
/// that trains on them, 20 % of the sequences for validation.
pub fn frozen_setup(dir: &Path, sequences_per_part: usize, calibration: usize) -> TrainConfig {
    let mut spec = SyntheticSpec::small(Layout::Generated);
    spec.sequences_per_part = sequences_per_part;
    write_synthetic(&dir.join("data"), &spec).unwrap();
    let weights = dir.join("backbone.safetensors");
    let mut rng = trainer::rng::stream(9, "calibration");
    let frames: Vec<image::RgbImage> = grasp_schema::taxonomy::Class::ALL
        .iter()
        .cycle()
        .take(calibration)
        .map(|c| class_image(*c, 32, spec.noise, &mut rng))
        .collect();
    trainer::init::write_random_backbone(&weights, 0.25, 32, &frames, 1).unwrap();
    let mut cfg = TrainConfig {
        data: dir.join("data"),
        out: dir.join("run"),
        mode: TrainMode::FrozenPretrained,
        weights: Some(weights),
        width_mult: 0.25,
        input_size: 32,
        batch_size: Some(16),
        cache_dir: dir.join("cache"),
        ..Default::default()
    };
    cfg.split.val_fraction = 0.2;
    cfg
}
