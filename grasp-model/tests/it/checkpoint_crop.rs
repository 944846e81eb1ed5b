//! A checkpoint trained on centre crops (`grasp-train --center-crop`, or
//! `reader.crop = { angle_deg = D }`, with or without `--denoise`) is given whole camera
//! frames by `hannes-run`: `Classifier::predict` crops and denoises them as
//! its input record says, so the runtime sees what the head was trained on.
//! Checkpoints of format 2, whose crop lived in the trainer's options, load
//! with those mapped onto the record, or are refused by field name.

use candle_core::{Device, Tensor};
use grasp_model::backbone::{Architecture, BackboneInfo};
use grasp_model::checkpoint::{save, CheckpointMeta, Classifier, TrainMode, FORMAT_VERSION};
use grasp_model::heads::{HeadConfig, HeadKind};
use grasp_model::input::preprocess::center_crop;
use grasp_model::input::{Crop, InputSpec, Lens};
use grasp_schema::taxonomy::Class;
use image::{Rgb, RgbImage};
use std::path::{Path, PathBuf};

fn spec(crop: Crop, denoise: bool) -> InputSpec {
    InputSpec {
        crop,
        denoise,
        preprocess: Architecture::MobileNetV2.preprocess(32),
    }
}

/// A frozen-pretrained checkpoint on the width-0.1 MobileNetV2 fixture with
/// a fixed FC head whose outputs depend on the image, with `input`.
fn checkpoint(dir: &Path, name: &str, input: InputSpec) -> PathBuf {
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
            step_hz: None,
            trace_s: None,
        },
        input,
        backbone: info,
        seed: 0,
        epoch: 0,
        val_loss: 0.0,
        val_accuracy: 0.0,
        train_sequences: None,
        train_config: serde_json::json!({}),
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

/// The same checkpoint rewritten as format 2: `preprocessing`, and the
/// crop and denoising in `train_config.reader`.
fn legacy_checkpoint(dir: &Path, name: &str, reader: serde_json::Value) -> PathBuf {
    let ckpt = checkpoint(dir, name, spec(Crop::Whole, false));
    let path = ckpt.join(grasp_model::checkpoint::META_FILE);
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let input = meta.as_object_mut().unwrap().remove("input").unwrap();
    meta["format_version"] = 2.into();
    meta["preprocessing"] = input["preprocess"].clone();
    meta["train_config"] = serde_json::json!({ "reader": reader });
    std::fs::write(&path, serde_json::to_vec(&meta).unwrap()).unwrap();
    ckpt
}

