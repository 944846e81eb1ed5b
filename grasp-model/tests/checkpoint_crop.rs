//! A checkpoint trained on centre crops (`grasp-train --center-crop`) is
//! given whole camera frames by `hannes-run`: `Classifier::predict` crops
//! them as recorded, so the runtime sees what the head was trained on.

use candle_core::{Device, Tensor};
use grasp_model::backbone::{Architecture, BackboneInfo};
use grasp_model::checkpoint::{save, CheckpointMeta, Classifier, TrainMode, FORMAT_VERSION};
use grasp_model::heads::{HeadConfig, HeadKind};
use grasp_model::model::preprocess::center_crop;
use grasp_schema::taxonomy::Class;
use image::{Rgb, RgbImage};
use std::path::{Path, PathBuf};

/// A frozen-pretrained checkpoint on the width-0.1 MobileNetV2 fixture with
/// a fixed FC head whose outputs depend on the image, trained with `reader`.
fn checkpoint(dir: &Path, name: &str, reader: serde_json::Value) -> PathBuf {
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mnv2_w010.safetensors");
    let backbone = dir.join("backbone.safetensors");
    if !backbone.exists() {
        std::fs::copy(fixture, &backbone).unwrap();
    }
    let mut info = BackboneInfo::pretrained(&backbone, Architecture::MobileNetV2, 0.1).unwrap();
    info.num_classes = 5;
    let meta = CheckpointMeta {
        format_version: FORMAT_VERSION,
        classes: Class::ALL.to_vec(),
        mode: TrainMode::FrozenPretrained,
        head: HeadConfig {
            kind: HeadKind::Fc,
            feature_dim: 1280,
            classes: Class::COUNT,
            lstm_hidden: 256,
        },
        preprocessing: Architecture::MobileNetV2.preprocess(32),
        backbone: info,
        seed: 0,
        epoch: 0,
        val_loss: 0.0,
        val_accuracy: 0.0,
        train_sequences: None,
        train_config: serde_json::json!({ "reader": reader }),
    };
    let dev = Device::Cpu;
    // Small, fixed weights: the softmax stays far from saturation, so a
    // different input shows in every probability.
    let weights: Vec<f32> = (0..Class::COUNT * 1280)
        .map(|i| 0.01 * (i as f32 * 0.7).sin())
        .collect();
    let tensors = vec![
        (
            "head.fc.weight".to_string(),
            Tensor::from_vec(weights, (Class::COUNT, 1280), &dev).unwrap(),
        ),
        (
            "head.fc.bias".to_string(),
            Tensor::zeros(Class::COUNT, candle_core::DType::F32, &dev).unwrap(),
        ),
    ];
    let ckpt = dir.join(name);
    save(&ckpt, &meta, &tensors).unwrap();
    ckpt
}

/// A frame whose centre (a red square) differs from its border (stripes).
fn frame() -> RgbImage {
    RgbImage::from_fn(64, 48, |x, y| {
        if (22..42).contains(&x) && (14..34).contains(&y) {
            Rgb([220, 30, 30])
        } else {
            Rgb([((x * 37) % 256) as u8, ((y * 53) % 256) as u8, 90])
        }
    })
}

fn max_diff(a: &[f32; Class::COUNT], b: &[f32; Class::COUNT]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn predict_crops_camera_frames_as_the_checkpoint_was_trained() {
    let dir = tempfile::tempdir().unwrap();
    let cropped_ckpt = checkpoint(
        dir.path(),
        "crop",
        serde_json::json!({ "center_crop": 0.5 }),
    );
    let cropped = Classifier::load(&cropped_ckpt, &Device::Cpu).unwrap();
    assert_eq!(cropped.center_crop(), Some(0.5));
    // The same weights read without the crop record.
    let meta_path = cropped_ckpt.join(grasp_model::checkpoint::META_FILE);
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).unwrap()).unwrap();
    meta["train_config"]["reader"]["center_crop"] = serde_json::Value::Null;
    std::fs::write(&meta_path, serde_json::to_vec(&meta).unwrap()).unwrap();
    let whole = Classifier::load(&cropped_ckpt, &Device::Cpu).unwrap();
    assert_eq!(whole.center_crop(), None);

    let frame = frame();
    let via_crop = cropped.predict(std::slice::from_ref(&frame)).unwrap()[0];
    let by_hand = whole.predict(&[center_crop(&frame, 0.5)]).unwrap()[0];
    let uncropped = whole.predict(std::slice::from_ref(&frame)).unwrap()[0];
    assert!(
        max_diff(&via_crop, &by_hand) < 1e-6,
        "{via_crop:?} vs {by_hand:?}"
    );
    assert!(
        max_diff(&via_crop, &uncropped) > 1e-4,
        "the crop changed nothing: {via_crop:?}"
    );
}

#[test]
fn a_crop_outside_zero_to_one_is_a_corrupt_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    for bad in [
        serde_json::json!(1.5),
        serde_json::json!(0.0),
        serde_json::json!("half"),
    ] {
        let ckpt = checkpoint(dir.path(), "bad", serde_json::json!({ "center_crop": bad }));
        let err = Classifier::load(&ckpt, &Device::Cpu)
            .err()
            .expect("loaded a bad crop");
        assert!(err.to_string().contains("center_crop"), "{err}");
    }
}
