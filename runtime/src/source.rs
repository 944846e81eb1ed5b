//! Frame sources: a recorded sequence folder (the generator's layout with
//! `sequence.json`, or bare PNGs), replayed at its real frame rate or as fast
//! as possible, and in-memory frames for tests and benchmarks. The live
//! camera is in `camera.rs` (feature `camera`).

use anyhow::{bail, Context, Result};
use grasp_model::input::Lens;
use grasp_schema::dataset::SEQUENCE_FILE;
use grasp_schema::taxonomy::{Class, Preshape};
use image::RgbImage;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Frame rate assumed for bare PNG folders without `--fps`.
pub const DEFAULT_FPS: f64 = 30.0;

/// One captured frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Position in the source since [`FrameSource::begin`].
    pub index: u64,
    /// Source time since `begin`, in seconds (capture time for a camera,
    /// index / fps for a recording).
    pub time_s: f64,
    pub image: RgbImage,
}

/// A stream of frames.
pub trait FrameSource: Send {
    /// Called when an approach window opens: a recording restarts from its
    /// first frame, a camera drops frames captured before now.
    fn begin(&mut self) -> Result<()>;
    /// The next frame; `None` once a recording is exhausted.
    fn next_frame(&mut self) -> Result<Option<Frame>>;
    fn describe(&self) -> String;
}

/// How a recording is replayed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// Frame i is released at begin + i / fps, like a camera.
    RealTime,
    /// Every frame as soon as asked for.
    AsFastAsPossible,
}

/// Releases frames on a frame-rate clock.
#[derive(Debug, Clone)]
struct Clock {
    fps: f64,
    pacing: Pacing,
    start: Instant,
}

impl Clock {
    fn time_of(&self, index: u64) -> f64 {
        index as f64 / self.fps
    }

    fn wait_for(&self, index: u64) {
        if self.pacing == Pacing::RealTime {
            let due = self.start + Duration::from_secs_f64(self.time_of(index));
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
    }
}

/// What `sequence.json` says about a recording, when present.
#[derive(Debug, Clone, Default)]
pub struct SequenceInfo {
    pub fps: Option<f64>,
    /// The sequence's pre-shape label.
    pub preshape: Option<Preshape>,
    /// Per-frame ground truth, in frame order.
    pub labels: Vec<Class>,
    /// `render.center_region`: only the centred square of this fraction of
    /// the shorter side was rendered (the rest is black); None: all of it.
    pub center_region: Option<f64>,
    /// `plan.intrinsics`, the lens a model that crops a fixed angle needs:
    /// None when absent, an error when present but unusable.
    pub intrinsics: Option<Result<Pinhole, String>>,
    /// The `sequence.json` these come from.
    pub path: Option<PathBuf>,
}

impl SequenceInfo {
    /// The recording's lens, from `plan.intrinsics` (None without one); an
    /// unusable one is an error naming its field.
    pub fn lens(&self) -> Result<Option<Lens>> {
        match &self.intrinsics {
            None => Ok(None),
            Some(Err(why)) => bail!("{why}"),
            Some(Ok(k)) => Ok(Some(
                Lens::from_pinhole(k.fx, k.fy, k.width, k.height)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", self.record()))?,
            )),
        }
    }

    fn record(&self) -> String {
        self.path
            .as_ref()
            .map_or_else(|| SEQUENCE_FILE.to_string(), |p| p.display().to_string())
    }

    /// Refuses a model that looks further out than the recording was
    /// rendered: it would see the black surround. `crop` is the model's
    /// centre crop (None: whole frames).
    pub fn check_crop(&self, crop: Option<f64>, dir: &Path) -> Result<()> {
        let why = self
            .center_region
            .and_then(|region| grasp_schema::dataset::crop_outside_region(region, crop));
        match why {
            Some(why) => bail!("{}: {why}", dir.display()),
            None => Ok(()),
        }
    }
}

/// The part of `plan.intrinsics` a lens needs.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct Pinhole {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
}

/// A folder of PNG frames replayed from disk, decoded one at a time.
pub struct SequenceFolder {
    dir: PathBuf,
    files: Vec<PathBuf>,
    info: SequenceInfo,
    clock: Clock,
    next: u64,
}

