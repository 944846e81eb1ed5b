//! The dataset reader on both layouts, bad-data handling and splits.

use grasp_model::input::{Crop, Lens};
use grasp_schema::taxonomy::{Class, Preshape};
use std::collections::HashSet;
use trainer::data::split::{select, stratified_split, SplitConfig};
use trainer::data::synthetic::{write_synthetic, Layout, SyntheticSpec};
use trainer::data::{read_dataset, BadData, LabelSource, OnBadData, ReaderOptions};
use trainer::plan::DataPlan;

use crate::lead_in::{look_away_first, sequence_json};

fn generated() -> (tempfile::TempDir, SyntheticSpec) {
    generated_at(SyntheticSpec::small(Layout::Generated).size)
}

/// A generated dataset of `size` x `size` frames.
fn generated_at(size: u32) -> (tempfile::TempDir, SyntheticSpec) {
    let dir = tempfile::tempdir().unwrap();
    let spec = SyntheticSpec {
        size,
        ..SyntheticSpec::small(Layout::Generated)
    };
    write_synthetic(dir.path(), &spec).unwrap();
    (dir, spec)
}

fn fraction(f: f64) -> Crop {
    Crop::Fraction(f)
}

#[test]
fn generated_layout_takes_labels_from_sequence_json() {
    let (dir, spec) = generated();
    let bad = BadData::new(OnBadData::Fail);
    let data = read_dataset(dir.path(), &ReaderOptions::default(), &bad).unwrap();
    assert_eq!(data.sequences.len(), 5 * spec.sequences_per_part);
    assert!(!data.is_real());
    let handle = data
        .sequences
        .iter()
        .find(|s| s.part.as_deref() == Some("handle"))
        .unwrap();
    assert_eq!(handle.object, "025_mug");
    assert_eq!(handle.preshape, Preshape::Lateral);
    assert_eq!(handle.label_source, LabelSource::SequenceJson);
    assert_eq!(handle.frames.len(), spec.frames);
    assert_eq!(handle.labels[0], Class::Lateral);
    assert_eq!(handle.labels[spec.frames - 1], Class::NoGrasp);
    assert_eq!(handle.stratum(), "025_mug/handle");
    let multi = data.multi_grasp_objects();
    assert_eq!(
        multi.into_iter().collect::<Vec<_>>(),
        vec!["025_mug".to_string()]
    );
}

#[test]
fn authors_layout_labels_the_last_half_second_no_grasp() {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = SyntheticSpec::small(Layout::Authors);
    spec.frames = 12;
    write_synthetic(dir.path(), &spec).unwrap();
    let opts = ReaderOptions {
        real_fps: 8.0,
        ..Default::default()
    };
    let data = read_dataset(dir.path(), &opts, &BadData::new(OnBadData::Fail)).unwrap();
    assert!(data.is_real());
    let s = &data.sequences[0];
    assert_eq!(s.label_source, LabelSource::PreshapeFolder);
    // 0.5 s at 8 fps = 4 frames.
    let ng = s.labels.iter().filter(|c| **c == Class::NoGrasp).count();
    assert_eq!(ng, 4);
    assert_eq!(s.labels[7], Class::from(s.preshape));
    assert_eq!(s.labels[8], Class::NoGrasp);
    // Without part annotations there is no part; the pre-shape folder
    // stands for it in the split's strata.
    assert_eq!(s.part, None);
    assert_eq!(
        s.stratum(),
        format!("{}/{}", s.object, s.preshape.authors_folder())
    );
    assert_eq!(s.condition, "real");
}

#[test]
fn unreadable_images_and_missing_labels_are_reported_with_their_path() {
    let (dir, _) = generated();
    let data = read_dataset(
        dir.path(),
        &ReaderOptions::default(),
        &BadData::new(OnBadData::Fail),
    )
    .unwrap();
    let broken = data.sequences[0].frames[1].clone();
    std::fs::write(&broken, b"not a png").unwrap();
    let unlabeled = data.sequences[1].dir.join("sequence.json");
    std::fs::remove_file(&unlabeled).unwrap();

    // fail: the reader stops at the missing labels, naming the file.
    let err = read_dataset(
        dir.path(),
        &ReaderOptions::default(),
        &BadData::new(OnBadData::Fail),
    )
    .unwrap_err();
    assert!(
        err.to_string().contains(&unlabeled.display().to_string()),
        "{err}"
    );
    assert!(err.to_string().contains("missing labels"), "{err}");

    // skip: the sequence is left out and listed.
    let bad = BadData::new(OnBadData::Skip);
    let data2 = read_dataset(dir.path(), &ReaderOptions::default(), &bad).unwrap();
    assert_eq!(data2.sequences.len(), data.sequences.len() - 1);
    assert_eq!(bad.problems().len(), 1);
    assert_eq!(bad.problems()[0].path, unlabeled);

    // The unreadable frame is found when decoded.
    let fail = BadData::new(OnBadData::Fail);
    let err = trainer::data::images::load_frame(&broken, &fail).unwrap_err();
    assert!(
        err.to_string().contains(&broken.display().to_string()),
        "{err}"
    );
    let skip = BadData::new(OnBadData::Skip);
    assert!(trainer::data::images::load_frame(&broken, &skip)
        .unwrap()
        .is_none());
    assert_eq!(skip.problems()[0].path, broken);
}

