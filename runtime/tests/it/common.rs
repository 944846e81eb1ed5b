//! Helpers shared by the runtime's integration tests.
#![allow(dead_code)] // each test binary uses a different part

use grasp_schema::taxonomy::Class;
use image::RgbImage;
use runtime::classifier::{ClassifyError, FrameClassifier};
use runtime::link::{Hand, HandLink, LinkConfig};
use runtime::transport::SerialConnector;
use std::path::Path;
use std::time::{Duration, Instant};

/// Small timeouts so failure paths run in milliseconds. The watchdog stays
/// long: a loaded CI machine must not open the hand by accident.
pub fn fast_link() -> LinkConfig {
    LinkConfig {
        ack_timeout_ms: 40,
        retries: 2,
        heartbeat_interval_ms: 30,
        watchdog_ms: 2000,
        reconnect_interval_ms: 20,
        reconnect_timeout_ms: 3000,
    }
}

pub fn start_hand(path: &Path, cfg: LinkConfig) -> Hand {
    Hand::start(HandLink::new(
        Box::new(SerialConnector::new(path, 115_200)),
        cfg,
    ))
    .expect("link starts")
}

/// Polls `cond` for up to `limit` (a bound for a stuck test, not a timing
/// assertion).
pub fn eventually(limit: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let t = Instant::now();
    while t.elapsed() < limit {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    cond()
}

/// Test frames: the red channel encodes the class the fake model sees.
pub fn frames_of(classes: &[Class]) -> Vec<RgbImage> {
    classes
        .iter()
        .map(|c| RgbImage::from_pixel(8, 8, image::Rgb([c.index() as u8 * 40, 0, 0])))
        .collect()
}

/// Reads the class back from the frame; optionally NaN on one frame, and
/// optionally slow.
pub struct FakeModel {
    pub nan_at: Option<usize>,
    pub delay: Duration,
    seen: usize,
}

impl FakeModel {
    pub fn new() -> Self {
        FakeModel {
            nan_at: None,
            delay: Duration::ZERO,
            seen: 0,
        }
    }
}

impl FrameClassifier for FakeModel {
    fn classify(&mut self, frame: &RgbImage, _time_s: f64) -> Result<[f32; 5], ClassifyError> {
        std::thread::sleep(self.delay);
        let class = (frame.get_pixel(0, 0)[0] / 40) as usize;
        let mut p = [0.05; 5];
        p[class] = 0.8;
        if self.nan_at == Some(self.seen) {
            p[0] = f32::NAN;
        }
        self.seen += 1;
        Ok(p)
    }
}
