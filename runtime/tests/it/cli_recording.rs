//! `hannes-run replay` of recordings whose size differs from the size their
//! lens was measured at: the fixed-angle crop is cut at the same angle; and
//! `hannes-run bench` timing a recording's frames through its lens.

use crate::cli_common::*;
use std::path::{Path, PathBuf};

/// The stand-in checkpoint, copied with a fixed-angle crop of `angle_deg`.
fn angle_checkpoint(dir: &Path, angle_deg: f64) -> PathBuf {
    let ckpt = dir.join("angle-ckpt");
    std::fs::create_dir_all(&ckpt).unwrap();
    for entry in std::fs::read_dir(checkpoint()).unwrap().flatten() {
        std::fs::copy(entry.path(), ckpt.join(entry.file_name())).unwrap();
    }
    let json = ckpt.join("best.json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    meta["input"]["crop"] = serde_json::json!({ "angle_deg": angle_deg });
    std::fs::write(&json, serde_json::to_vec(&meta).unwrap()).unwrap();
    ckpt
}

/// A recording of `frames` whose sequence.json gives a square lens of
/// `focal` px at `lens_size` px.
fn recording(dir: &Path, frames: &[image::RgbImage], lens_size: u32, focal: f64) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut files = Vec::new();
    for (i, f) in frames.iter().enumerate() {
        let name = format!("{i:05}.png");
        f.save(dir.join(&name)).unwrap();
        files.push(name);
    }
    let record = serde_json::json!({
        "frame_files": files,
        "plan": {"fps": 10.0, "intrinsics": {
            "width": lens_size, "height": lens_size, "fx": focal, "fy": focal}},
    });
    std::fs::write(dir.join("sequence.json"), record.to_string()).unwrap();
    dir.to_path_buf()
}

/// Replay's per-frame rows without the timing column.
fn replay_rows(ckpt: &Path, seq: &Path) -> Vec<String> {
    let out = hannes_run(&[
        "replay",
        "--checkpoint",
        ckpt.to_str().unwrap(),
        "--source",
        seq.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    text(&out.stdout)
        .lines()
        .skip(1)
        .take_while(|l| !l.starts_with("decision"))
        .map(|l| {
            let mut words: Vec<&str> = l.split_whitespace().collect();
            words.pop(); // the timing
            words.join(" ")
        })
        .collect()
}

/// A recording scaled to half the size its sequence.json's intrinsics
/// were written for is cut at the checkpoint's angle through the lens
/// scaled with it: the same rows as the same frames with matching
/// intrinsics (it once got the full-size focal length, twice the crop and
/// a wrong pre-shape). Replay's JSON names the checkpoint, its input record
/// and the lens.
#[test]
fn a_recording_at_another_size_than_its_intrinsics_is_cut_at_the_same_angle() {
    let dir = tempfile::tempdir().unwrap();
    let focal = 32.0 / 21f64.to_radians().tan();
    let angle = grasp_schema::dataset::crop_angle_deg(0.5, focal, 64, 64);
    let ckpt = angle_checkpoint(dir.path(), angle);
    let frames: Vec<image::RgbImage> = (0..3)
        .map(|k| {
            image::RgbImage::from_fn(32, 32, |x, y| {
                let centre = (8..24).contains(&x) && (8..24).contains(&y);
                let v = if centre {
                    200 - 40 * k
                } else {
                    (x * 7 + y * 3) as u8
                };
                image::Rgb([v, (x * 8) as u8, (y * 8) as u8])
            })
        })
        .collect();
    let scaled = recording(&dir.path().join("scaled"), &frames, 64, focal);
    let matching = recording(&dir.path().join("matching"), &frames, 32, focal / 2.0);
    let rows = replay_rows(&ckpt, &scaled);
    assert_eq!(rows.len(), 3);
    assert_eq!(rows, replay_rows(&ckpt, &matching));

    let out = hannes_run(&[
        "replay",
        "--checkpoint",
        ckpt.to_str().unwrap(),
        "--source",
        scaled.to_str().unwrap(),
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let model = &json["model"];
    assert_eq!(model["checkpoint"], ckpt.to_str().unwrap());
    assert_eq!(model["input"]["crop"]["angle_deg"], angle);
    assert_eq!(model["lens"]["focal"]["width"], 64);
    assert_eq!(model["lens_from"], "sequence.json");
    assert!(json["decision"].is_object(), "{json}");

    // A focal length in millimetres is refused by name, not cut under a pixel.
    let out = hannes_run(&[
        "replay",
        "--checkpoint",
        ckpt.to_str().unwrap(),
        "--source",
        scaled.to_str().unwrap(),
        "--focal-px",
        "1.93",
        "--lens-size",
        "640x480",
    ]);
    assert!(!out.status.success());
    let reason = last_line(&out.stderr);
    assert!(
        reason.contains("focal_px") && reason.contains("field of view"),
        "{reason}"
    );
}

/// `bench --recording` times a recording's own frames, repeated in order,
/// through the lens its sequence.json records, and says so; a bare PNG
/// folder needs the lens flags for a fixed-angle checkpoint, and a broken
/// frame is named.
#[test]
fn bench_times_the_frames_of_a_recording_through_its_lens() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = angle_checkpoint(dir.path(), 30.0);
    let ckpt = ckpt.to_str().unwrap();
    let bench = |recording: &Path, extra: &[&str]| {
        let source = ["--recording", recording.to_str().unwrap()];
        bench_inference(ckpt, "7", &[&source[..], extra].concat())
    };
    let frames: Vec<image::RgbImage> = (0..3u8)
        .map(|k| {
            image::RgbImage::from_fn(32, 32, |x, y| {
                image::Rgb([k * 60, (x * 8) as u8, (y * 8) as u8])
            })
        })
        .collect();
    let focal = 16.0 / 21f64.to_radians().tan();
    let seq = recording(&dir.path().join("rec"), &frames, 32, focal);
    let out = bench(&seq, &[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report = text(&out.stdout);
    let expected = format!(
        "inference 32x32 of {} (7 frames, back to back)",
        seq.display()
    );
    assert!(report.contains(&expected), "{report}");

    let bare = sequence(dir.path(), 2, None);
    let out = bench(&bare, &[]);
    assert!(!out.status.success());
    assert!(
        last_line(&out.stderr).contains("lens"),
        "{}",
        text(&out.stderr)
    );
    let out = bench(&bare, &["--hfov-deg", "42"]);
    assert!(out.status.success(), "{}", text(&out.stderr));

    let other = tempfile::tempdir().unwrap();
    let broken = sequence(other.path(), 3, Some(1));
    let out = bench(&broken, &["--hfov-deg", "42"]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("frame_0001.png"),
        "{}",
        text(&out.stderr)
    );
}
