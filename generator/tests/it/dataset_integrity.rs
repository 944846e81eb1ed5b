//! Damaged or incomplete datasets never read `ok` (issue 15, item 5):
//! `dataset verify` checks every file's structure by default (PNG chunk
//! CRCs up to IEND, EXR chunks, `sequence.json`), names every configured
//! sequence that is missing, and `render --resume` re-renders sequences
//! whose files are missing or cut short.

use crate::render_common::*;
use generator::dataset::verify::{verify, verify_shard};
use generator::render::{render, Pass, Shard};
use grasp_schema::dataset::{ManifestEntry, MANIFEST_FILE, SEQUENCE_FILE};
use std::path::Path;
use std::sync::Arc;

fn entries(root: &Path) -> Vec<ManifestEntry> {
    std::fs::read_to_string(root.join(MANIFEST_FILE))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Keeps the first half of a file, as a full disk or a killed writer does.
fn truncate(path: &Path) {
    let bytes = std::fs::read(path).unwrap();
    assert!(bytes.len() > 100, "{} is too small to cut", path.display());
    std::fs::write(path, &bytes[..bytes.len() / 2]).unwrap();
}

fn problems_text(root: &Path, source: &dyn generator::plan::PlanSource) -> String {
    let report = verify(root, Some(source), false).unwrap();
    assert!(!report.ok(), "verify passed:\n{}", report.render_text());
    report.problems.join("\n")
}

#[test]
fn verify_catches_cut_short_frames_masks_exrs_and_records_without_decoding() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let src = Arc::new(source(3, 2, 32));
    let mut config = workbench();
    config.passes = vec![Pass::Rgb, Pass::Depth, Pass::Part];
    render(src.clone(), &config, &options(dir.path(), 1)).unwrap();
    let clean = verify(dir.path(), Some(src.as_ref()), false).unwrap();
    assert!(clean.ok(), "{}", clean.render_text());

    let seqs = entries(dir.path());
    let seq = |i: usize| dir.path().join(&seqs[i].path);
    truncate(&seq(0).join("00001.png"));
    truncate(&seq(1).join("part00000.png"));
    truncate(&seq(1).join("00001.exr"));
    truncate(&seq(2).join(SEQUENCE_FILE));
    let text = problems_text(dir.path(), src.as_ref());
    for damaged in [
        format!("{}/00001.png: truncated", seqs[0].path),
        format!("{}/part00000.png: truncated", seqs[1].path),
        format!("{}/00001.exr", seqs[1].path),
        format!("{}: invalid sequence record", seqs[2].path),
    ] {
        assert!(text.contains(&damaged), "{damaged} not reported:\n{text}");
    }
    // A flipped byte inside a PNG (same length) fails its chunk CRC.
    let frame = seq(0).join("00000.png");
    let mut bytes = std::fs::read(&frame).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x40;
    std::fs::write(&frame, bytes).unwrap();
    let text = problems_text(dir.path(), src.as_ref());
    assert!(text.contains("00000.png: chunk IDAT"), "{text}");
}

#[test]
fn verify_names_the_configured_sequences_that_are_missing() {
    // No Blender needed: an all-failed render leaves an empty dataset.
    let dir = tempfile::tempdir().unwrap();
    let src = source(9, 2, 32);
    std::fs::write(dir.path().join(MANIFEST_FILE), "").unwrap();
    let report = verify(dir.path(), Some(&src), false).unwrap();
    assert!(!report.ok());
    let text = report.problems.join("\n");
    assert!(
        text.contains("9 of the 9 configured sequences are missing"),
        "{text}"
    );
    assert!(
        text.contains(
            "missing sequence box/a_box/power_no3/Wrist_d435/rgb00000 (a_box/body/default/00000)"
        ),
        "{text}"
    );
}

#[test]
fn verify_of_an_incomplete_dataset_lists_what_is_missing() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let src = Arc::new(source(4, 2, 32));
    render(src.clone(), &workbench(), &options(dir.path(), 1)).unwrap();
    let seqs = entries(dir.path());
    // As after a disk-full: two sequences gone, the manifest rebuilt.
    for e in &seqs[1..3] {
        std::fs::remove_dir_all(dir.path().join(&e.path)).unwrap();
    }
    let kept: Vec<String> = [&seqs[0], &seqs[3]]
        .iter()
        .map(|e| serde_json::to_string(e).unwrap())
        .collect();
    std::fs::write(dir.path().join(MANIFEST_FILE), kept.join("\n") + "\n").unwrap();
    let text = problems_text(dir.path(), src.as_ref());
    assert!(
        text.contains("2 of the 4 configured sequences are missing"),
        "{text}"
    );
    for e in &seqs[1..3] {
        assert!(
            text.contains(&format!("missing sequence {} ({})", e.path, e.id)),
            "{text}"
        );
    }
}

#[test]
fn a_shard_verifies_against_its_own_sequences_only() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let src = Arc::new(source(3, 2, 32));
    let shard = Shard { index: 1, count: 2 };
    let mut opts = options(dir.path(), 1);
    opts.shard = shard;
    render(src.clone(), &workbench(), &opts).unwrap();
    let own = verify_shard(dir.path(), Some(src.as_ref()), false, shard).unwrap();
    assert!(own.ok(), "{}", own.render_text());
    let whole = verify(dir.path(), Some(src.as_ref()), false).unwrap();
    assert!(whole
        .problems
        .iter()
        .any(|p| p.contains("2 of the 3 configured sequences are missing")));
}

#[test]
fn resume_rerenders_sequences_with_missing_or_cut_short_frames() {
    if !have_blender() {
        return;
    }
    let src = Arc::new(source(4, 3, 32));
    let (whole, damaged) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    render(src.clone(), &workbench(), &options(whole.path(), 1)).unwrap();
    render(src.clone(), &workbench(), &options(damaged.path(), 1)).unwrap();
    let seqs = entries(damaged.path());
    truncate(&damaged.path().join(&seqs[0].path).join("00002.png"));
    std::fs::remove_file(damaged.path().join(&seqs[2].path).join("00000.png")).unwrap();

    let mut again = options(damaged.path(), 1);
    again.resume = true;
    let s = render(src.clone(), &workbench(), &again).unwrap();
    assert_eq!((s.skipped, s.redone, s.rendered), (2, 2, 2), "{s:?}");
    // Workbench is deterministic: the repaired dataset equals the whole one.
    let (a, b) = (tree(whole.path()), tree(damaged.path()));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs");
    }
    let report = verify(damaged.path(), Some(src.as_ref()), false).unwrap();
    assert!(report.ok(), "{}", report.render_text());
}
