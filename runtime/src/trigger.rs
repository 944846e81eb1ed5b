//! Triggers start an approach and, optionally, the closure of the fingers.
//! The paper's demo used a keyboard key and timers; an EMG onset detector
//! plugs in by implementing [`Trigger`] (or by feeding a [`ChannelTrigger`]).

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Why a trigger cannot be had, or cannot fire.
#[derive(Debug, thiserror::Error)]
pub enum TriggerError {
    #[error("unknown trigger '{spec}' (expected stdin, now, timer:SECONDS)")]
    Unknown { spec: String },
    #[error("trigger '{spec}': '{secs}' is not a number of seconds")]
    NotSeconds { spec: String, secs: String },
    #[error("trigger '{spec}': seconds must be in [0, 3600]")]
    OutOfRange { spec: String },
    #[error("cannot start the stdin reader")]
    Stdin(#[source] io::Error),
    /// The device behind a trigger failed (an EMG amplifier unplugged).
    #[error("trigger {trigger} failed")]
    Device {
        trigger: String,
        #[source]
        source: io::Error,
    },
}

/// How often a waiting trigger looks at the stop flag.
const POLL: Duration = Duration::from_millis(10);

pub trait Trigger: Send {
    /// Blocks until the trigger fires (`Ok(true)`), or until `stop` is set or
    /// the trigger can never fire again (`Ok(false)`).
    fn wait(&mut self, stop: &AtomicBool) -> Result<bool, TriggerError>;
    fn describe(&self) -> String;
}

/// Fires a fixed time after `wait` is called.
#[derive(Debug, Clone)]
pub struct Timer(pub Duration);

impl Trigger for Timer {
    fn wait(&mut self, stop: &AtomicBool) -> Result<bool, TriggerError> {
        let due = Instant::now() + self.0;
        loop {
            if stop.load(Ordering::Relaxed) {
                return Ok(false);
            }
            let now = Instant::now();
            if now >= due {
                return Ok(true);
            }
            std::thread::sleep((due - now).min(POLL));
        }
    }

    fn describe(&self) -> String {
        format!("timer ({:.3} s)", self.0.as_secs_f64())
    }
}

/// Fires on each message from another thread (stdin reader, EMG detector,
/// tests). Clones share the channel: each event fires one waiter.
#[derive(Clone)]
pub struct ChannelTrigger {
    rx: Arc<Mutex<Receiver<()>>>,
    name: String,
}

impl ChannelTrigger {
    pub fn new(name: impl Into<String>) -> (Sender<()>, ChannelTrigger) {
        let (tx, rx) = std::sync::mpsc::channel();
        let trigger = ChannelTrigger {
            rx: Arc::new(Mutex::new(rx)),
            name: name.into(),
        };
        (tx, trigger)
    }

    /// Drops events that arrived before now (a key pressed twice must not
    /// start the next approach by itself).
    fn drain(&self, rx: &Receiver<()>) {
        while rx.try_recv().is_ok() {}
    }
}

impl Trigger for ChannelTrigger {
    fn wait(&mut self, stop: &AtomicBool) -> Result<bool, TriggerError> {
        let rx = self.rx.lock().unwrap_or_else(|p| p.into_inner());
        self.drain(&rx);
        loop {
            if stop.load(Ordering::Relaxed) {
                return Ok(false);
            }
            match rx.recv_timeout(POLL) {
                Ok(()) => return Ok(true),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return Ok(false),
            }
        }
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// A trigger fired by each line (Enter) on standard input. The reader
/// thread ends with stdin; the trigger then reports that it cannot fire.
pub fn stdin_trigger() -> Result<ChannelTrigger, TriggerError> {
    let (tx, trigger) = ChannelTrigger::new("stdin (press Enter)");
    std::thread::Builder::new()
        .name("stdin-trigger".into())
        .spawn(move || {
            let mut line = String::new();
            while matches!(std::io::stdin().read_line(&mut line), Ok(n) if n > 0) {
                line.clear();
                if tx.send(()).is_err() {
                    break;
                }
            }
        })
        .map_err(TriggerError::Stdin)?;
    Ok(trigger)
}

/// Parses `stdin`, `now` or `timer:SECONDS` / `delay:SECONDS`.
pub fn parse_trigger(
    spec: &str,
    stdin: &mut Option<ChannelTrigger>,
) -> Result<Box<dyn Trigger>, TriggerError> {
    if spec == "stdin" {
        if stdin.is_none() {
            *stdin = Some(stdin_trigger()?);
        }
        return Ok(Box::new(stdin.clone().expect("created above")));
    }
    if spec == "now" {
        return Ok(Box::new(Timer(Duration::ZERO)));
    }
    let secs = spec
        .strip_prefix("timer:")
        .or_else(|| spec.strip_prefix("delay:"))
        .ok_or_else(|| TriggerError::Unknown { spec: spec.into() })?;
    let s: f64 = secs.parse().map_err(|_| TriggerError::NotSeconds {
        spec: spec.into(),
        secs: secs.into(),
    })?;
    if !(s.is_finite() && (0.0..=3600.0).contains(&s)) {
        return Err(TriggerError::OutOfRange { spec: spec.into() });
    }
    Ok(Box::new(Timer(Duration::from_secs_f64(s))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timer_fires_after_its_delay_and_stops_on_request() {
        let stop = AtomicBool::new(false);
        let t = Instant::now();
        assert!(Timer(Duration::from_millis(20)).wait(&stop).unwrap());
        assert!(t.elapsed() >= Duration::from_millis(20));
        stop.store(true, Ordering::Relaxed);
        assert!(!Timer(Duration::from_secs(60)).wait(&stop).unwrap());
    }

    #[test]
    fn channel_trigger_ignores_stale_events_and_ends_with_its_sender() {
        let stop = AtomicBool::new(false);
        let (tx, mut trig) = ChannelTrigger::new("test");
        tx.send(()).unwrap(); // pressed before anyone waited: ignored
        let sender = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(30));
            tx.send(()).unwrap();
            tx // dropped after the send below returns
        });
        assert!(trig.wait(&stop).unwrap());
        drop(sender.join().unwrap());
        assert!(!trig.wait(&stop).unwrap());
    }

    #[test]
    fn specs_parse_or_explain() {
        let mut stdin = None;
        assert_eq!(
            parse_trigger("timer:1.5", &mut stdin).unwrap().describe(),
            "timer (1.500 s)"
        );
        assert!(parse_trigger("now", &mut stdin).is_ok());
        let e = parse_trigger("emg", &mut stdin).err().unwrap();
        assert!(e.to_string().contains("expected stdin"));
        assert!(parse_trigger("timer:-1", &mut stdin).is_err());
        assert!(parse_trigger("delay:x", &mut stdin).is_err());
    }
}