#[test]
fn invalid_sequence_json_names_the_file() {
    let (dir, _) = generated();
    let data = read_dataset(
        dir.path(),
        &ReaderOptions::default(),
        &BadData::new(OnBadData::Fail),
    )
    .unwrap();
    let json = data.sequences[2].dir.join("sequence.json");
    std::fs::write(&json, "{\"plan\": 3}").unwrap();
    let err = read_dataset(
        dir.path(),
        &ReaderOptions::default(),
        &BadData::new(OnBadData::Fail),
    )
    .unwrap_err();
    assert!(
        err.to_string().contains(&json.display().to_string()),
        "{err}"
    );
}

#[test]
fn splits_are_by_sequence_stratified_and_seeded() {
    let (dir, _) = generated();
    let data = read_dataset(
        dir.path(),
        &ReaderOptions::default(),
        &BadData::new(OnBadData::Fail),
    )
    .unwrap();
    let cfg = SplitConfig {
        val_fraction: 0.25,
        test_fraction: 0.25,
        seed: 7,
    };
    let s = stratified_split(&data, &cfg);
    assert_eq!(s, stratified_split(&data, &cfg));
    let all: Vec<&String> = s.train.iter().chain(&s.val).chain(&s.test).collect();
    let unique: HashSet<&String> = all.iter().copied().collect();
    assert_eq!(all.len(), data.sequences.len());
    assert_eq!(unique.len(), all.len(), "a sequence is in two splits");
    // Every object-part pair (4 sequences each) has 2 train, 1 val, 1 test.
    for ids in [&s.train, &s.val, &s.test] {
        let d = select(&data, ids);
        let strata: HashSet<String> = d.sequences.iter().map(|q| q.stratum()).collect();
        assert_eq!(strata.len(), 5);
    }
    assert_eq!(s.train.len(), 10);
    let other = stratified_split(
        &data,
        &SplitConfig {
            seed: 8,
            ..cfg.clone()
        },
    );
    assert_ne!(other.test, s.test);
}

/// Issue 15, item 10: an interrupted render leaves its partial sequences,
/// mesh cache and logs in `.grasp-gen/`; the reader never walks into it (or
/// any hidden folder), so even `--on-bad-data fail` reads the dataset.
#[test]
fn the_generators_bookkeeping_folders_are_not_read() {
    let (dir, spec) = generated();
    let work = dir.path().join(".grasp-gen");
    let partial = work.join("partial/00000004-0-4242");
    std::fs::create_dir_all(&partial).unwrap();
    std::fs::copy(
        read_dataset(
            dir.path(),
            &ReaderOptions::default(),
            &BadData::new(OnBadData::Fail),
        )
        .unwrap()
        .sequences[0]
            .frames[0]
            .clone(),
        partial.join("00000.png"),
    )
    .unwrap();
    std::fs::create_dir_all(work.join("meshes")).unwrap();
    std::fs::write(work.join("meshes/025_mug.vertices.f64"), [0u8; 24]).unwrap();
    std::fs::create_dir_all(work.join("logs")).unwrap();
    // A hidden folder among the real ones, as an editor or a sync tool leaves.
    std::fs::create_dir_all(dir.path().join("mug/025_mug/.sync/Wrist_d435/rgb00009")).unwrap();

    let bad = BadData::new(OnBadData::Fail);
    let data = read_dataset(dir.path(), &ReaderOptions::default(), &bad).unwrap();
    assert_eq!(data.sequences.len(), 5 * spec.sequences_per_part);
    assert!(data.sequences.iter().all(|s| !s.id.contains(".grasp-gen")));
    assert!(bad.problems().is_empty());
}

