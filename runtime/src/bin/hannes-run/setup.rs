//! What `run`, `replay` and `bench` set up the same way: the signal
//! handlers, the config (file, then flags), the frame source and the lens
//! the classifier crops through.

use crate::args::{PolicyArgs, SourceArgs};
use anyhow::{Context, Result};
use grasp_cli::LensArgs;
use grasp_model::checkpoint::Classifier;
use grasp_model::input::{Crop, Lens};
use runtime::config::RuntimeConfig;
use runtime::source::{FrameSource, Pacing, SequenceFolder};
use std::path::Path;

pub(crate) fn stop_flag() -> Result<&'static std::sync::atomic::AtomicBool> {
    runtime::signals::stop_flag().context("cannot install the signal handlers")
}

pub(crate) fn config(policy_args: &PolicyArgs) -> Result<RuntimeConfig> {
    let mut cfg = match &policy_args.config {
        Some(path) => RuntimeConfig::load(path)?,
        None => RuntimeConfig::default(),
    };
    policy_args
        .decision
        .apply(&mut cfg.policy)
        .context("--fallback")?;
    let policy = &mut cfg.policy;
    if let Some(ms) = policy_args.max_decision_age_ms {
        policy.max_decision_age_ms = ms;
    }
    cfg.validate()?;
    Ok(cfg)
}

/// Opens the frame source; returns it with whether it is live. The
/// classifier learns the camera's lens (the flags', else the recording's),
/// and a recording must hold every pixel its crop looks at.
pub(crate) fn open_source(
    source_args: &SourceArgs,
    pacing: Pacing,
    classifier: &mut Classifier,
) -> Result<(Box<dyn FrameSource>, bool)> {
    if let Some(rest) = source_args.source.strip_prefix("camera") {
        set_lens(classifier, source_args.lens.lens()?, &source_args.source)?;
        let device = rest.strip_prefix(':').unwrap_or("/dev/video0");
        return Ok((open_camera(Path::new(device))?, true));
    }
    let folder = open_recording(
        &source_args.source,
        source_args.fps,
        &source_args.lens,
        pacing,
        classifier,
    )?;
    Ok((Box::new(folder), false))
}

/// Opens a recording for `classifier`: sets the lens its crop needs
/// (`lens_args`' if given, else the one `sequence.json` records) and
/// checks, at the frames' own size, that the recording holds every pixel
/// the crop sees.
pub(crate) fn open_recording(
    source: &str,
    fps: Option<f64>,
    lens_args: &LensArgs,
    pacing: Pacing,
    classifier: &mut Classifier,
) -> Result<SequenceFolder> {
    let dir = Path::new(source);
    let folder = SequenceFolder::open(dir, fps, pacing)?;
    let lens = match lens_args.lens()? {
        Some(lens) => Some(lens),
        None => folder.info().lens()?,
    };
    set_lens(classifier, lens, source)?;
    let (width, height) = folder.frame_size()?;
    let crop = classifier.crop_fraction(width, height).with_context(|| {
        format!(
            "cannot crop the {width}x{height} frames of {}",
            dir.display()
        )
    })?;
    folder.info().check_crop(crop, dir)?;
    Ok(folder)
}

/// Gives the classifier the camera's lens; one that crops a fixed angle
/// refuses to start without it.
pub(crate) fn set_lens(
    classifier: &mut Classifier,
    lens: Option<Lens>,
    source: &str,
) -> Result<()> {
    match (lens, classifier.input().crop) {
        (Some(lens), _) => classifier.set_lens(lens),
        (None, Crop::AngleDeg(angle)) => anyhow::bail!(
            "the checkpoint crops a fixed angle of {angle} degrees, so it needs the camera's \
             lens: {source} does not record one (no sequence.json with plan.intrinsics); give \
             --focal-px with --lens-size, --hfov-deg or --lens-file"
        ),
        (None, _) => {}
    }
    Ok(())
}

#[cfg(feature = "camera")]
pub(crate) fn open_camera(device: &Path) -> Result<Box<dyn FrameSource>> {
    Ok(Box::new(runtime::camera::Camera::open(
        device, 640, 480, 30,
    )?))
}

#[cfg(not(feature = "camera"))]
pub(crate) fn open_camera(device: &Path) -> Result<Box<dyn FrameSource>> {
    anyhow::bail!(
        "cannot open {}: hannes-run was built without the `camera` feature \
         (rebuild with `cargo build --release -p runtime --features camera`)",
        device.display()
    )
}
