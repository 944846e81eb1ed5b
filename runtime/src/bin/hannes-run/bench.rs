//! Latency measurements for `hannes-run bench`: per-frame inference, the
//! host-to-hand link round trip, and trigger-to-command for whole approaches
//! against a simulated hand on a pseudo-terminal.

use crate::args::{BenchArgs, Stage};
use crate::setup::{open_recording, set_lens};
use anyhow::Result;
use grasp_cli::LensArgs;
use grasp_model::checkpoint::Classifier;
use grasp_model::input::Lens;
use grasp_schema::taxonomy::Preshape;
use image::RgbImage;
use runtime::approach::{actuate, classify_window};
use runtime::classifier::FrameClassifier;
use runtime::feed::FeedMode;
use runtime::link::{Hand, HandLink, LinkConfig};
use runtime::policy::PolicyConfig;
use runtime::protocol::preshape_command;
use runtime::simhand::PtyHand;
use runtime::source::{FrameSource, MemorySource, Pacing};
use runtime::transport::SerialConnector;
use serde::Serialize;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

pub(crate) fn command(args: BenchArgs) -> Result<()> {
    let mut classifier = runtime::model::load(&args.checkpoint)?;
    let period = pace_period(args.pace)?;
    let (frames, from) = match &args.recording {
        Some(dir) => (
            recording_frames(dir, &args.lens, &mut classifier)?,
            format!(" of {dir}"),
        ),
        None => {
            // A fixed-angle crop is timed through the lens flags' lens, by
            // default 42 degrees across the square frame (the generator's
            // d435 preset).
            let lens = Some(match args.lens.lens()? {
                Some(lens) => lens,
                None => Lens::horizontal_fov(42.0)?,
            });
            set_lens(&mut classifier, lens, "the benchmark")?;
            (
                synthetic_frames(args.frames.max(1), args.size),
                String::new(),
            )
        }
    };
    let (width, height) = frames[0].dimensions();
    let (count, warmup) = (args.frames.max(1), args.warmup);
    let samples = match args.stage {
        Stage::Frame => inference(&mut classifier, &frames, count, warmup, period)?,
        Stage::Prepare => {
            let mut prepare = |f: &RgbImage, _: usize| classifier.frame_input(f).map(drop);
            timed(&frames, count, warmup, period, &mut prepare)?
        }
        Stage::Network => {
            let inputs = frames
                .iter()
                .map(|f| classifier.frame_input(f))
                .collect::<grasp_model::error::Result<Vec<_>>>()?;
            let mut network = |_: &RgbImage, i: usize| {
                let x = &inputs[i % inputs.len()];
                classifier.network_features(x).map(drop)
            };
            timed(&frames, count, warmup, period, &mut network)?
        }
    };
    if let Some(path) = &args.times {
        write_times(path, &samples)?;
    }
    let inference = Summary::of(&samples);
    let paced = period.map_or("back to back".to_string(), |_| {
        format!("at {} fps", args.pace)
    });
    let what = match args.stage {
        Stage::Frame => format!("inference {width}x{height}{from}"),
        Stage::Prepare => format!("prepare {width}x{height}{from}"),
        Stage::Network => {
            let side = classifier.input().preprocess.size;
            format!("network {side}x{side} of {width}x{height}{from}")
        }
    };
    println!(
        "{what} ({} frames, {paced}): p50 {:.2} ms, p99 {:.2} ms, mean {:.2} ms, max {:.2} ms",
        inference.n, inference.p50_ms, inference.p99_ms, inference.mean_ms, inference.max_ms
    );
    if args.sends > 0 {
        let link = link_round_trip(args.sends, args.baud)?;
        println!(
            "link PRESHAPE->ACK over a pty at {} baud ({} sends): p50 {:.3} ms, p99 {:.3} ms",
            link.baud, link.round_trip.n, link.round_trip.p50_ms, link.round_trip.p99_ms
        );
    }
    if args.approaches > 0 {
        let window = synthetic_frames(60, args.size);
        let ap = approaches(&mut classifier, window, 30.0, args.approaches, args.baud)?;
        println!(
            "approach (window {} s at {} fps, {} runs): trigger->ACK p50 {:.1} ms, p99 {:.1} ms; \
             after the window p50 {:.1} ms, p99 {:.1} ms; {} frames classified, {} dropped",
            ap.window_s,
            ap.fps,
            ap.trigger_to_command.n,
            ap.trigger_to_command.p50_ms,
            ap.trigger_to_command.p99_ms,
            ap.after_window.p50_ms,
            ap.after_window.p99_ms,
            ap.frames_classified,
            ap.frames_dropped
        );
    }
    Ok(())
}

