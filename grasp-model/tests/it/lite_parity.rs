//! The candle EfficientNet-Lite against a plain PyTorch one, on a committed
//! fixture made by scripts/make_lite_fixture.py: a reduced network (width
//! 0.15, depth 0.5, stem 16, head 64, 10 classes) with random weights and
//! batch-norm statistics from real activations, some running variances
//! below TensorFlow's epsilon of 1e-3, saved in the legacy `.pth` format with
//! permuted TensorFlow-layout storages and shared, offset storages like the
//! pip-installed ImageNet files. Inputs of an odd (37x37, batch 2) and an
//! even, non-square (48x40, batch 1) size exercise SAME padding both ways.

use std::path::{Path, PathBuf};

use candle_core::{Device, Tensor};
use grasp_model::networks::{EfficientNetLite, EfficientNetLiteConfig};
use grasp_model::weights;

const TOL: f32 = 1e-4;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn config() -> EfficientNetLiteConfig {
    EfficientNetLiteConfig {
        width: 0.15,
        depth: 0.5,
        stem_channels: 16,
        head_channels: 64,
        num_classes: Some(10),
    }
}

/// Largest |a - b| / (1 + |b|) over all elements.
fn max_rel_diff(a: &Tensor, b: &Tensor) -> f32 {
    assert_eq!(a.dims(), b.dims());
    let a = a.flatten_all().unwrap().to_vec1::<f32>().unwrap();
    let b = b.flatten_all().unwrap().to_vec1::<f32>().unwrap();
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs() / (1.0 + y.abs()))
        .fold(0.0, f32::max)
}

#[test]
fn matches_pytorch_at_odd_and_even_sizes() {
    let vb = weights::var_builder(&fixture("lite_small_legacy.pth"), &Device::Cpu).unwrap();
    let model = EfficientNetLite::new(vb, &config()).unwrap();
    let io =
        candle_core::safetensors::load(fixture("lite_small_io.safetensors"), &Device::Cpu).unwrap();
    let mut worst = 0f32;
    for tag in ["odd", "even"] {
        let x = &io[&format!("input_{tag}")];
        let features = model.features(x).unwrap();
        let d = max_rel_diff(&features, &io[&format!("features_{tag}")]);
        assert!(d < TOL, "{tag}: features differ by {d}");
        let logits = model.forward(x).unwrap();
        let e = max_rel_diff(&logits, &io[&format!("logits_{tag}")]);
        assert!(e < TOL, "{tag}: logits differ by {e}");
        worst = worst.max(d).max(e);
        // the features are not degenerate (a constant would match nothing)
        let spread = features.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let distinct = spread.iter().filter(|v| **v > 1e-3).count();
        assert!(distinct > spread.len() / 2, "{tag}: mostly zero features");
    }
    println!("max relative difference from PyTorch: {worst:.2e}");
}

#[test]
fn the_batch_path_matches_single_images() {
    let vb = weights::var_builder(&fixture("lite_small_legacy.pth"), &Device::Cpu).unwrap();
    let model = EfficientNetLite::new(vb, &config()).unwrap();
    let io =
        candle_core::safetensors::load(fixture("lite_small_io.safetensors"), &Device::Cpu).unwrap();
    let x = &io["input_odd"];
    let batch = model.features(x).unwrap();
    for i in 0..2 {
        let one = model.features(&x.narrow(0, i, 1).unwrap()).unwrap();
        let d = max_rel_diff(&one, &batch.narrow(0, i, 1).unwrap());
        assert!(d < 1e-6, "image {i}: {d}");
    }
}