impl SequenceFolder {
    /// Opens `dir`. The frame rate is `fps` if given, else `plan.fps` from
    /// `sequence.json`, else [`DEFAULT_FPS`].
    pub fn open(dir: &Path, fps: Option<f64>, pacing: Pacing) -> Result<Self> {
        anyhow::ensure!(dir.is_dir(), "{} is not a directory", dir.display());
        let record = dir.join(SEQUENCE_FILE);
        let (files, info) = if record.exists() {
            read_sequence_json(&record)?
        } else {
            (list_pngs(dir)?, SequenceInfo::default())
        };
        if files.is_empty() {
            bail!("{} holds no PNG frames", dir.display());
        }
        let files: Vec<PathBuf> = files.into_iter().map(|f| dir.join(f)).collect();
        if let Some(missing) = files.iter().find(|f| !f.is_file()) {
            bail!(
                "frame {} listed in {} is missing",
                missing.display(),
                record.display()
            );
        }
        let fps = fps.or(info.fps).unwrap_or(DEFAULT_FPS);
        check_fps(fps).with_context(|| format!("frame rate of {}", dir.display()))?;
        Ok(SequenceFolder {
            dir: dir.to_path_buf(),
            files,
            info,
            clock: Clock {
                fps,
                pacing,
                start: Instant::now(),
            },
            next: 0,
        })
    }

    pub fn info(&self) -> &SequenceInfo {
        &self.info
    }

    /// Width and height of the recording's first frame (read from its
    /// header only).
    pub fn frame_size(&self) -> Result<(u32, u32)> {
        let first = &self.files[0];
        image::image_dimensions(first)
            .with_context(|| format!("cannot read the size of frame {}", first.display()))
    }

    pub fn fps(&self) -> f64 {
        self.clock.fps
    }

    pub fn len(&self) -> usize {
        self.files.len()
    }

    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }
}

impl FrameSource for SequenceFolder {
    fn begin(&mut self) -> Result<()> {
        self.next = 0;
        self.clock.start = Instant::now();
        Ok(())
    }

    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let Some(path) = self.files.get(self.next as usize) else {
            return Ok(None);
        };
        let index = self.next;
        self.clock.wait_for(index);
        let image = image::open(path)
            .with_context(|| format!("cannot decode frame {}", path.display()))?
            .to_rgb8();
        self.next += 1;
        Ok(Some(Frame {
            index,
            time_s: self.clock.time_of(index),
            image,
        }))
    }

    fn describe(&self) -> String {
        format!(
            "{} ({} frames at {} fps)",
            self.dir.display(),
            self.files.len(),
            self.clock.fps
        )
    }
}

/// Frames held in memory (tests, benchmarks).
pub struct MemorySource {
    frames: Vec<RgbImage>,
    clock: Clock,
    next: u64,
}

impl MemorySource {
    pub fn new(frames: Vec<RgbImage>, fps: f64, pacing: Pacing) -> Result<Self> {
        check_fps(fps)?;
        Ok(MemorySource {
            frames,
            clock: Clock {
                fps,
                pacing,
                start: Instant::now(),
            },
            next: 0,
        })
    }
}

impl FrameSource for MemorySource {
    fn begin(&mut self) -> Result<()> {
        self.next = 0;
        self.clock.start = Instant::now();
        Ok(())
    }

    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let Some(image) = self.frames.get(self.next as usize) else {
            return Ok(None);
        };
        let index = self.next;
        self.clock.wait_for(index);
        self.next += 1;
        Ok(Some(Frame {
            index,
            time_s: self.clock.time_of(index),
            image: image.clone(),
        }))
    }

    fn describe(&self) -> String {
        format!(
            "{} in-memory frames at {} fps",
            self.frames.len(),
            self.clock.fps
        )
    }
}

fn check_fps(fps: f64) -> Result<()> {
    anyhow::ensure!(
        fps.is_finite() && fps > 0.0 && fps <= 1000.0,
        "frame rate must be in (0, 1000] fps, got {fps}"
    );
    Ok(())
}

fn list_pngs(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).with_context(|| format!("cannot list {}", dir.display()))? {
        let path = entry?.path();
        let is_png = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if is_png && path.is_file() {
            files.push(PathBuf::from(
                path.file_name().expect("listed file has a name"),
            ));
        }
    }
    // Zero-padded names sort in frame order.
    files.sort();
    Ok(files)
}