/// Order statistics of a sample of durations, in milliseconds.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Summary {
    pub n: usize,
    pub mean_ms: f64,
    pub p50_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

impl Summary {
    /// Nearest-rank percentiles (no interpolation: every value reported was
    /// measured).
    pub fn of(samples: &[Duration]) -> Summary {
        assert!(!samples.is_empty(), "no samples");
        let mut ms: Vec<f64> = samples.iter().map(|d| d.as_secs_f64() * 1e3).collect();
        ms.sort_by(f64::total_cmp);
        let rank = |q: f64| ms[((q * ms.len() as f64).ceil() as usize).clamp(1, ms.len()) - 1];
        Summary {
            n: ms.len(),
            mean_ms: ms.iter().sum::<f64>() / ms.len() as f64,
            p50_ms: rank(0.50),
            p99_ms: rank(0.99),
            max_ms: ms[ms.len() - 1],
        }
    }
}

/// Deterministic 224x224 test frames (the model's input size).
pub fn synthetic_frames(n: usize, size: u32) -> Vec<RgbImage> {
    (0..n)
        .map(|i| {
            RgbImage::from_fn(size, size, |x, y| {
                let v = (x * 7 + y * 13 + i as u32 * 31) % 256;
                image::Rgb([v as u8, (255 - v) as u8, ((x ^ y) % 256) as u8])
            })
        })
        .collect()
}

/// Every frame of the recording in `dir`, decoded, with the classifier
/// given the recording's lens (or `lens`) as `replay` gives it.
fn recording_frames(
    dir: &str,
    lens: &LensArgs,
    classifier: &mut Classifier,
) -> Result<Vec<RgbImage>> {
    let mut folder = open_recording(dir, None, lens, Pacing::AsFastAsPossible, classifier)?;
    folder.begin()?;
    let mut frames = Vec::with_capacity(folder.len());
    while let Some(frame) = folder.next_frame()? {
        frames.push(frame.image);
    }
    Ok(frames)
}

/// The time between paced frames for `--pace FPS`; none for 0 (back to
/// back).
fn pace_period(fps: f64) -> Result<Option<Duration>> {
    if fps == 0.0 {
        return Ok(None);
    }
    if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
        anyhow::bail!("--pace: expected frames per second in (0, 1000], or 0, got {fps}");
    }
    Ok(Some(Duration::from_secs_f64(1.0 / fps)))
}

/// Per-frame inference time of `count` frames, `frames` repeated in order,
/// after `warmup` untimed ones; with a `period`, each frame starts one
/// period after the previous one started (a frame that overruns starts the
/// next at once).
pub fn inference(
    classifier: &mut dyn FrameClassifier,
    frames: &[RgbImage],
    count: usize,
    warmup: usize,
    period: Option<Duration>,
) -> Result<Vec<Duration>> {
    // A frame time for a classifier with history: the camera's period,
    // or 30 frames/s without one.
    let step_s = period.map_or(1.0 / 30.0, |p| p.as_secs_f64());
    classifier.begin_approach();
    let mut classify = |f: &RgbImage, i: usize| classifier.classify(f, i as f64 * step_s).map(drop);
    timed(frames, count, warmup, period, &mut classify)
}

/// The time of `run(frame, index)` for `count` frames, `frames` repeated
/// in order, after `warmup` untimed ones, back to back or one per `period`.
fn timed<E>(
    frames: &[RgbImage],
    count: usize,
    warmup: usize,
    period: Option<Duration>,
    run: &mut dyn FnMut(&RgbImage, usize) -> std::result::Result<(), E>,
) -> Result<Vec<Duration>>
where
    anyhow::Error: From<E>,
{
    for (i, f) in frames.iter().cycle().take(warmup).enumerate() {
        run(f, i)?;
    }
    let mut samples = Vec::with_capacity(count);
    let mut next = Instant::now();
    for (i, f) in frames.iter().cycle().take(count).enumerate() {
        if period.is_some() {
            std::thread::sleep(next.saturating_duration_since(Instant::now()));
        }
        let t = Instant::now();
        run(f, warmup + i)?;
        samples.push(t.elapsed());
        next = period.map_or(next, |p| t + p);
    }
    Ok(samples)
}