#[test]
fn the_lead_in_before_the_target_is_in_view_is_found_and_trimmed() {
    let (dir, spec) = generated();
    look_away_first(&sequence_json(dir.path(), "handle"), 3);
    let bad = BadData::new(OnBadData::Fail);
    let mut data = read_dataset(dir.path(), &ReaderOptions::default(), &bad).unwrap();
    let leads: Vec<usize> = data.sequences.iter().map(|s| s.lead_in).collect();
    assert_eq!(leads.iter().filter(|n| **n == 3).count(), 1, "{leads:?}");
    assert_eq!(leads.iter().sum::<usize>(), 3, "{leads:?}");
    let before = data
        .sequences
        .iter()
        .find(|s| s.lead_in == 3)
        .unwrap()
        .clone();

    assert_eq!(data.trim_lead_ins(), (1, 3));
    let after = data.sequences.iter().find(|s| s.id == before.id).unwrap();
    assert_eq!(after.frames, before.frames[3..]);
    assert_eq!(after.labels, before.labels[3..]);
    assert_eq!(after.frames.len(), spec.frames - 3);
    // Times stay the recording's: the first kept frame is at 3 / fps.
    assert!((after.time_s(0) - 3.0 / spec.fps).abs() < 1e-12);
    assert_eq!(
        data.trim_lead_ins(),
        (0, 0),
        "trimming twice drops nothing more"
    );
}

/// Sets `render.center_region` of one sequence's record.
fn set_center_region(json: &std::path::Path, value: serde_json::Value) {
    set_record(json, &["render", "center_region"], value);
}

#[test]
fn a_crop_wider_than_the_rendered_centre_is_refused_naming_the_file() {
    // Frames large enough for a 0.42 crop to stay above the backbone's
    // minimum square.
    let (dir, _) = generated_at(64);
    let fail = BadData::new(OnBadData::Fail);
    let data = read_dataset(dir.path(), &ReaderOptions::default(), &fail).unwrap();
    let json = data.sequences[1].dir.join("sequence.json");
    set_center_region(&json, serde_json::json!(0.5));
    let crop = |c: Option<f64>| ReaderOptions {
        crop: c.map_or(Crop::Whole, fraction),
        ..ReaderOptions::default()
    };
    // Inside the rendered centre: read as before.
    let inside = read_dataset(dir.path(), &crop(Some(0.42)), &fail).unwrap();
    assert_eq!(inside.sequences.len(), data.sequences.len());
    // The rendered region travels with the sequence (augmented views keep
    // inside it); whole frames record none.
    assert_eq!(inside.sequences[1].rendered_region, Some(0.5));
    assert_eq!(inside.sequences[0].rendered_region, None);
    assert!(read_dataset(dir.path(), &crop(Some(0.5)), &fail).is_ok());
    // Wider, or whole frames: the model would see the black surround.
    for c in [Some(0.6), None] {
        let err = format!(
            "{:#}",
            read_dataset(dir.path(), &crop(c), &fail).unwrap_err()
        );
        assert!(err.contains(&json.display().to_string()), "{err}");
        assert!(err.contains("rendered only in their central 0.5"), "{err}");
    }
    // A value that is no fraction is bad data: skipped and reported.
    set_center_region(&json, serde_json::json!(-2));
    let skip = BadData::new(OnBadData::Skip);
    let read = read_dataset(dir.path(), &crop(Some(0.42)), &skip).unwrap();
    assert_eq!(read.sequences.len(), data.sequences.len() - 1);
    assert_eq!(skip.problems()[0].path, json);
}

#[test]
fn a_sensor_probe_degrades_each_frame_before_the_crop() {
    use trainer::data::probe::SensorProbe;
    let (dir, _) = generated();
    let opts = ReaderOptions {
        crop: fraction(0.5),
        ..ReaderOptions::default()
    };
    let bad = BadData::new(OnBadData::Fail);
    let data = read_dataset(dir.path(), &opts, &bad).unwrap();
    let mut seq = data.sequences[0].clone();
    let plain = seq.load_frame(1, &bad).unwrap().unwrap();
    let probe = SensorProbe {
        noise_sigma: 0.05,
        blur_sigma_px: 1.0,
    };
    seq.probe = Some(probe);
    let probed = seq.load_frame(1, &bad).unwrap().unwrap();
    assert_eq!(probed.dimensions(), plain.dimensions());
    assert_ne!(probed, plain);
    let raw = trainer::data::images::load_frame(&seq.frames[1], &bad)
        .unwrap()
        .unwrap();
    let expect = probe.apply(&raw, &format!("{}/1", seq.id));
    assert_eq!(probed, trainer::data::images::center_crop(&expect, 0.5));
}

