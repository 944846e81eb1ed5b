//! A run stopped midway (as by Ctrl-C, plus the debris of a hard kill) and
//! then resumed gives the same dataset as an uninterrupted run: same
//! folders, labels and metadata, and with Workbench the same pixels.

use crate::render_common::*;
use generator::dataset::verify::verify;
use generator::render::render;
use grasp_schema::dataset::MANIFEST_FILE;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

#[test]
fn stopped_then_resumed_equals_uninterrupted() {
    if !have_blender() {
        return;
    }
    let src = Arc::new(source(5, 3, 32));
    let (whole, resumed) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    render(src.clone(), &workbench(), &options(whole.path(), 1)).unwrap();

    // Stop as soon as the first sequence is in the manifest.
    let opts = options(resumed.path(), 1);
    let stop = opts.stop.clone();
    let manifest = resumed.path().join(MANIFEST_FILE);
    let watcher = std::thread::spawn(move || {
        while std::fs::read_to_string(&manifest)
            .map(|t| t.is_empty())
            .unwrap_or(true)
        {
            std::thread::sleep(Duration::from_millis(20));
        }
        stop.store(true, Ordering::SeqCst);
    });
    let first = render(src.clone(), &workbench(), &opts).unwrap();
    watcher.join().unwrap();
    assert!(first.interrupted);
    assert!(first.rendered >= 1 && first.rendered < 5, "{first:?}");

    // A hard kill would also leave a partial sequence behind.
    let debris = resumed.path().join(".grasp-gen/partial/00000004-0");
    std::fs::create_dir_all(&debris).unwrap();
    std::fs::write(debris.join("00000.png"), b"half").unwrap();

    // Without --resume, a started dataset is refused.
    let err = render(src.clone(), &workbench(), &options(resumed.path(), 1)).unwrap_err();
    assert!(format!("{err:#}").contains("--resume"));

    let mut again = options(resumed.path(), 2);
    again.resume = true;
    let second = render(src.clone(), &workbench(), &again).unwrap();
    assert_eq!(second.skipped, first.rendered);
    assert_eq!(second.skipped + second.rendered, 5);
    assert!(!debris.exists());

    let (a, b) = (tree(whole.path()), tree(resumed.path()));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs");
    }
    let report = verify(resumed.path(), Some(src.as_ref()), true).unwrap();
    assert!(report.ok(), "{}", report.render_text());
}

/// A folder rendered with other settings (here: a dataset of 4 sequences
/// grown to 6, which numbers the folders differently) holds another
/// sequence than the one planned there: resuming is refused before anything
/// is rendered or overwritten, naming the folder and both sequences.
#[test]
fn resuming_with_settings_that_number_folders_differently_is_refused() {
    use generator::dataset::assign_folders;
    use generator::plan::PlanSource;
    use grasp_schema::dataset::{SequenceRecord, SEQUENCE_FILE};
    let out = tempfile::tempdir().unwrap();
    let src = source(6, 2, 16);
    let assigned = assign_folders(&src.keys().unwrap());
    // Another sequence sits in the folder planned for the second one.
    let (planned, other) = (&assigned[1], src.plans[4].clone());
    assert_ne!(planned.planned.key, other.key);
    let dir = out.path().join(&planned.rel_dir);
    std::fs::create_dir_all(&dir).unwrap();
    let record = SequenceRecord {
        plan: other.clone(),
        frame_files: vec!["00000.png".into(), "00001.png".into()],
        render: serde_json::json!({}),
        generator_version: "test".into(),
    };
    std::fs::write(
        dir.join(SEQUENCE_FILE),
        serde_json::to_vec(&record).unwrap(),
    )
    .unwrap();
    let written = std::fs::read(dir.join(SEQUENCE_FILE)).unwrap();

    let mut opts = options(out.path(), 1);
    opts.resume = true;
    let err = format!(
        "{:#}",
        render(Arc::new(src), &workbench(), &opts).unwrap_err()
    );
    assert!(err.contains(&planned.rel_dir), "{err}");
    assert!(err.contains(&other.key.id()), "{err}");
    assert!(err.contains(&planned.planned.key.id()), "{err}");
    assert!(err.contains("other settings"), "{err}");
    // Nothing was overwritten, and nothing rendered.
    assert_eq!(std::fs::read(dir.join(SEQUENCE_FILE)).unwrap(), written);
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
}

/// Issue 39: a dataset resumed after a change of a render setting that
/// changes pixels (`center_region`) would hold frames of two renders, and
/// `dataset verify --config` said ok. Resuming is refused, naming the field
/// and both values (so is another resolution); verify reports it; the
/// device, threads and PNG compression may differ.
#[test]
fn resuming_with_another_render_setting_is_refused_and_verify_reports_it() {
    use generator::dataset::verify::verify_config;
    use generator::render::{Device, RenderConfig, Shard};
    if !have_blender() {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let src = Arc::new(source(3, 2, 16));
    render(src.clone(), &workbench(), &options(out.path(), 1)).unwrap();
    // One sequence left to render, as after an interrupted run.
    let records = tree(out.path());
    let last = records
        .keys()
        .filter(|k| k.ends_with(grasp_schema::dataset::SEQUENCE_FILE))
        .max()
        .unwrap();
    let last_dir = out.path().join(last).parent().unwrap().to_path_buf();
    std::fs::remove_dir_all(&last_dir).unwrap();

    let cropped = RenderConfig {
        center_region: 0.5,
        ..workbench()
    };
    let mut opts = options(out.path(), 1);
    opts.resume = true;
    let err = format!("{:#}", render(src.clone(), &cropped, &opts).unwrap_err());
    assert!(err.contains("[render] center_region"), "{err}");
    assert!(
        err.contains("rendered with 1.0, the config has 0.5"),
        "{err}"
    );
    assert!(err.contains("1 more finished sequence(s) differ"), "{err}");
    assert!(!last_dir.exists(), "nothing rendered");

    let report = verify_config(out.path(), src.as_ref(), &cropped, false, Shard::ALL).unwrap();
    let text = report.render_text();
    assert!(!report.ok());
    assert!(
        text.contains("[render] center_region: rendered with 1.0, the config has 0.5"),
        "{text}"
    );
    assert!(text.contains("(2 sequence(s) so;"), "{text}");

    // The resolution is planned ([plan.camera]), not a [render] setting.
    let larger = Arc::new(source(3, 2, 24));
    let err = format!(
        "{:#}",
        render(larger.clone(), &workbench(), &opts).unwrap_err()
    );
    assert!(
        err.contains("[plan.camera] resolution: rendered at 16x16, the config plans 24x24"),
        "{err}"
    );
    assert!(!last_dir.exists(), "nothing rendered");

    // Where the pixels are computed may change: the resume goes through.
    let elsewhere = RenderConfig {
        device: Device::Cpu,
        threads: 1,
        png_compression: 50,
        ..workbench()
    };
    let s = render(src.clone(), &elsewhere, &opts).unwrap();
    assert_eq!((s.skipped, s.rendered), (2, 1), "{s:?}");
    let report = verify_config(out.path(), src.as_ref(), &workbench(), true, Shard::ALL).unwrap();
    assert!(report.ok(), "{}", report.render_text());
}
