//! Checkpoint loading errors name the file and the tensor.

use std::collections::HashMap;
use std::path::Path;

use crate::common::fixture;
use candle_core::{Device, Tensor};
use grasp_model::networks::{MobileNetV2, MobileNetV2Config};
use grasp_model::weights;

fn config(width_mult: f64, num_classes: usize) -> MobileNetV2Config {
    MobileNetV2Config {
        width_mult,
        num_classes,
        dropout: 0.2,
    }
}

/// Builds the model from `path` and returns the error message.
fn load_error(path: &Path, cfg: &MobileNetV2Config) -> String {
    let result =
        weights::var_builder(path, &Device::Cpu).and_then(|vb| Ok(MobileNetV2::new(vb, cfg)?));
    format!("{:#}", result.expect_err("loading should fail"))
}

fn fixture_tensors() -> HashMap<String, Tensor> {
    candle_core::safetensors::load(fixture("mnv2_w010.safetensors"), &Device::Cpu).unwrap()
}

#[test]
fn missing_file_is_named() {
    let path = Path::new("/nonexistent/mobilenet_v2-b0353104.pth");
    let msg = load_error(path, &config(1.0, 1000));
    assert!(
        msg.contains("mobilenet_v2-b0353104.pth") && msg.contains("does not exist"),
        "{msg}"
    );
}

#[test]
fn unknown_extension_is_rejected() {
    let msg = load_error(Path::new("weights.bin"), &config(1.0, 1000));
    assert!(
        msg.contains("weights.bin") && msg.contains(".safetensors"),
        "{msg}"
    );
}

#[test]
fn wrong_format_is_named() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["garbage.pth", "garbage.safetensors"] {
        let path = dir.path().join(name);
        std::fs::write(&path, b"this is not a checkpoint").unwrap();
        let msg = load_error(&path, &config(0.1, 5));
        assert!(msg.contains(name), "{msg}");
    }
}

#[test]
fn missing_tensor_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut tensors = fixture_tensors();
    tensors.remove("features.4.conv.1.0.weight");
    let path = dir.path().join("partial.safetensors");
    candle_core::safetensors::save(&tensors, &path).unwrap();
    let msg = load_error(&path, &config(0.1, 5));
    assert!(msg.contains("partial.safetensors"), "{msg}");
    assert!(
        msg.contains("missing tensor `features.4.conv.1.0.weight`"),
        "{msg}"
    );
}

#[test]
fn misshaped_tensor_is_named() {
    // 5-class weights into a 1000-class model
    let msg = load_error(&fixture("mnv2_w010.pth"), &config(0.1, 1000));
    assert!(msg.contains("mnv2_w010.pth"), "{msg}");
    assert!(
        msg.contains("`classifier.1.weight` has shape [5, 1280]"),
        "{msg}"
    );
    // width 0.1 weights into a width 1.0 model
    let msg = load_error(&fixture("mnv2_w010.safetensors"), &config(1.0, 5));
    assert!(
        msg.contains("`features.0.0.weight` has shape [8, 3, 3, 3]"),
        "{msg}"
    );
}

#[test]
fn both_formats_hold_the_same_tensors() {
    let pth = weights::load_tensors(&fixture("mnv2_w010.pth"), &Device::Cpu).unwrap();
    let st = fixture_tensors();
    for (name, t) in &st {
        if name.ends_with("num_batches_tracked") {
            continue;
        }
        let p = pth
            .get(name)
            .unwrap_or_else(|| panic!("{name} missing from .pth"));
        let d = (p - t).unwrap().abs().unwrap().sum_all().unwrap();
        assert_eq!(d.to_scalar::<f32>().unwrap(), 0.0, "{name}");
    }
}

#[test]
fn legacy_pth_format_loads() {
    // torchvision's mobilenet_v2-b0353104.pth predates PyTorch's zip format.
    let legacy = weights::load_tensors(&fixture("mnv2_w010_legacy.pth"), &Device::Cpu).unwrap();
    let st = fixture_tensors();
    // the file's five tensors less the batch-norm step counter, which is skipped
    assert_eq!(legacy.len(), 4);
    assert!(!legacy.contains_key("features.0.1.num_batches_tracked"));
    for (name, t) in &legacy {
        assert_eq!(t.dims(), st[name].dims(), "{name}");
        let a = t
            .flatten_all()
            .unwrap()
            .to_dtype(candle_core::DType::F64)
            .unwrap();
        let b = st[name]
            .flatten_all()
            .unwrap()
            .to_dtype(candle_core::DType::F64)
            .unwrap();
        let d = (a - b).unwrap().abs().unwrap().sum_all().unwrap();
        assert_eq!(d.to_scalar::<f64>().unwrap(), 0.0, "{name}");
    }
    // an incomplete checkpoint still gives a clear missing-tensor error
    let msg = load_error(&fixture("mnv2_w010_legacy.pth"), &config(0.1, 5));
    assert!(
        msg.contains("mnv2_w010_legacy.pth") && msg.contains("missing tensor"),
        "{msg}"
    );
}