/// A frame whose centre (a red square) differs from its border (stripes).
fn frame() -> RgbImage {
    RgbImage::from_fn(128, 96, |x, y| {
        if (44..84).contains(&x) && (28..68).contains(&y) {
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

fn lens(focal_px: f64) -> Lens {
    Lens::Focal {
        focal_px,
        width: 128,
        height: 96,
    }
}

#[test]
fn predict_crops_camera_frames_as_the_checkpoint_was_trained() {
    let dir = tempfile::tempdir().unwrap();
    let cropped = checkpoint(dir.path(), "crop", spec(Crop::Fraction(0.5), false));
    let cropped = Classifier::load(&cropped, &Device::Cpu).unwrap();
    assert_eq!(cropped.input().crop, Crop::Fraction(0.5));
    let whole = checkpoint(dir.path(), "whole", spec(Crop::Whole, false));
    let whole = Classifier::load(&whole, &Device::Cpu).unwrap();

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
    for bad in [1.5, 0.0, -0.2] {
        let ckpt = checkpoint(dir.path(), "bad", spec(Crop::Whole, false));
        let path = ckpt.join(grasp_model::checkpoint::META_FILE);
        let mut meta: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        meta["input"]["crop"] = serde_json::json!({ "fraction": bad });
        std::fs::write(&path, serde_json::to_vec(&meta).unwrap()).unwrap();
        let err = Classifier::load(&ckpt, &Device::Cpu)
            .err()
            .expect("loaded a bad crop");
        assert!(err.to_string().contains("input.crop"), "{err}");
    }
}

#[test]
fn a_fixed_angle_crop_follows_the_cameras_focal_length() {
    let dir = tempfile::tempdir().unwrap();
    // 0.5 of a 96 px side at a focal length of 80 px spans 2 atan(0.3).
    let angle = grasp_schema::dataset::crop_angle_deg(0.5, 80.0, 128, 96);
    let angled = checkpoint(dir.path(), "angle", spec(Crop::AngleDeg(angle), false));
    let fraction = checkpoint(dir.path(), "fraction", spec(Crop::Fraction(0.5), false));
    let mut angled = Classifier::load(&angled, &Device::Cpu).unwrap();
    let fraction = Classifier::load(&fraction, &Device::Cpu).unwrap();
    assert_eq!(angled.input().crop, Crop::AngleDeg(angle));
    let frame = frame();
    // Without the camera's lens there is no crop to take.
    let err = angled.predict(std::slice::from_ref(&frame)).unwrap_err();
    assert!(err.to_string().contains("focal length"), "{err}");
    // At that focal length the angle is the same 0.5 of the frame...
    angled.set_lens(lens(80.0));
    assert!((angled.crop_fraction(128, 96).unwrap().unwrap() - 0.5).abs() < 1e-12);
    let a = angled.predict(std::slice::from_ref(&frame)).unwrap()[0];
    let f = fraction.predict(std::slice::from_ref(&frame)).unwrap()[0];
    assert!(max_diff(&a, &f) < 1e-6, "{a:?} vs {f:?}");
    // ...through a lens twice as wide, half of it.
    angled.set_lens(lens(40.0));
    assert!((angled.crop_fraction(128, 96).unwrap().unwrap() - 0.25).abs() < 1e-12);
    let wide = angled.predict(std::slice::from_ref(&frame)).unwrap()[0];
    let whole = checkpoint(dir.path(), "whole", spec(Crop::Whole, false));
    let whole = Classifier::load(&whole, &Device::Cpu).unwrap();
    let by_hand = whole.predict(&[center_crop(&frame, 0.25)]).unwrap()[0];
    assert!(max_diff(&wide, &by_hand) < 1e-6, "{wide:?} vs {by_hand:?}");
    assert!(
        max_diff(&wide, &a) > 1e-4,
        "the lens changed nothing: {wide:?}"
    );
    // Through a lens too narrow to hold the angle it is the whole frame.
    angled.set_lens(lens(200.0));
    assert_eq!(angled.crop_fraction(128, 96).unwrap(), Some(1.0));
    assert!(angled.crop_fraction(0, 96).is_err());
}

/// Frames of another size than the lens was measured at: the focal length
/// scales with them, so half-size frames are cut at the same angle (a
/// 112 px recording of a 224 px render once got the 224 px focal length,
/// a wrong crop and a wrong pre-shape).
#[test]
fn the_lens_scales_with_the_frames_size() {
    let dir = tempfile::tempdir().unwrap();
    let angle = grasp_schema::dataset::crop_angle_deg(0.5, 80.0, 128, 96);
    let angled = checkpoint(dir.path(), "angle", spec(Crop::AngleDeg(angle), false));
    let mut angled = Classifier::load(&angled, &Device::Cpu).unwrap();
    angled.set_lens(lens(80.0));
    for (w, h) in [(128, 96), (256, 192), (64, 48)] {
        let f = angled.crop_fraction(w, h).unwrap().unwrap();
        assert!((f - 0.5).abs() < 1e-12, "{w}x{h}: {f}");
    }
    // Another shape is a crop of the sensor, whose focal length is unknown.
    let err = angled.crop_fraction(96, 96).unwrap_err().to_string();
    assert!(
        err.contains("96x96") && err.contains("another shape"),
        "{err}"
    );
}

/// A focal length in millimetres (1.93 for the D435) instead of pixels is
/// refused by name instead of cropping under a pixel; so is a crop too
/// small for the backbone, and an empty frame.
#[test]
fn implausible_lenses_and_tiny_crops_are_refused() {
    for bad in [1.93, 0.0, -5.0, f64::NAN, 1e6] {
        let err = Lens::focal(bad, 224, 224).unwrap_err().to_string();
        assert!(
            err.contains("focal_px") && err.contains("field of view"),
            "{bad}: {err}"
        );
    }
    for bad in [5.0, 175.0, f64::INFINITY] {
        let err = Lens::horizontal_fov(bad).unwrap_err().to_string();
        assert!(err.contains("hfov_deg"), "{bad}: {err}");
    }
    assert!(Lens::focal(291.8, 224, 224).is_ok());
    let small = Crop::Fraction(0.1).fraction(None, 100, 100).unwrap_err();
    assert!(small.to_string().contains("10 px"), "{small}");
    let one = Crop::Whole.fraction(None, 1, 1).unwrap_err();
    assert!(one.to_string().contains("1x1"), "{one}");
    assert!(Crop::Whole.fraction(None, 0, 5).is_err());
}

#[test]
fn a_denoising_checkpoint_denoises_the_crop_it_reads() {
    let dir = tempfile::tempdir().unwrap();
    let clean = checkpoint(dir.path(), "clean", spec(Crop::Fraction(0.5), false));
    let denoising = checkpoint(dir.path(), "denoise", spec(Crop::Fraction(0.5), true));
    let clean = Classifier::load(&clean, &Device::Cpu).unwrap();
    let denoising = Classifier::load(&denoising, &Device::Cpu).unwrap();
    assert!(denoising.input().denoise && !clean.input().denoise);
    // A frame with sensor noise: the denoising checkpoint reads the crop
    // denoised, exactly as the trainer fed it.
    let mut noisy = frame();
    for (i, v) in noisy.iter_mut().enumerate() {
        let n = ((i as f32 * 12.9898).sin() * 43758.547).fract() - 0.5;
        *v = (f32::from(*v) + 40.0 * n).round().clamp(0.0, 255.0) as u8;
    }
    let prepared = denoising.prepare(&noisy).unwrap();
    let expected = grasp_model::input::denoise::denoise(&center_crop(&noisy, 0.5));
    assert_eq!(prepared, expected);
    assert_ne!(prepared, center_crop(&noisy, 0.5));
    let whole = checkpoint(dir.path(), "whole", spec(Crop::Whole, false));
    let whole = Classifier::load(&whole, &Device::Cpu).unwrap();
    let via = denoising.predict(std::slice::from_ref(&noisy)).unwrap()[0];
    let by_hand = whole.predict(&[expected]).unwrap()[0];
    assert!(max_diff(&via, &by_hand) < 1e-6, "{via:?} vs {by_hand:?}");
    let plain = clean.predict(std::slice::from_ref(&noisy)).unwrap()[0];
    assert!(max_diff(&via, &plain) > 1e-4, "denoising changed nothing");
}

/// Format 2 checkpoints load with their reader options mapped onto the
/// input record.
#[test]
fn format_2_checkpoints_load_with_their_crop_mapped() {
    let dir = tempfile::tempdir().unwrap();
    for (reader, input) in [
        (serde_json::json!({}), spec(Crop::Whole, false)),
        (
            serde_json::json!({ "center_crop": 0.5, "camera": "Wrist_d435" }),
            spec(Crop::Fraction(0.5), false),
        ),
        (
            serde_json::json!({ "crop_angle_deg": 18.3, "denoise": true, "center_crop": null }),
            spec(Crop::AngleDeg(18.3), true),
        ),
    ] {
        let ckpt = legacy_checkpoint(dir.path(), "old", reader.clone());
        let clf = Classifier::load(&ckpt, &Device::Cpu).unwrap();
        assert_eq!(clf.input(), &input, "{reader}");
    }
}

#[test]
fn bad_format_2_crop_or_denoise_records_are_corrupt_checkpoints() {
    let dir = tempfile::tempdir().unwrap();
    for (reader, field) in [
        (serde_json::json!({ "center_crop": 1.5 }), "crop.fraction"),
        (serde_json::json!({ "center_crop": "half" }), "center_crop"),
        (
            serde_json::json!({ "crop_angle_deg": 0.0 }),
            "crop.angle_deg",
        ),
        (
            serde_json::json!({ "crop_angle_deg": 200.0 }),
            "crop.angle_deg",
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
        let ckpt = legacy_checkpoint(dir.path(), "bad", reader.clone());
        let err = Classifier::load(&ckpt, &Device::Cpu)
            .err()
            .unwrap_or_else(|| panic!("loaded {reader}"));
        let err = err.to_string();
        assert!(
            err.contains(field) && err.contains("best.json"),
            "{reader}: {err}"
        );
    }
}

/// `predict` runs a frame on a worker of the kernels' rayon pool. The
/// probabilities must not depend on the pool's size, and predictions run
/// concurrently on one pool must all finish with the same results.
#[test]
fn predictions_do_not_depend_on_the_pool_and_run_concurrently() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = checkpoint(dir.path(), "denoised", spec(Crop::Fraction(0.5), true));
    let clf = std::sync::Arc::new(Classifier::load(&ckpt, &Device::Cpu).unwrap());
    let frames: Vec<RgbImage> = (0..4u32)
        .map(|i| {
            RgbImage::from_fn(128, 96, |x, y| {
                let v = (x * 7 + y * 13 + i * 31) % 256;
                Rgb([v as u8, (255 - v) as u8, ((x ^ y) % 256) as u8])
            })
        })
        .collect();
    let pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    };
    let alone: Vec<_> = pool(1).install(|| {
        frames
            .iter()
            .map(|f| clf.predict(std::slice::from_ref(f)).unwrap()[0])
            .collect()
    });
    for threads in [2, 3] {
        let pooled: Vec<_> = pool(threads).install(|| {
            frames
                .iter()
                .map(|f| clf.predict(std::slice::from_ref(f)).unwrap()[0])
                .collect()
        });
        for (a, b) in alone.iter().zip(&pooled) {
            assert!(max_diff(a, b) < 1e-6, "{threads} threads: {a:?} vs {b:?}");
        }
    }
    // Two predictions at once on a pool of 2, many times; a deadlock
    // fails the test after a minute instead of hanging it.
    let (tx, rx) = std::sync::mpsc::channel();
    let (clf2, frames2) = (clf.clone(), frames.clone());
    std::thread::spawn(move || {
        let two = pool(2);
        for round in 0..40 {
            let (i, j) = (round % 4, (round + 1) % 4);
            let (a, b) = two.install(|| {
                rayon::join(
                    || clf2.predict(std::slice::from_ref(&frames2[i])).unwrap()[0],
                    || clf2.predict(std::slice::from_ref(&frames2[j])).unwrap()[0],
                )
            });
            tx.send((i, a, j, b)).unwrap();
        }
    });
    for _ in 0..40 {
        let (i, a, j, b) = rx
            .recv_timeout(std::time::Duration::from_secs(60))
            .expect("two concurrent predictions did not finish within a minute");
        assert!(max_diff(&a, &alone[i]) < 1e-6, "{a:?} vs {:?}", alone[i]);
        assert!(max_diff(&b, &alone[j]) < 1e-6, "{b:?} vs {:?}", alone[j]);
    }
}