/// Sets `plan.intrinsics` of one sequence's record to a square lens of
/// focal length `focal` pixels.
fn set_focal(json: &std::path::Path, focal: f64) {
    for axis in ["fx", "fy"] {
        set_record(
            json,
            &["plan", "intrinsics", axis],
            serde_json::json!(focal),
        );
    }
}

#[test]
fn a_fixed_angle_crop_takes_the_fraction_each_lens_needs() {
    // Large enough frames that the widest lens's square (0.2) is no
    // smaller than the backbone's minimum.
    let (dir, _) = generated_at(100);
    let fail = BadData::new(OnBadData::Fail);
    let data = read_dataset(dir.path(), &ReaderOptions::default(), &fail).unwrap();
    let k = {
        let json = data.sequences[0].dir.join("sequence.json");
        let record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
        record["plan"]["intrinsics"].clone()
    };
    let (w, h) = (
        k["width"].as_u64().unwrap() as u32,
        k["height"].as_u64().unwrap() as u32,
    );
    let focal = k["fy"].as_f64().unwrap();
    // The angle that 0.4 of this lens spans; sequence 1 gets a lens twice
    // as wide, sequence 2 one too narrow for the angle in its rendered 0.5.
    let angle = grasp_schema::dataset::crop_angle_deg(0.4, focal, w, h);
    let wide = data.sequences[1].dir.join("sequence.json");
    let narrow = data.sequences[2].dir.join("sequence.json");
    set_focal(&wide, focal / 2.0);
    set_focal(&narrow, focal * 1.5);
    set_center_region(&narrow, serde_json::json!(0.5));
    let opts = ReaderOptions {
        crop: Crop::AngleDeg(angle),
        ..ReaderOptions::default()
    };
    let read = read_dataset(dir.path(), &opts, &fail).unwrap();
    let crop_of = |json: &std::path::Path| {
        read.sequences
            .iter()
            .find(|s| s.dir.join("sequence.json") == json)
            .unwrap()
            .crop_fraction(w, h)
            .unwrap()
            .unwrap()
    };
    let first = read.sequences[0].dir.join("sequence.json");
    assert!((crop_of(&first) - 0.4).abs() < 1e-9);
    assert!((crop_of(&wide) - 0.2).abs() < 1e-9);
    // 0.6 is needed, 0.5 was rendered: cut down to it, not refused.
    assert!((crop_of(&narrow) - 0.5).abs() < 1e-9);
    // Frames seen through the wide lens are the smaller square.
    let seq = read
        .sequences
        .iter()
        .find(|s| s.dir.join("sequence.json") == wide)
        .unwrap();
    let frame = seq.load_frame(0, &fail).unwrap().unwrap();
    let side = grasp_schema::dataset::centre_square(w, h, 0.2).2;
    assert_eq!(frame.dimensions(), (side, side));
}

#[test]
fn a_fixed_angle_crop_needs_intrinsics_and_excludes_the_fraction_crop() {
    let fail = BadData::new(OnBadData::Fail);
    let both = Crop::from_options(Some(0.4), Some(18.0)).unwrap_err();
    assert!(both.to_string().contains("both"), "{both}");
    let (dir, _) = generated();
    for bad_angle in [0.0, 180.0, f64::NAN] {
        let opts = ReaderOptions {
            crop: Crop::AngleDeg(bad_angle),
            ..ReaderOptions::default()
        };
        let err = format!("{:#}", read_dataset(dir.path(), &opts, &fail).unwrap_err());
        assert!(err.contains("crop.angle_deg"), "{err}");
    }
    // The authors' layout records no lens: refused, naming the folder.
    let real = tempfile::tempdir().unwrap();
    write_synthetic(real.path(), &SyntheticSpec::small(Layout::Authors)).unwrap();
    // The angle that half of a 32 px frame spans at a focal length of 40 px.
    let angle = grasp_schema::dataset::crop_angle_deg(0.5, 40.0, 32, 32);
    let mut opts = ReaderOptions {
        crop: Crop::AngleDeg(angle),
        ..ReaderOptions::default()
    };
    let err = format!("{:#}", read_dataset(real.path(), &opts, &fail).unwrap_err());
    assert!(err.contains("focal length") && err.contains("rgb"), "{err}");
    assert!(
        err.contains("--focal-px") && err.contains("--hfov-deg"),
        "{err}"
    );
    // Given the camera's lens, it reads, and each frame is cut at the
    // angle through that lens at the frame's own size.
    let hfov = 2.0 * (16.0f64 / 40.0).atan().to_degrees();
    opts.lens = Some(Lens::horizontal_fov(hfov).unwrap());
    let read = read_dataset(real.path(), &opts, &fail).unwrap();
    let seq = &read.sequences[0];
    let f = seq.crop_fraction(32, 32).unwrap().unwrap();
    assert!((f - 0.5).abs() < 1e-9, "{f}");
    // Twice the frame size: the same angle, the same fraction.
    let f = seq.crop_fraction(64, 64).unwrap().unwrap();
    assert!((f - 0.5).abs() < 1e-9, "{f}");
    let frame = seq.load_frame(0, &fail).unwrap().unwrap();
    assert_eq!(frame.dimensions(), (16, 16));
}

