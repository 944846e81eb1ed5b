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
}
