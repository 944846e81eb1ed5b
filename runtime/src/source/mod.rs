//! Frame sources: a recorded sequence folder (the generator's layout with
//! `sequence.json`, or bare PNGs), replayed at its real frame rate or as fast
//! as possible, and in-memory frames for tests and benchmarks. The live
//! camera is in `camera.rs` (feature `camera`).
//!
//! `folder.rs` replays a folder, `record.rs` reads its `sequence.json`,
//! `error.rs` says what goes wrong.

mod error;
mod folder;
mod record;

pub use error::{BadFrameRate, SourceError};
pub use folder::SequenceFolder;
pub use record::{Pinhole, SequenceInfo};

use image::RgbImage;
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
    fn begin(&mut self) -> Result<(), SourceError>;
    /// The next frame; `None` once a recording is exhausted.
    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError>;
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

/// Frames held in memory (tests, benchmarks).
pub struct MemorySource {
    frames: Vec<RgbImage>,
    clock: Clock,
    next: u64,
}

impl MemorySource {
    pub fn new(frames: Vec<RgbImage>, fps: f64, pacing: Pacing) -> Result<Self, BadFrameRate> {
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
    fn begin(&mut self) -> Result<(), SourceError> {
        self.next = 0;
        self.clock.start = Instant::now();
        Ok(())
    }

    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
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

fn check_fps(fps: f64) -> Result<(), BadFrameRate> {
    match fps.is_finite() && fps > 0.0 && fps <= 1000.0 {
        true => Ok(()),
        false => Err(BadFrameRate { fps }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grasp_model::input::Lens;
    use grasp_schema::dataset::SEQUENCE_FILE;
    use grasp_schema::taxonomy::{Class, Preshape};
    use std::path::Path;

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