/// Reads the fields the runtime needs from `sequence.json`, leniently: a
/// newer generator may add fields, and only these must be right.
fn read_sequence_json(path: &Path) -> Result<(Vec<PathBuf>, SequenceInfo)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{} is not valid JSON", path.display()))?;
    let files = v
        .get("frame_files")
        .and_then(|f| f.as_array())
        .with_context(|| {
            format!(
                "{}: field `frame_files` is missing or not a list",
                path.display()
            )
        })?
        .iter()
        .enumerate()
        .map(|(i, f)| {
            f.as_str()
                .map(PathBuf::from)
                .with_context(|| format!("{}: `frame_files[{i}]` is not a string", path.display()))
        })
        .collect::<Result<Vec<_>>>()?;
    let plan = v.get("plan");
    let fps = match plan.and_then(|p| p.get("fps")) {
        None => None,
        Some(f) => Some(
            f.as_f64()
                .with_context(|| format!("{}: `plan.fps` is not a number", path.display()))?,
        ),
    };
    let preshape = plan
        .and_then(|p| p.get("preshape"))
        .and_then(|p| serde_json::from_value(p.clone()).ok());
    let labels = plan
        .and_then(|p| p.get("frames"))
        .and_then(|f| f.as_array())
        .map(|frames| {
            frames
                .iter()
                .filter_map(|f| serde_json::from_value(f.get("class")?.clone()).ok())
                .collect()
        })
        .unwrap_or_default();
    let center_region = match v.get("render").and_then(|r| r.get("center_region")) {
        None => None,
        Some(c) => Some(
            c.as_f64()
                .filter(|c| *c > 0.0 && *c <= 1.0)
                .with_context(|| {
                    format!(
                        "{}: `render.center_region` is not a fraction in (0, 1]",
                        path.display()
                    )
                })?,
        ),
    };
    let intrinsics = plan
        .and_then(|p| p.get("intrinsics"))
        .filter(|k| !k.is_null())
        .map(|k| {
            Pinhole::deserialize(k).map_err(|e| format!("{}: plan.intrinsics: {e}", path.display()))
        });
    Ok((
        files,
        SequenceInfo {
            fps,
            preshape,
            labels,
            center_region,
            intrinsics,
            path: Some(path.to_path_buf()),
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_frames(dir: &Path, n: usize) {
        for i in 0..n {
            let img = RgbImage::from_pixel(4, 3, image::Rgb([i as u8, 0, 0]));
            img.save(dir.join(format!("{i:05}.png"))).unwrap();
        }
    }

    #[test]
    fn bare_pngs_replay_in_name_order_at_the_default_rate() {
        let dir = tempfile::tempdir().unwrap();
        write_frames(dir.path(), 3);
        std::fs::write(dir.path().join("notes.txt"), "x").unwrap();
        let mut s = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible).unwrap();
        s.begin().unwrap();
        let mut got = Vec::new();
        while let Some(f) = s.next_frame().unwrap() {
            got.push((f.index, f.image.get_pixel(0, 0)[0], f.time_s));
        }
        assert_eq!(
            got,
            vec![(0, 0, 0.0), (1, 1, 1.0 / 30.0), (2, 2, 2.0 / 30.0)]
        );
    }

    #[test]
    fn sequence_json_gives_the_frame_rate_order_and_labels() {
        let dir = tempfile::tempdir().unwrap();
        write_frames(dir.path(), 2);
        let record = serde_json::json!({
            "plan": {"fps": 10.0, "preshape": "pinch3",
                     "frames": [{"class": "pinch3"}, {"class": "no_grasp"}]},
            "frame_files": ["00001.png", "00000.png"],
        });
        std::fs::write(dir.path().join(SEQUENCE_FILE), record.to_string()).unwrap();
        let mut s = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible).unwrap();
        assert_eq!(s.fps(), 10.0);
        assert_eq!(s.info().preshape, Some(Preshape::Pinch3));
        assert_eq!(s.info().labels, vec![Class::Pinch3, Class::NoGrasp]);
        s.begin().unwrap();
        let f = s.next_frame().unwrap().unwrap();
        assert_eq!(f.image.get_pixel(0, 0)[0], 1);
    }

    #[test]
    fn the_recordings_focal_length_is_read_along_its_shorter_side() {
        let dir = tempfile::tempdir().unwrap();
        write_frames(dir.path(), 1);
        let record = |intrinsics: serde_json::Value| {
            let r = serde_json::json!({
                "plan": {"fps": 10.0, "intrinsics": intrinsics}, "frame_files": ["00000.png"],
            });
            std::fs::write(dir.path().join(SEQUENCE_FILE), r.to_string()).unwrap();
            let s = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible).unwrap();
            s.info().lens().map_err(|e| e.to_string())
        };
        let lens =
            |w: u32, h: u32| serde_json::json!({"width": w, "height": h, "fx": 300.0, "fy": 200.0});
        let focal = |f: f64, width: u32, height: u32| {
            Ok(Some(Lens::Focal {
                focal_px: f,
                width,
                height,
            }))
        };
        assert_eq!(record(lens(640, 480)), focal(200.0, 640, 480));
        assert_eq!(record(lens(480, 640)), focal(300.0, 480, 640));
        // A focal length of 0 (or negative) names its field, instead of
        // reading as "no plan.intrinsics".
        for bad in [0.0, -1.0] {
            let err = record(serde_json::json!({"width": 64, "height": 64, "fx": bad, "fy": bad}))
                .unwrap_err();
            assert!(err.contains("plan.intrinsics.fy"), "{err}");
        }
        let err = record(serde_json::json!({"width": 64, "height": 64})).unwrap_err();
        assert!(
            err.contains("plan.intrinsics") && err.contains("fx"),
            "{err}"
        );
        assert_eq!(
            SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible)
                .unwrap()
                .frame_size()
                .unwrap(),
            (4, 3)
        );
    }

    #[test]
    fn a_centre_only_recording_refuses_a_model_that_looks_wider() {
        let dir = tempfile::tempdir().unwrap();
        write_frames(dir.path(), 1);
        let record = |region: serde_json::Value| {
            let r = serde_json::json!({
                "plan": {"fps": 10.0}, "frame_files": ["00000.png"],
                "render": {"center_region": region},
            });
            std::fs::write(dir.path().join(SEQUENCE_FILE), r.to_string()).unwrap();
        };
        record(serde_json::json!(0.5));
        let s = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible).unwrap();
        assert_eq!(s.info().center_region, Some(0.5));
        s.info().check_crop(Some(0.42), dir.path()).unwrap();
        for crop in [Some(0.6), None] {
            let err = s.info().check_crop(crop, dir.path()).unwrap_err();
            assert!(
                err.to_string()
                    .contains("rendered only in their central 0.5"),
                "{err}"
            );
        }
        record(serde_json::json!("half"));
        let err = SequenceFolder::open(dir.path(), None, Pacing::AsFastAsPossible)
            .err()
            .unwrap();
        assert!(err.to_string().contains("render.center_region"), "{err}");
    }

    #[test]
    fn real_time_replay_releases_frames_on_the_clock() {
        let frames = vec![RgbImage::new(2, 2); 4];
        let mut s = MemorySource::new(frames, 100.0, Pacing::RealTime).unwrap();
        s.begin().unwrap();
        let t = Instant::now();
        while s.next_frame().unwrap().is_some() {}
        // Frame 3 is due 30 ms after begin: the source cannot be earlier.
        assert!(t.elapsed() >= Duration::from_millis(30));
    }

    #[test]
    fn bad_inputs_name_the_file_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let err = SequenceFolder::open(dir.path(), None, Pacing::RealTime)
            .err()
            .unwrap();
        assert!(err.to_string().contains("no PNG frames"));
        std::fs::write(dir.path().join(SEQUENCE_FILE), r#"{"frame_files": 3}"#).unwrap();
        let err = SequenceFolder::open(dir.path(), None, Pacing::RealTime)
            .err()
            .unwrap();
        assert!(err.to_string().contains("frame_files"), "{err}");
        std::fs::write(
            dir.path().join(SEQUENCE_FILE),
            r#"{"frame_files": ["00000.png"], "plan": {"fps": 0}}"#,
        )
        .unwrap();
        let err = SequenceFolder::open(dir.path(), None, Pacing::RealTime)
            .err()
            .unwrap();
        assert!(err.to_string().contains("missing"), "{err}");
        write_frames(dir.path(), 1);
        let err = SequenceFolder::open(dir.path(), None, Pacing::RealTime)
            .err()
            .unwrap();
        assert!(format!("{err:#}").contains("frame rate"), "{err:#}");
        std::fs::write(dir.path().join("00000.png"), b"not a png").unwrap();
        let mut s = SequenceFolder::open(dir.path(), Some(30.0), Pacing::RealTime).unwrap();
        s.begin().unwrap();
        let err = s.next_frame().unwrap_err();
        assert!(format!("{err:#}").contains("00000.png"), "{err:#}");
    }
}
