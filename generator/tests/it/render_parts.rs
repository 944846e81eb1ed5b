//! The `part` pass on tiny renders (64 px, 2 frames): Workbench (object found
//! by the depth against the mesh) and Cycles at 1 sample (object index pass).
//! The camera ends facing the box's -Y side, so nearly every labelled pixel
//! of the last frame is the `sides` part; from the first, higher view the top
//! shows too. A scaled object (`plan.object.scale`) is drawn and labelled at
//! its scaled size.

use crate::render_common::*;
use generator::dataset::verify::verify;
use generator::render::{render, Engine, Pass, RenderConfig};
use grasp_schema::dataset::{part_file_name, ManifestEntry, SequenceRecord, MANIFEST_FILE};
use std::path::Path;
use std::sync::Arc;

fn labels(dir: &Path, frame: &str) -> Vec<u8> {
    image::open(dir.join(part_file_name(frame)))
        .unwrap()
        .to_luma8()
        .into_raw()
}

/// Renders a_box, seen from (0, -0.7, 1.15) then (0, -0.25, 0.9), with the
/// object scaled by `scale` and stretched by `proportions`; returns the
/// sequence folder.
fn render_box(
    config: &RenderConfig,
    scale: f64,
    proportions: [f64; 3],
    dir: &Path,
) -> std::path::PathBuf {
    let mut src = source(1, 2, 64);
    src.plans.truncate(1);
    src.plans[0].object.scale = scale;
    src.plans[0].object.proportions = proportions;
    let src = Arc::new(src);
    let s = render(src.clone(), config, &options(dir, 1)).unwrap();
    assert_eq!((s.rendered, s.failed.len()), (1, 0), "{s:?}");
    let manifest = std::fs::read_to_string(dir.join(MANIFEST_FILE)).unwrap();
    let entry: ManifestEntry = serde_json::from_str(manifest.lines().next().unwrap()).unwrap();
    dir.join(&entry.path)
}

/// Pixels labelled none, `top` and `sides`.
fn counts(l: &[u8]) -> [usize; 3] {
    [0u8, 1, 2].map(|k| l.iter().filter(|x| **x == k).count())
}

fn check(config: RenderConfig, keep_exr: bool) {
    let dir = tempfile::tempdir().unwrap();
    let mut src = source(1, 2, 64);
    src.plans.truncate(1); // a_box, seen from (0, -0.7, 1.15) then (0, -0.25, 0.9)
    let src = Arc::new(src);
    let s = render(src.clone(), &config, &options(dir.path(), 1)).unwrap();
    assert_eq!((s.rendered, s.failed.len()), (1, 0), "{s:?}");
    let report = verify(dir.path(), Some(src.as_ref()), true).unwrap();
    assert!(report.ok(), "{}", report.render_text());

    let manifest = std::fs::read_to_string(dir.path().join(MANIFEST_FILE)).unwrap();
    let entry: ManifestEntry = serde_json::from_str(manifest.lines().next().unwrap()).unwrap();
    let seq = dir.path().join(&entry.path);
    let record: SequenceRecord =
        serde_json::from_str(&std::fs::read_to_string(seq.join("sequence.json")).unwrap()).unwrap();
    assert_eq!(record.part_labels().unwrap(), ["top", "sides"]);
    assert_eq!(seq.join("00000.exr").exists(), keep_exr);

    let last = labels(&seq, "00001.png");
    let [_, top, sides] = counts(&last);
    assert!(sides > 160, "{:?}", counts(&last));
    assert!(
        sides as f64 >= 0.9 * (top + sides) as f64,
        "{:?}",
        counts(&last)
    );
    let [_, top, sides] = counts(&labels(&seq, "00000.png"));
    assert!(
        top > 5 && sides > 5,
        "first frame: top {top}, sides {sides}"
    );
}

#[test]
fn part_labels_from_workbench_depth() {
    if !have_blender() {
        return;
    }
    let mut c = workbench();
    c.passes = vec![Pass::Rgb, Pass::Part];
    check(c, false);
}

/// Cycles, one sample, with the object-index and part passes.
fn cycles_with_parts() -> RenderConfig {
    RenderConfig {
        engine: Engine::Cycles,
        samples: 1,
        denoiser: "none".into(),
        passes: vec![Pass::Rgb, Pass::Instance, Pass::Part],
        ..Default::default()
    }
}

#[test]
fn part_labels_from_cycles_object_index() {
    if !have_blender() {
        return;
    }
    check(cycles_with_parts(), true);
}

#[test]
fn a_scaled_object_is_drawn_and_labelled_at_its_size() {
    if !have_blender() {
        return;
    }
    // Cycles' object index says which pixels Blender drew as the object.
    let c = cycles_with_parts();
    let (small, large) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let small = counts(&labels(
        &render_box(&c, 0.8, [1.0; 3], small.path()),
        "00001.png",
    ));
    let large = counts(&labels(
        &render_box(&c, 1.25, [1.0; 3], large.path()),
        "00001.png",
    ));
    let object = |c: [usize; 3]| c[1] + c[2];
    assert!(object(small) > 100, "0.8: {small:?}");
    // The drawn area grows at least with the square of the scale, (1.25 /
    // 0.8)^2 = 2.4 (more, as the larger box comes nearer the camera), and
    // every pixel of it lies in a part box at the plan's scale. Drawn at
    // the catalog's size both times, it would grow by about 1.4.
    let ratio = object(large) as f64 / object(small) as f64;
    assert!((2.2..5.0).contains(&ratio), "{small:?} against {large:?}");
}

/// `plan.object.proportions` (`[randomize.proportions]`) reaches Blender and
/// the labels: seen from the -Y side, the box stretched x 1.4 along X (and
/// / 1.4 along Y) shows a face about 1.4 x 1.4 = 2 times wider than the box
/// stretched the other way, and its pixels are labelled at the plan's
/// proportions. Drawn or labelled unstretched, both would match.
#[test]
fn a_stretched_object_is_drawn_and_labelled_at_its_proportions() {
    if !have_blender() {
        return;
    }
    let c = cycles_with_parts();
    let (wide, narrow) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let k = 1.4;
    let wide = counts(&labels(
        &render_box(&c, 1.0, [k, 1.0 / k, 1.0], wide.path()),
        "00001.png",
    ));
    let narrow = counts(&labels(
        &render_box(&c, 1.0, [1.0 / k, k, 1.0], narrow.path()),
        "00001.png",
    ));
    let object = |c: [usize; 3]| c[1] + c[2];
    assert!(object(narrow) > 60, "narrow: {narrow:?}");
    // The narrow box's face also comes (k - 1/k) x half its depth nearer
    // the camera, which enlarges it a little: the ratio stays below 2.
    let ratio = object(wide) as f64 / object(narrow) as f64;
    assert!((1.4..2.4).contains(&ratio), "{wide:?} against {narrow:?}");
}
