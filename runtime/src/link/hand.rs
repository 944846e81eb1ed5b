//! [`Hand`]: the link shared with a heartbeat thread that keeps the
//! hand's watchdog fed.

use super::{Delivery, HandLink, LinkError, LinkStats, StartError};
use crate::protocol::{Ack, Command};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A [`HandLink`] shared with a heartbeat thread.
pub struct Hand {
    link: Arc<Mutex<HandLink>>,
    stop: Arc<AtomicBool>,
    heartbeat: Option<JoinHandle<()>>,
}

impl Hand {
    /// Connects (HELLO) and starts the heartbeat.
    pub fn start(mut link: HandLink) -> Result<Hand, StartError> {
        link.cfg.validate()?;
        link.connect()?;
        let interval = Duration::from_millis(link.cfg.heartbeat_interval_ms);
        let link = Arc::new(Mutex::new(link));
        let stop = Arc::new(AtomicBool::new(false));
        let heartbeat = {
            let (link, stop) = (link.clone(), stop.clone());
            std::thread::Builder::new()
                .name("hannes-heartbeat".into())
                .spawn(move || heartbeat_loop(&link, &stop, interval))
                .map_err(StartError::Heartbeat)?
        };
        Ok(Hand {
            link,
            stop,
            heartbeat: Some(heartbeat),
        })
    }

    /// Sends a command; returns once it is acknowledged.
    pub fn send(&self, command: Command) -> Result<Delivery, LinkError> {
        self.send_until(command, None)
    }

    /// Sends a command that must not be executed at or after `expires`
    /// ([`HandLink::send_until`]).
    pub fn send_until(
        &self,
        command: Command,
        expires: Option<Instant>,
    ) -> Result<Delivery, LinkError> {
        self.send_unless_stopped(command, expires, None)
    }

    /// [`Hand::send_until`] that transmits nothing more once `stop` is set
    /// ([`HandLink::send_unless_stopped`]).
    pub fn send_unless_stopped(
        &self,
        command: Command,
        expires: Option<Instant>,
        stop: Option<&AtomicBool>,
    ) -> Result<Delivery, LinkError> {
        let delivery = lock(&self.link).send_unless_stopped(command, expires, stop);
        match &delivery {
            Ok(d) => tracing::info!(
                command = command.name(),
                seq = d.ack.seq,
                attempts = d.attempts,
                latency_ms = d.elapsed.as_secs_f64() * 1e3,
                state = ?d.ack.state,
                "acknowledged"
            ),
            // Not a failure of the link: the caller asked for it.
            Err(e @ LinkError::Stopped { .. }) => tracing::warn!("{e}"),
            Err(e) => tracing::error!("{e}"),
        }
        delivery
    }

    pub fn stats(&self) -> LinkStats {
        lock(&self.link).stats()
    }

    pub fn is_connected(&self) -> bool {
        lock(&self.link).is_connected()
    }

    /// What the hand last acknowledged ([`HandLink::last_ack`]).
    pub fn last_ack(&self) -> Option<Ack> {
        lock(&self.link).last_ack()
    }
}

impl Drop for Hand {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.heartbeat.take() {
            let _ = h.join();
        }
    }
}

fn lock(link: &Mutex<HandLink>) -> MutexGuard<'_, HandLink> {
    // A panic in another holder leaves the link usable: its state is only
    // counters and an optional connection.
    link.lock().unwrap_or_else(|p| p.into_inner())
}

fn heartbeat_loop(link: &Mutex<HandLink>, stop: &AtomicBool, interval: Duration) {
    let tick = (interval / 4).max(Duration::from_millis(2));
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(tick);
        let mut link = lock(link);
        if link.idle() < interval || stop.load(Ordering::Relaxed) {
            continue;
        }
        // Bounded by the interval: while the device is gone, re-opening it
        // goes on in slices, and a command waiting for the lock gets it
        // within one interval instead of a whole reconnect timeout.
        match link.send_until(Command::Heartbeat, Some(Instant::now() + interval)) {
            Ok(_) => {}
            Err(e @ LinkError::Expired { .. }) => tracing::debug!("heartbeat: {e}"),
            Err(e) => tracing::warn!("heartbeat failed: {e}"),
        }
    }
}
