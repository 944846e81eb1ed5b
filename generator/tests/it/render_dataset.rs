//! Renders a few hand-made sequences with real Blender workers (Workbench,
//! 48 px, 3 frames) and checks the dataset with `dataset verify`, shards and
//! merge, and the crashed-worker retry.

use crate::render_common::*;
use generator::dataset::{merge::merge, verify::verify};
use generator::render::{render, Shard};
use grasp_schema::dataset::{ManifestEntry, MANIFEST_FILE};
use std::sync::Arc;

#[test]
fn render_then_verify() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let src = Arc::new(source(4, 3, 48));
    let s = render(src.clone(), &workbench(), &options(dir.path(), 2)).unwrap();
    assert_eq!((s.rendered, s.frames, s.failed.len()), (4, 12, 0), "{s:?}");
    let report = verify(dir.path(), Some(src.as_ref()), true).unwrap();
    assert!(report.ok(), "{}", report.render_text());
    assert_eq!(report.sequences, 4);
    assert_eq!(report.counts["a_box/body"].values().sum::<usize>(), 2);
    let manifest = std::fs::read_to_string(dir.path().join(MANIFEST_FILE)).unwrap();
    let entries: Vec<ManifestEntry> = manifest
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(entries.len(), 4);
    assert_eq!(entries[0].path, "box/a_box/power_no3/Wrist_d435/rgb00000");
    // Frames are real images of the right size, not blank.
    let img = image::open(dir.path().join(&entries[0].path).join("00002.png"))
        .unwrap()
        .to_rgb8();
    assert_eq!(img.dimensions(), (48, 48));
    let first = img.get_pixel(0, 0);
    assert!(img.pixels().any(|p| p != first), "a uniform frame");

    // A corrupt frame and a missing manifest line are caught.
    std::fs::write(
        dir.path().join(&entries[1].path).join("00001.png"),
        b"not a png",
    )
    .unwrap();
    let lines: Vec<&str> = manifest.lines().skip(1).collect();
    std::fs::write(dir.path().join(MANIFEST_FILE), lines.join("\n")).unwrap();
    let report = verify(dir.path(), None, false).unwrap();
    assert_eq!(report.problems.len(), 2, "{:?}", report.problems);
    assert!(report.problems.iter().any(|p| p.contains("00001.png")));
    assert!(report.problems.iter().any(|p| p.contains("not listed")));
}

#[test]
fn shards_merge_into_the_unsharded_dataset() {
    if !have_blender() {
        return;
    }
    let src = Arc::new(source(3, 2, 32));
    let (a, b, merged, whole) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    for (k, dir) in [(0, &a), (1, &b)] {
        let mut o = options(dir.path(), 1);
        o.shard = Shard { index: k, count: 2 };
        let s = render(src.clone(), &workbench(), &o).unwrap();
        assert_eq!(s.in_shard, if k == 0 { 2 } else { 1 });
    }
    let m = merge(
        merged.path(),
        &[a.path().to_path_buf(), b.path().to_path_buf()],
    )
    .unwrap();
    assert_eq!(m.copied, 3);
    // Merging again is a no-op.
    assert_eq!(
        merge(merged.path(), &[a.path().to_path_buf()])
            .unwrap()
            .already_present,
        2
    );
    render(src.clone(), &workbench(), &options(whole.path(), 1)).unwrap();
    // Workbench is deterministic: the merged shards equal an unsharded run, byte for byte.
    let (m, w) = (tree(merged.path()), tree(whole.path()));
    assert_eq!(m.keys().collect::<Vec<_>>(), w.keys().collect::<Vec<_>>());
    for (name, bytes) in &m {
        assert!(bytes == &w[name], "{name} differs");
    }
    assert!(verify(merged.path(), Some(src.as_ref()), true)
        .unwrap()
        .ok());
}

#[test]
fn crashed_worker_is_restarted_and_its_sequence_retried() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let marker = dir.path().join("crash-marker");
    let src = Arc::new(source(2, 2, 32));
    let out = dir.path().join("data");
    let mut opts = options(&out, 1);
    let crash = generator::render::worker::CRASH_ONCE_ENV.to_string();
    opts.worker_env = vec![(crash, marker.to_string_lossy().into_owned())];
    let s = render(src.clone(), &workbench(), &opts).unwrap();
    assert!(marker.exists(), "the worker never crashed");
    assert_eq!((s.rendered, s.retries, s.failed.len()), (2, 1, 0), "{s:?}");
    let report = verify(&out, Some(src.as_ref()), true).unwrap();
    assert!(report.ok(), "{}", report.render_text());
}
