//! Opening the device and starting a session with HELLO, retried until
//! `reconnect_timeout_ms` (or a command's expiry, or a stop).

use super::exchange::Wait;
use super::{is_set, HandLink, LinkError};
use crate::protocol::{Command, HandTime};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// Why a reconnect ended without a session.
pub(super) enum Reconnect {
    Failed(LinkError),
    /// The command's expiry came first.
    Expired,
    /// A stop was requested.
    Stopped,
}

/// How one try at a session went.
enum Try {
    Session,
    /// Worth another try after a pause: why this one failed.
    Again(String),
    /// The hand answered, but not with a session: trying again is no use.
    GiveUp(LinkError),
}

impl HandLink {
    /// Opens the device (retrying until `reconnect_timeout_ms`) and starts a
    /// session with HELLO. A no-op while connected.
    pub fn connect(&mut self) -> Result<(), LinkError> {
        self.connect_until(None, None).map_err(|e| match e {
            Reconnect::Failed(e) => e,
            Reconnect::Expired | Reconnect::Stopped => unreachable!("no expiry or stop given"),
        })
    }

    /// [`HandLink::connect`], giving up at `expires` too, or once `stop`
    /// is set.
    pub(super) fn connect_until(
        &mut self,
        expires: Option<Instant>,
        stop: Option<&AtomicBool>,
    ) -> Result<(), Reconnect> {
        if self.conn.is_some() {
            return Ok(());
        }
        let started = Instant::now();
        let budget = started + Duration::from_millis(self.cfg.reconnect_timeout_ms);
        loop {
            if expires.is_some_and(|e| Instant::now() >= e) {
                return Err(Reconnect::Expired);
            }
            if is_set(stop) {
                return Err(Reconnect::Stopped);
            }
            let last_error = match self.try_session() {
                Try::Session => return Ok(()),
                Try::GiveUp(e) => return Err(Reconnect::Failed(e)),
                Try::Again(why) => why,
            };
            if Instant::now() >= budget {
                return Err(Reconnect::Failed(LinkError::Disconnected {
                    device: self.device(),
                    waited_ms: started.elapsed().as_millis() as u64,
                    last_error,
                }));
            }
            let pause = Duration::from_millis(self.cfg.reconnect_interval_ms);
            let wake = expires.map_or(Instant::now() + pause, |e| e.min(Instant::now() + pause));
            std::thread::sleep(wake.saturating_duration_since(Instant::now()));
        }
    }

    /// Opens the device once and says HELLO. A new connection starts with a
    /// fresh decoder and forgets the clock (it may be another hand).
    fn try_session(&mut self) -> Try {
        match self.connector.open() {
            Ok(conn) => self.conn = Some(conn),
            Err(e) => return Try::Again(e.to_string()),
        }
        self.reset_decoder();
        self.clock.reset();
        // Another hand, or the same one after its watchdog: only its HELLO
        // says what state it is in.
        self.last_ack = None;
        match self.hello() {
            Ok(()) => {
                self.session += 1;
                Try::Session
            }
            Err(Some(e)) => {
                self.conn = None;
                Try::GiveUp(e)
            }
            Err(None) => {
                self.conn = None;
                Try::Again("the device vanished during HELLO".to_string())
            }
        }
    }

    /// HELLO with retries but without reconnecting. `Err(None)`: I/O error.
    fn hello(&mut self) -> Result<(), Option<LinkError>> {
        let command = Command::Hello {
            watchdog_ms: self.cfg.watchdog_ms,
        };
        let seq = self.alloc_seq();
        let packet = command.packet(seq, HandTime(0)).encode(); // HELLO has no deadline
        let attempts = 1 + self.cfg.retries;
        for attempt in 1..=attempts {
            if attempt > 1 {
                self.stats.retransmissions += 1;
            }
            match self.exchange(&packet, seq, command.code()) {
                Ok(Wait::Acked(ack)) => {
                    return self
                        .accept(command, ack, attempt, Instant::now())
                        .map(|_| ())
                        .map_err(Some)
                }
                Ok(Wait::TimedOut) => {}
                Err(_) => return Err(None),
            }
        }
        Err(Some(LinkError::NoAck {
            command: command.name(),
            seq,
            attempts,
            timeout_ms: self.cfg.ack_timeout_ms,
            device: self.device(),
        }))
    }
}