/// Each sample in ms, one a line (for `lab/bench_peers.py`).
fn write_times(path: &std::path::Path, samples: &[Duration]) -> Result<()> {
    let lines: String = samples
        .iter()
        .map(|d| format!("{:.4}\n", d.as_secs_f64() * 1e3))
        .collect();
    std::fs::write(path, lines)
        .map_err(|e| anyhow::anyhow!("cannot write --times {}: {e}", path.display()))
}

#[derive(Debug, Clone, Serialize)]
pub struct LinkBench {
    pub baud: u32,
    /// PRESHAPE sent to its ACK received.
    pub round_trip: Summary,
}

/// PRESHAPE round trips to a simulated hand on a pseudo-terminal.
pub fn link_round_trip(sends: usize, baud: u32) -> Result<LinkBench> {
    let dir = tempfile::tempdir()?;
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {})?;
    let hand = Hand::start(HandLink::new(
        Box::new(SerialConnector::new(pty.path(), baud)),
        LinkConfig::default(),
    ))?;
    let mut samples = Vec::with_capacity(sends);
    for i in 0..sends {
        let p = Preshape::ALL[i % Preshape::ALL.len()];
        let t = Instant::now();
        hand.send(preshape_command(p))?;
        samples.push(t.elapsed());
    }
    drop(hand);
    Ok(LinkBench {
        baud,
        round_trip: Summary::of(&samples),
    })
}

#[derive(Debug, Clone, Serialize)]
pub struct ApproachBench {
    pub fps: f64,
    pub window_s: f64,
    /// Trigger to the pre-shape's ACK.
    pub trigger_to_command: Summary,
    /// The part of it after the window closed: last inference, decision,
    /// link round trip.
    pub after_window: Summary,
    pub frames_classified: u64,
    pub frames_dropped: u64,
}

/// Whole approaches: a 30 fps recording replayed in real time (stale frames
/// dropped), the default policy, a simulated hand on a pseudo-terminal.
pub fn approaches(
    classifier: &mut dyn FrameClassifier,
    frames: Vec<RgbImage>,
    fps: f64,
    runs: usize,
    baud: u32,
) -> Result<ApproachBench> {
    let dir = tempfile::tempdir()?;
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {})?;
    let hand = Hand::start(HandLink::new(
        Box::new(SerialConnector::new(pty.path(), baud)),
        LinkConfig::default(),
    ))?;
    let policy = PolicyConfig {
        fallback: Some(Preshape::Power), // an untrained model still commands
        ..PolicyConfig::default()
    };
    let stop = AtomicBool::new(false);
    let mut source: Box<dyn FrameSource> =
        Box::new(MemorySource::new(frames, fps, Pacing::RealTime)?);
    let (mut total, mut after) = (Vec::new(), Vec::new());
    let (mut classified, mut dropped) = (0, 0);
    let window = Duration::from_secs_f64(policy.window_s);
    for _ in 0..runs {
        let t0 = Instant::now();
        let (feed, report) = classify_window(
            source,
            FeedMode::Latest,
            classifier,
            &policy,
            t0,
            &mut |_| {},
        )?;
        classified += report.feed.delivered;
        dropped += report.feed.dropped;
        let report = actuate(&hand, report, None, &stop, t0, policy.max_decision_age())?;
        source = feed.join(); // as `hannes-run run`: after the command
        let acked = report.preshape.ok_or_else(|| {
            anyhow::anyhow!(
                "approach sent no pre-shape: {:?}, expired: {:?}",
                report.link_error,
                report.expired
            )
        })?;
        let elapsed = Duration::from_secs_f64(acked.since_trigger_ms / 1e3);
        total.push(elapsed);
        after.push(elapsed.saturating_sub(window));
    }
    drop(hand);
    Ok(ApproachBench {
        fps,
        window_s: policy.window_s,
        trigger_to_command: Summary::of(&total),
        after_window: Summary::of(&after),
        frames_classified: classified,
        frames_dropped: dropped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let s: Vec<Duration> = (1..=100).map(Duration::from_millis).collect();
        let sum = Summary::of(&s);
        assert_eq!((sum.p50_ms, sum.p99_ms, sum.max_ms), (50.0, 99.0, 100.0));
        assert!((sum.mean_ms - 50.5).abs() < 1e-9);
        let one = Summary::of(&[Duration::from_millis(7)]);
        assert_eq!((one.p50_ms, one.p99_ms), (7.0, 7.0));
    }
}
