//! A checkpoint that is not there is told apart from one that is there but
//! cannot be used, without reading the message.

use crate::common::fixture;
use candle_core::{DType, Device, Tensor};
use grasp_model::backbone::{Architecture, BackboneInfo};
use grasp_model::checkpoint::{
    save, CheckpointMeta, Classifier, TrainMode, FORMAT_VERSION, META_FILE, WEIGHTS_FILE,
};
use grasp_model::heads::{HeadConfig, HeadKind};
use grasp_model::ModelError;
use grasp_schema::taxonomy::Class;
use std::path::{Path, PathBuf};

/// A frozen-pretrained checkpoint on the width-0.1 MobileNetV2 fixture (a
/// copy, so that tests may change it), with an FC head of zeros.
fn checkpoint(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let backbone = dir.join("backbone.safetensors");
    std::fs::copy(fixture("mnv2_w010.safetensors"), &backbone).unwrap();
    let mut info = BackboneInfo::pretrained(&backbone, Architecture::MobileNetV2, 0.1).unwrap();
    info.num_classes = 5;
    let head = HeadConfig {
        kind: HeadKind::Fc,
        feature_dim: 1280,
        classes: Class::COUNT,
        lstm_hidden: 256,
        step_hz: None,
        trace_s: None,
    };
    let meta = CheckpointMeta {
        format_version: FORMAT_VERSION,
        classes: Class::ALL.to_vec(),
        mode: TrainMode::FrozenPretrained,
        head,
        input: grasp_model::input::InputSpec {
            crop: grasp_model::input::Crop::Whole,
            denoise: false,
            preprocess: Architecture::MobileNetV2.preprocess(32),
        },
        backbone: info,
        seed: 0,
        epoch: 0,
        val_loss: 0.0,
        val_accuracy: 0.0,
        train_sequences: None,
        train_config: serde_json::json!({}),
    };
    let dev = Device::Cpu;
    let tensors = vec![
        (
            "head.fc.weight".to_string(),
            Tensor::zeros((Class::COUNT, 1280), DType::F32, &dev).unwrap(),
        ),
        (
            "head.fc.bias".to_string(),
            Tensor::zeros(Class::COUNT, DType::F32, &dev).unwrap(),
        ),
    ];
    let ckpt = dir.join("ckpt");
    save(&ckpt, &meta, &tensors).unwrap();
    ckpt
}

fn load(path: &Path) -> Result<Classifier, ModelError> {
    Classifier::load(path, &Device::Cpu)
}

#[test]
fn a_whole_checkpoint_loads_and_predicts_uniformly_from_a_zero_head() {
    let dir = tempfile::tempdir().unwrap();
    let clf = load(&checkpoint(dir.path())).unwrap();
    let frame = image::RgbImage::from_pixel(32, 32, image::Rgb([10, 200, 30]));
    let p = clf.predict(&[frame]).unwrap();
    assert_eq!(p.len(), 1);
    for v in p[0] {
        assert!((v - 0.2).abs() < 1e-6, "{p:?}");
    }
}

#[test]
fn missing_files_are_missing() {
    let dir = tempfile::tempdir().unwrap();
    let err = load(&dir.path().join("nowhere")).err().unwrap();
    assert!(err.is_missing() && !err.is_corrupt(), "{err:?}");
    assert!(err.to_string().contains("nowhere"), "{err}");

    let ckpt = checkpoint(dir.path());
    std::fs::remove_file(ckpt.join(WEIGHTS_FILE)).unwrap();
    let err = load(&ckpt).err().unwrap();
    assert!(err.is_missing(), "{err:?}");
    assert!(err.to_string().contains(WEIGHTS_FILE), "{err}");

    let ckpt = checkpoint(&dir.path().join("again"));
    std::fs::remove_file(dir.path().join("again/backbone.safetensors")).unwrap();
    let err = load(&ckpt).err().unwrap();
    assert!(err.is_missing(), "{err:?}");
}

#[test]
fn corrupt_files_are_corrupt() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = checkpoint(dir.path());
    std::fs::write(ckpt.join(WEIGHTS_FILE), b"not tensors").unwrap();
    let err = load(&ckpt).err().unwrap();
    assert!(err.is_corrupt() && !err.is_missing(), "{err:?}");
    assert!(err.to_string().contains(WEIGHTS_FILE), "{err}");

    std::fs::write(ckpt.join(META_FILE), b"{ not json").unwrap();
    let err = load(&ckpt).err().unwrap();
    assert!(err.is_corrupt(), "{err:?}");
    assert!(err.to_string().contains(META_FILE), "{err}");

    // a backbone file whose bytes changed after training
    let ckpt = checkpoint(&dir.path().join("again"));
    let backbone = dir.path().join("again/backbone.safetensors");
    let mut bytes = std::fs::read(&backbone).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&backbone, bytes).unwrap();
    let err = load(&ckpt).err().unwrap();
    assert!(matches!(err, ModelError::HashMismatch { .. }), "{err:?}");
    assert!(err.is_corrupt());
}

#[test]
fn a_newer_format_is_neither_missing_nor_corrupt() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = checkpoint(dir.path());
    let json = ckpt.join(META_FILE);
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    meta["format_version"] = (FORMAT_VERSION + 1).into();
    std::fs::write(&json, meta.to_string()).unwrap();
    let err = load(&ckpt).err().unwrap();
    assert!(
        matches!(err, ModelError::UnsupportedVersion { found, .. } if found == FORMAT_VERSION + 1),
        "{err:?}"
    );
}

/// Head weights with a NaN (a diverged training) would make every output
/// NaN: refused at load, naming the file and the tensor, instead of a
/// normal-looking 25 % report or a hand driven by garbage.
#[test]
fn non_finite_weights_are_a_corrupt_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = checkpoint(dir.path());
    for bad in [f32::NAN, f32::INFINITY] {
        let dev = Device::Cpu;
        let mut w = vec![0f32; Class::COUNT * 1280];
        w[7] = bad;
        let tensors: std::collections::HashMap<String, Tensor> = [
            (
                "head.fc.weight".to_string(),
                Tensor::from_vec(w, (Class::COUNT, 1280), &dev).unwrap(),
            ),
            (
                "head.fc.bias".to_string(),
                Tensor::zeros(Class::COUNT, DType::F32, &dev).unwrap(),
            ),
        ]
        .into_iter()
        .collect();
        candle_core::safetensors::save(&tensors, ckpt.join(WEIGHTS_FILE)).unwrap();
        let err = load(&ckpt).err().expect("loaded NaN weights");
        assert!(err.is_corrupt(), "{err}");
        let msg = err.to_string();
        assert!(
            msg.contains(WEIGHTS_FILE) && msg.contains("head.fc.weight"),
            "{msg}"
        );
    }
}
