//! Decouples capture from classification. A thread pulls frames from the
//! source into a one-frame slot. In [`FeedMode::Latest`] a new frame replaces
//! one the classifier has not taken yet (counted as dropped), so a slow
//! classifier always works on the freshest frame instead of a growing queue.
//! In [`FeedMode::Lockstep`] the source waits for the classifier (offline
//! replay: every frame is classified, none dropped).
//!
//! Stopping the feed ([`FrameFeed::stop`]) never waits for the source: the
//! capture thread may be inside `next_frame`, for up to a frame interval (a
//! paced replay sleeping until its next frame is due, 400 ms at 2.5
//! frames/s; a camera waiting for its next frame). Whatever comes after the
//! decision must not wait for that; the source is handed back later by
//! [`StoppedFeed::join`].

use crate::source::{Frame, FrameSource, SourceError};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Instant;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeedMode {
    Latest,
    Lockstep,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct FeedStats {
    /// Frames the source produced.
    pub captured: u64,
    /// Frames handed to the classifier.
    pub delivered: u64,
    /// Frames replaced before the classifier took them.
    pub dropped: u64,
}

#[derive(Debug)]
pub enum FeedItem {
    Frame(Frame),
    /// The source is exhausted.
    Ended,
    /// The deadline passed without a new frame.
    TimedOut,
    Failed(String),
}

#[derive(Default)]
struct Slot {
    frame: Option<Frame>,
    stats: FeedStats,
    ended: bool,
    error: Option<String>,
}

struct Shared {
    slot: Mutex<Slot>,
    changed: Condvar,
    stop: AtomicBool,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Slot> {
        self.slot.lock().unwrap_or_else(|p| p.into_inner())
    }
}

pub struct FrameFeed {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<Box<dyn FrameSource>>>,
}

impl FrameFeed {
    /// Calls `source.begin()` and starts capturing.
    pub fn start(
        mut source: Box<dyn FrameSource>,
        mode: FeedMode,
    ) -> Result<FrameFeed, SourceError> {
        source.begin()?;
        let shared = Arc::new(Shared {
            slot: Mutex::new(Slot::default()),
            changed: Condvar::new(),
            stop: AtomicBool::new(false),
        });
        let thread = {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("frame-feed".into())
                .spawn(move || {
                    produce(&mut *source, &shared, mode);
                    source
                })
                .map_err(SourceError::FeedThread)?
        };
        Ok(FrameFeed {
            shared,
            thread: Some(thread),
        })
    }

    /// The freshest frame not yet taken, waiting until `deadline` (forever
    /// if `None`).
    pub fn next(&self, deadline: Option<Instant>) -> FeedItem {
        let mut slot = self.shared.lock();
        loop {
            if let Some(frame) = slot.frame.take() {
                slot.stats.delivered += 1;
                self.shared.changed.notify_all();
                return FeedItem::Frame(frame);
            }
            if let Some(e) = &slot.error {
                return FeedItem::Failed(e.clone());
            }
            if slot.ended {
                return FeedItem::Ended;
            }
            slot = match deadline {
                None => self
                    .shared
                    .changed
                    .wait(slot)
                    .unwrap_or_else(|p| p.into_inner()),
                Some(d) => {
                    let now = Instant::now();
                    if now >= d {
                        return FeedItem::TimedOut;
                    }
                    self.shared
                        .changed
                        .wait_timeout(slot, d - now)
                        .unwrap_or_else(|p| p.into_inner())
                        .0
                }
            };
        }
    }

    pub fn stats(&self) -> FeedStats {
        self.shared.lock().stats
    }

    /// Stops capturing and returns at once, without waiting for the capture
    /// thread (see the module docs), with the statistics as of now: a frame
    /// left in the slot was never classified and counts as dropped; a frame
    /// the source returns later is discarded and not counted.
    pub fn stop(self) -> (StoppedFeed, FeedStats) {
        let stats = {
            let mut slot = self.shared.lock();
            // Set under the lock: the capture thread looks at it under the
            // lock before storing a frame, so nothing is counted after now.
            self.shared.stop.store(true, Ordering::Relaxed);
            if slot.frame.take().is_some() {
                slot.stats.dropped += 1;
            }
            slot.stats
        };
        self.shared.changed.notify_all();
        (StoppedFeed { feed: self }, stats)
    }

    /// [`FrameFeed::stop`], then [`StoppedFeed::join`].
    pub fn finish(self) -> (Box<dyn FrameSource>, FeedStats) {
        let (stopped, stats) = self.stop();
        (stopped.join(), stats)
    }

    fn halt(&mut self) -> Option<Box<dyn FrameSource>> {
        self.shared.stop.store(true, Ordering::Relaxed);
        self.shared.changed.notify_all();
        self.thread
            .take()
            .map(|t| t.join().expect("frame feed thread panicked"))
    }
}

/// A stopped feed whose capture thread may still be inside the source's
/// `next_frame`. Dropping it waits for that call too.
pub struct StoppedFeed {
    feed: FrameFeed,
}

impl StoppedFeed {
    /// Waits for the capture thread's last `next_frame` (at most a frame
    /// interval of the source) and hands the source back.
    pub fn join(mut self) -> Box<dyn FrameSource> {
        self.feed.halt().expect("feed thread joined once")
    }
}

impl Drop for FrameFeed {
    fn drop(&mut self) {
        self.halt();
    }
}

fn produce(source: &mut dyn FrameSource, shared: &Shared, mode: FeedMode) {
    let stopped = || shared.stop.load(Ordering::Relaxed);
    while !stopped() {
        let next = source.next_frame();
        let mut slot = shared.lock();
        if stopped() {
            return; // fetched after the feed stopped: not part of the window
        }
        match next {
            Ok(Some(frame)) => {
                if mode == FeedMode::Lockstep {
                    while slot.frame.is_some() && !stopped() {
                        slot = shared.changed.wait(slot).unwrap_or_else(|p| p.into_inner());
                    }
                    if stopped() {
                        return;
                    }
                }
                slot.stats.captured += 1;
                if slot.frame.replace(frame).is_some() {
                    slot.stats.dropped += 1;
                }
            }
            Ok(None) => slot.ended = true,
            Err(e) => slot.error = Some(grasp_support::error_chain(&e)),
        }
        let done = slot.ended || slot.error.is_some();
        drop(slot);
        shared.changed.notify_all();
        if done {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::{MemorySource, Pacing};
    use image::RgbImage;
    use std::time::Duration;

    fn frames(n: usize) -> Vec<RgbImage> {
        (0..n)
            .map(|i| RgbImage::from_pixel(2, 2, image::Rgb([i as u8, 0, 0])))
            .collect()
    }

    #[test]
    fn lockstep_delivers_every_frame_in_order() {
        let src = MemorySource::new(frames(20), 30.0, Pacing::AsFastAsPossible).unwrap();
        let feed = FrameFeed::start(Box::new(src), FeedMode::Lockstep).unwrap();
        let mut got = Vec::new();
        while let FeedItem::Frame(f) = feed.next(None) {
            std::thread::sleep(Duration::from_millis(1));
            got.push(f.index);
        }
        let (_, stats) = feed.finish();
        assert_eq!(got, (0..20).collect::<Vec<_>>());
        assert_eq!(stats.dropped, 0);
        assert_eq!(stats.delivered, 20);
    }

    #[test]
    fn a_slow_consumer_gets_fresh_frames_and_the_rest_are_counted_dropped() {
        // 30 fps camera, a consumer needing 100 ms per frame.
        let src = MemorySource::new(frames(30), 30.0, Pacing::RealTime).unwrap();
        let feed = FrameFeed::start(Box::new(src), FeedMode::Latest).unwrap();
        let mut got = Vec::new();
        while let FeedItem::Frame(f) = feed.next(None) {
            got.push(f.index);
            std::thread::sleep(Duration::from_millis(100));
        }
        let (_, stats) = feed.finish();
        assert!(got.len() < 30, "a slow consumer cannot see every frame");
        assert!(got.windows(2).all(|w| w[1] > w[0]), "frames stay in order");
        assert!(stats.dropped > 0);
        assert_eq!(stats.captured, 30);
        assert_eq!(stats.delivered + stats.dropped, stats.captured);
        // Dropping, not queueing: the last frame seen is the last captured.
        assert_eq!(*got.last().unwrap(), 29);
    }

    /// A source whose second frame is fetched only once `gate` opens (or
    /// after a bound for a stuck test); it tells `holding` when it waits.
    struct Held {
        next: u64,
        holding: std::sync::mpsc::Sender<()>,
        gate: std::sync::mpsc::Receiver<()>,
        opened_by_the_gate: Arc<AtomicBool>,
    }

    impl FrameSource for Held {
        fn begin(&mut self) -> Result<(), SourceError> {
            Ok(())
        }
        fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
            if self.next == 1 {
                self.holding.send(()).unwrap();
                let opened = self.gate.recv_timeout(Duration::from_secs(10)).is_ok();
                self.opened_by_the_gate.store(opened, Ordering::Relaxed);
            }
            self.next += 1;
            Ok(Some(Frame {
                index: self.next - 1,
                time_s: 0.0,
                image: RgbImage::new(2, 2),
            }))
        }
        fn describe(&self) -> String {
            "held".into()
        }
    }

    #[test]
    fn stopping_does_not_wait_for_a_source_inside_next_frame() {
        for mode in [FeedMode::Latest, FeedMode::Lockstep] {
            let (holding, held) = std::sync::mpsc::channel();
            let (open, gate) = std::sync::mpsc::channel();
            let opened_by_the_gate = Arc::new(AtomicBool::new(false));
            let source = Held {
                next: 0,
                holding,
                gate,
                opened_by_the_gate: opened_by_the_gate.clone(),
            };
            let feed = FrameFeed::start(Box::new(source), mode).unwrap();
            assert!(matches!(feed.next(None), FeedItem::Frame(f) if f.index == 0));
            held.recv().unwrap(); // the capture thread is inside next_frame
            let (stopped, stats) = feed.stop();
            // Reached while the source is still held: stop did not wait.
            open.send(()).unwrap();
            let _source = stopped.join();
            assert!(opened_by_the_gate.load(Ordering::Relaxed), "{mode:?}");
            // The frame fetched after the stop is not counted.
            let expected = FeedStats {
                captured: 1,
                delivered: 1,
                dropped: 0,
            };
            assert_eq!(stats, expected, "{mode:?}");
        }
    }

    #[test]
    fn deadline_and_source_errors_are_reported() {
        struct Failing;
        impl FrameSource for Failing {
            fn begin(&mut self) -> Result<(), SourceError> {
                Ok(())
            }
            fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
                Err(SourceError::Capture {
                    device: "/dev/video9".into(),
                    source: std::io::Error::other("camera unplugged"),
                })
            }
            fn describe(&self) -> String {
                "failing".into()
            }
        }
        let feed = FrameFeed::start(Box::new(Failing), FeedMode::Latest).unwrap();
        match feed.next(Some(Instant::now() + Duration::from_secs(5))) {
            FeedItem::Failed(e) => assert!(e.contains("unplugged")),
            other => panic!("{other:?}"),
        }
        let slow = MemorySource::new(frames(2), 1.0, Pacing::RealTime).unwrap();
        let feed = FrameFeed::start(Box::new(slow), FeedMode::Latest).unwrap();
        assert!(matches!(feed.next(None), FeedItem::Frame(_)));
        let soon = Instant::now() + Duration::from_millis(20);
        assert!(matches!(feed.next(Some(soon)), FeedItem::TimedOut));
    }
}