#[test]
fn denoising_filters_the_crop_the_backbone_sees() {
    let (dir, _) = generated();
    let bad = BadData::new(OnBadData::Fail);
    let opts = |denoise| ReaderOptions {
        crop: fraction(0.5),
        denoise,
        ..ReaderOptions::default()
    };
    let plain = read_dataset(dir.path(), &opts(false), &bad).unwrap();
    let denoised = read_dataset(dir.path(), &opts(true), &bad).unwrap();
    assert!(denoised.sequences.iter().all(|s| s.denoise));
    let mut seq = plain.sequences[0].clone();
    // A noisy camera (a sensor view's), then the crop, then the filter.
    seq.probe = Some(trainer::data::probe::SensorProbe {
        noise_sigma: 0.04,
        blur_sigma_px: 0.0,
    });
    let noisy = seq.load_frame(1, &bad).unwrap().unwrap();
    seq.denoise = true;
    let filtered = seq.load_frame(1, &bad).unwrap().unwrap();
    assert_eq!(filtered, grasp_model::input::denoise::denoise(&noisy));
    let noise = grasp_model::input::denoise::noise_sigma;
    assert!(
        noise(&filtered) < 0.75 * noise(&noisy),
        "{} -> {}",
        noise(&noisy),
        noise(&filtered)
    );
}

/// Sets one value of a sequence's record, by JSON pointer path.
fn set_record(json: &std::path::Path, path: &[&str], value: serde_json::Value) {
    let mut record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    let mut at = &mut record;
    for key in &path[..path.len() - 1] {
        at = &mut at[*key];
    }
    at[path[path.len() - 1]] = value;
    std::fs::write(json, record.to_string()).unwrap();
}

/// A test world's sequences (another render world, a held-out reach) are
/// read and can be scored, but never go into a training or validation set.
#[test]
fn test_worlds_are_read_but_never_trained_or_validated_on() {
    let (dir, _) = generated();
    let fail = BadData::new(OnBadData::Fail);
    let data = read_dataset(dir.path(), &ReaderOptions::default(), &fail).unwrap();
    assert!(data.sequences.iter().all(|s| s.test_world.is_none()));
    let cfg = trainer::config::TrainConfig {
        data: dir.path().to_path_buf(),
        ..Default::default()
    };
    trainer::train::load_splits(&DataPlan::of(&cfg), &fail).unwrap();

    let foreign = data.sequences[0].dir.join("sequence.json");
    set_record(&foreign, &["render", "world"], serde_json::json!("foreign"));
    let reach = data.sequences[1].dir.join("sequence.json");
    set_record(
        &reach,
        &["plan", "sampled", "held_out"],
        serde_json::json!("reach"),
    );
    let marked = read_dataset(dir.path(), &ReaderOptions::default(), &fail).unwrap();
    assert_eq!(
        marked.sequences[0].test_world.as_deref(),
        Some("render.world = \"foreign\"")
    );
    assert_eq!(
        marked.sequences[1].test_world.as_deref(),
        Some("dataset.held_out = \"reach\"")
    );
    let err = format!(
        "{:#}",
        trainer::train::load_splits(&DataPlan::of(&cfg), &fail).unwrap_err()
    );
    assert!(err.contains("belongs to a test world"), "{err}");
    assert!(err.contains(&dir.path().display().to_string()), "{err}");
    // As a separate validation set it is refused too.
    let (train, _) = generated();
    let as_val = trainer::config::TrainConfig {
        data: train.path().to_path_buf(),
        val_data: Some(dir.path().to_path_buf()),
        ..Default::default()
    };
    let err = format!(
        "{:#}",
        trainer::train::load_splits(&DataPlan::of(&as_val), &fail).unwrap_err()
    );
    assert!(err.contains("the validation set"), "{err}");
}
