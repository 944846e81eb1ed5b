//! A checkpoint trained on centre crops (`grasp-train --center-crop`, or
//! `--crop-angle-deg`, with or without `--denoise`) is given whole camera
//! frames by `hannes-run`: `Classifier::predict` crops and denoises them as
//! recorded, so the runtime sees what the head was trained on.

use candle_core::{Device, Tensor};
use grasp_model::backbone::{Architecture, BackboneInfo};
use grasp_model::checkpoint::{
    save, CentreCrop, CheckpointMeta, Classifier, TrainMode, FORMAT_VERSION,
};
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
    assert_eq!(cropped.crop(), Some(CentreCrop::Fraction(0.5)));
    // The same weights read without the crop record.
    let meta_path = cropped_ckpt.join(grasp_model::checkpoint::META_FILE);
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).unwrap()).unwrap();
    meta["train_config"]["reader"]["center_crop"] = serde_json::Value::Null;
    std::fs::write(&meta_path, serde_json::to_vec(&meta).unwrap()).unwrap();
    let whole = Classifier::load(&cropped_ckpt, &Device::Cpu).unwrap();
    assert_eq!(whole.crop(), None);

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

#[test]
fn a_fixed_angle_crop_follows_the_cameras_focal_length() {
    let dir = tempfile::tempdir().unwrap();
    // 0.5 of a 48 px side at a focal length of 40 px spans 2 atan(0.3).
    let angle = grasp_schema::dataset::crop_angle_deg(0.5, 40.0, 64, 48);
    let angled = checkpoint(
        dir.path(),
        "angle",
        serde_json::json!({ "crop_angle_deg": angle }),
    );
    let fraction = checkpoint(
        dir.path(),
        "fraction",
        serde_json::json!({ "center_crop": 0.5 }),
    );
    let mut angled = Classifier::load(&angled, &Device::Cpu).unwrap();
    let fraction = Classifier::load(&fraction, &Device::Cpu).unwrap();
    assert_eq!(angled.crop(), Some(CentreCrop::AngleDeg(angle)));
    let frame = frame();
    // Without the camera's focal length there is no crop to take.
    let err = angled.predict(std::slice::from_ref(&frame)).unwrap_err();
    assert!(err.to_string().contains("focal length"), "{err}");
    assert!(angled.set_focal_px(0.0).is_err());
    assert!(angled.set_focal_px(f64::NAN).is_err());
    // At that focal length the angle is the same 0.5 of the frame...
    angled.set_focal_px(40.0).unwrap();
    assert!((angled.crop_fraction(64, 48).unwrap().unwrap() - 0.5).abs() < 1e-12);
    let a = angled.predict(std::slice::from_ref(&frame)).unwrap()[0];
    let f = fraction.predict(std::slice::from_ref(&frame)).unwrap()[0];
    assert!(max_diff(&a, &f) < 1e-6, "{a:?} vs {f:?}");
    // ...through a lens twice as wide, half of it.
    angled.set_focal_px(20.0).unwrap();
    assert!((angled.crop_fraction(64, 48).unwrap().unwrap() - 0.25).abs() < 1e-12);
    let wide = angled.predict(std::slice::from_ref(&frame)).unwrap()[0];
    let whole = checkpoint(dir.path(), "whole", serde_json::json!({}));
    let whole = Classifier::load(&whole, &Device::Cpu).unwrap();
    let by_hand = whole.predict(&[center_crop(&frame, 0.25)]).unwrap()[0];
    assert!(max_diff(&wide, &by_hand) < 1e-6, "{wide:?} vs {by_hand:?}");
    assert!(
        max_diff(&wide, &a) > 1e-4,
        "the lens changed nothing: {wide:?}"
    );
    // Through a lens too narrow to hold the angle it is the whole frame.
    angled.set_focal_px(100.0).unwrap();
    assert_eq!(angled.crop_fraction(64, 48).unwrap(), Some(1.0));
    assert_eq!(angled.crop_fraction(0, 48).ok(), None);
}

#[test]
fn a_denoising_checkpoint_denoises_the_crop_it_reads() {
    let dir = tempfile::tempdir().unwrap();
    let clean = checkpoint(
        dir.path(),
        "clean",
        serde_json::json!({ "center_crop": 0.5 }),
    );
    let denoising = checkpoint(
        dir.path(),
        "denoise",
        serde_json::json!({ "center_crop": 0.5, "denoise": true }),
    );
    let clean = Classifier::load(&clean, &Device::Cpu).unwrap();
    let denoising = Classifier::load(&denoising, &Device::Cpu).unwrap();
    assert!(denoising.denoises() && !clean.denoises());
    // A frame with sensor noise: the denoising checkpoint reads the crop
    // denoised, exactly as the trainer fed it.
    let mut noisy = frame();
    for (i, v) in noisy.iter_mut().enumerate() {
        let n = ((i as f32 * 12.9898).sin() * 43758.547).fract() - 0.5;
        *v = (f32::from(*v) + 40.0 * n).round().clamp(0.0, 255.0) as u8;
    }
    let prepared = denoising.prepare(&noisy).unwrap();
    let expected = grasp_model::model::denoise::denoise(&center_crop(&noisy, 0.5));
    assert_eq!(prepared, expected);
    assert_ne!(prepared, center_crop(&noisy, 0.5));
    let whole = checkpoint(dir.path(), "whole", serde_json::json!({}));
    let whole = Classifier::load(&whole, &Device::Cpu).unwrap();
    let via = denoising.predict(std::slice::from_ref(&noisy)).unwrap()[0];
    let by_hand = whole.predict(&[expected]).unwrap()[0];
    assert!(max_diff(&via, &by_hand) < 1e-6, "{via:?} vs {by_hand:?}");
    let plain = clean.predict(std::slice::from_ref(&noisy)).unwrap()[0];
    assert!(max_diff(&via, &plain) > 1e-4, "denoising changed nothing");
}

#[test]
fn bad_angle_or_denoise_records_are_corrupt_checkpoints() {
    let dir = tempfile::tempdir().unwrap();
    for (reader, field) in [
        (
            serde_json::json!({ "crop_angle_deg": 0.0 }),
            "crop_angle_deg",
        ),
        (
            serde_json::json!({ "crop_angle_deg": 200.0 }),
            "crop_angle_deg",
        ),
        (
            serde_json::json!({ "crop_angle_deg": "wide" }),
            "crop_angle_deg",
        ),
        (
            serde_json::json!({ "center_crop": 0.5, "crop_angle_deg": 18.0 }),
            "both",
        ),
        (serde_json::json!({ "denoise": "yes" }), "denoise"),
    ] {
        let ckpt = checkpoint(dir.path(), "bad", reader.clone());
        let err = Classifier::load(&ckpt, &Device::Cpu)
            .err()
            .unwrap_or_else(|| panic!("loaded {reader}"));
        assert!(err.to_string().contains(field), "{reader}: {err}");
    }
}
