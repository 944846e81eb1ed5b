//! The host side of the Hannes link: stop-and-wait delivery with an ACK
//! timeout and bounded retries, reconnection when the device disappears, and
//! a heartbeat thread that keeps the hand's watchdog fed.
//!
//! A command counts as executed only once its ACK (same SEQ, same CMD,
//! status OK) came back.
//!
//! A command may have an expiry ([`HandLink::send_until`]): it is never
//! transmitted at or after it, no reconnect waits past it, and PRESHAPE and
//! CLOSE carry it to the hand as a deadline on the hand's clock
//! ([`HandClock`]), so a frame delayed on the way is refused by the hand
//! instead of executed late.
//!
//! A command may also be given a stop flag ([`Hand::send_unless_stopped`]):
//! once it is set (a signal), no copy is transmitted and no reconnect is
//! waited for. The ACK wait of a copy already sent still runs out (one
//! `ack_timeout_ms` at most), so the caller learns whether it arrived.

use crate::decoder::{Decoder, DecoderStats};
use crate::protocol::{Ack, Command, HandTime, Status};
use crate::transport::{is_timeout, Connector, Duplex};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Link timing. All durations in milliseconds so config files stay plain.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LinkConfig {
    /// How long to wait for the ACK of one transmission.
    pub ack_timeout_ms: u64,
    /// Retransmissions after the first attempt (same SEQ).
    pub retries: u32,
    /// A heartbeat is sent when nothing else was sent for this long.
    pub heartbeat_interval_ms: u64,
    /// Silence after which the hand opens itself (sent in HELLO).
    pub watchdog_ms: u16,
    /// Pause between attempts to re-open a vanished device.
    pub reconnect_interval_ms: u64,
    /// Give up re-opening after this long (the next command tries again).
    pub reconnect_timeout_ms: u64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        LinkConfig {
            ack_timeout_ms: 100,
            retries: 3,
            heartbeat_interval_ms: 200,
            watchdog_ms: 1000,
            reconnect_interval_ms: 100,
            reconnect_timeout_ms: 5000,
        }
    }
}

impl LinkConfig {
    fn ack_timeout(&self) -> Duration {
        Duration::from_millis(self.ack_timeout_ms)
    }

    /// Rejects settings under which the hand would open itself between two
    /// heartbeats.
    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!(self.ack_timeout_ms > 0, "link.ack_timeout_ms must be > 0");
        anyhow::ensure!(
            self.heartbeat_interval_ms > 0
                && self.heartbeat_interval_ms * 2 <= u64::from(self.watchdog_ms),
            "link.heartbeat_interval_ms ({}) must be > 0 and at most half of link.watchdog_ms ({})",
            self.heartbeat_interval_ms,
            self.watchdog_ms
        );
        Ok(())
    }
}

#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("{command} (seq {seq}) was not acknowledged by the hand on {device} after {attempts} attempts of {timeout_ms} ms each")]
    NoAck {
        command: &'static str,
        seq: u8,
        attempts: u32,
        timeout_ms: u64,
        device: String,
    },
    #[error("hand on {device} rejected {command} (seq {seq}) with status {status:?}")]
    Rejected {
        command: &'static str,
        seq: u8,
        status: Status,
        device: String,
    },
    #[error(
        "cannot reach the hand on {device} (gave up re-opening after {waited_ms} ms): {last_error}"
    )]
    Disconnected {
        device: String,
        waited_ms: u64,
        last_error: String,
    },
    /// The command's expiry came before its ACK: it is not transmitted
    /// again. If `transmissions` > 0 an earlier copy may have reached the
    /// hand in time (its ACK lost); the hand refuses one that arrives late.
    #[error("{command} (seq {seq}) expired before the hand on {device} acknowledged it ({transmissions} transmissions); not sent again")]
    Expired {
        command: &'static str,
        seq: u8,
        transmissions: u32,
        device: String,
    },
    /// A stop was requested (a signal) before the ACK: the command is not
    /// transmitted again. If `transmissions` > 0 a copy may have reached
    /// the hand.
    #[error("{command} (seq {seq}) was not sent again to the hand on {device}: stop requested ({transmissions} transmissions)")]
    Stopped {
        command: &'static str,
        seq: u8,
        transmissions: u32,
        device: String,
    },
}

/// An acknowledged command.
#[derive(Debug, Clone, Copy)]
pub struct Delivery {
    pub ack: Ack,
    pub attempts: u32,
    /// From the first transmission to the ACK (reconnects included).
    pub elapsed: Duration,
}

#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct LinkStats {
    pub transmissions: u64,
    pub retransmissions: u64,
    pub acked: u64,
    pub heartbeats: u64,
    /// ACKs that did not match the frame in flight (late, duplicated).
    pub stale_acks: u64,
    /// Sessions re-established after the device was lost.
    pub reconnects: u64,
    pub rx_crc_errors: u64,
    pub rx_discarded_bytes: u64,
}

enum Wait {
    Acked(Ack),
    TimedOut,
}

/// How many recent ACKs the clock estimate looks at (3 s of heartbeats at
/// the default interval): recent enough that clock drift (tens of ppm) is
/// negligible, enough that one ACK sent without delay is among them.
const CLOCK_SAMPLES: usize = 16;

/// The host's estimate of the hand's clock, from the hand time stamped in
/// each ACK. An ACK stamped `h` (whole milliseconds, rounded down) and
/// received at host time `r` bounds the offset (hand minus host) from
/// below, by the ACK's travel time. The largest recent bound is the
/// estimate, so a host instant converted with it lands at or before the
/// true hand time: a deadline on the hand's clock can only come early.
#[derive(Debug)]
pub struct HandClock {
    epoch: Instant,
    /// The last sample's raw and unwrapped hand time (ms).
    last: Option<(u32, i64)>,
    /// Offsets, hand minus host, in microseconds.
    offsets_us: VecDeque<i64>,
}

impl HandClock {
    pub fn new() -> Self {
        HandClock {
            epoch: Instant::now(),
            last: None,
            offsets_us: VecDeque::with_capacity(CLOCK_SAMPLES),
        }
    }

    /// Forgets the samples (a new session may be another hand).
    pub fn reset(&mut self) {
        self.last = None;
        self.offsets_us.clear();
    }

    fn host_us(&self, t: Instant) -> i64 {
        match t.checked_duration_since(self.epoch) {
            Some(d) => d.as_micros() as i64,
            None => -(self.epoch.duration_since(t).as_micros() as i64),
        }
    }

    /// Records an ACK stamped `hand` and received at `received`.
    pub fn observe(&mut self, hand: HandTime, received: Instant) {
        // Unwrapped across the 32-bit wrap of the hand's clock.
        let unwrapped = match self.last {
            None => i64::from(hand.0),
            Some((raw, prev)) => prev + hand.since(HandTime(raw)),
        };
        self.last = Some((hand.0, unwrapped));
        if self.offsets_us.len() == CLOCK_SAMPLES {
            self.offsets_us.pop_front();
        }
        self.offsets_us
            .push_back(unwrapped * 1000 - self.host_us(received));
    }

    /// The hand time at host instant `t` (at or before the true one);
    /// `None` before any sample.
    pub fn to_hand(&self, t: Instant) -> Option<HandTime> {
        let offset = *self.offsets_us.iter().max()?;
        let ms = (self.host_us(t) + offset).div_euclid(1000);
        // Reduced modulo 2^32: the hand's clock wraps.
        Some(HandTime(ms.rem_euclid(1 << 32) as u32))
    }
}

impl Default for HandClock {
    fn default() -> Self {
        Self::new()
    }
}

/// Deadline sent with a command that has no expiry: as far ahead as the
/// hand's wrapping clock can express (24.8 days).
const NO_DEADLINE_MS: u32 = i32::MAX as u32;

/// Single-threaded link. Wrap it in [`Hand`] for the heartbeat.
pub struct HandLink {
    connector: Box<dyn Connector>,
    conn: Option<Box<dyn Duplex>>,
    decoder: Decoder,
    cfg: LinkConfig,
    next_seq: u8,
    last_tx: Instant,
    stats: LinkStats,
    decoder_base: DecoderStats,
    clock: HandClock,
    /// Counts sessions (HELLOs acknowledged): frames are re-encoded for a
    /// new one, whose hand clock may differ.
    session: u64,
    /// The loss of the device was logged (once per outage).
    down_reported: bool,
}

impl HandLink {
    pub fn new(connector: Box<dyn Connector>, cfg: LinkConfig) -> Self {
        HandLink {
            connector,
            conn: None,
            decoder: Decoder::new(),
            cfg,
            next_seq: 0,
            last_tx: Instant::now(),
            stats: LinkStats::default(),
            decoder_base: DecoderStats::default(),
            clock: HandClock::new(),
            session: 0,
            down_reported: false,
        }
    }

    pub fn device(&self) -> String {
        self.connector.describe()
    }

    pub fn config(&self) -> &LinkConfig {
        &self.cfg
    }

    pub fn is_connected(&self) -> bool {
        self.conn.is_some()
    }

    pub fn stats(&self) -> LinkStats {
        let d = self.decoder.stats();
        LinkStats {
            rx_crc_errors: self.decoder_base.crc_errors + d.crc_errors,
            rx_discarded_bytes: self.decoder_base.discarded_bytes + d.discarded_bytes,
            ..self.stats
        }
    }

    /// Time since the last transmission.
    pub fn idle(&self) -> Duration {
        self.last_tx.elapsed()
    }

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
    fn connect_until(
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
            let last_error = match self.connector.open() {
                Ok(conn) => {
                    self.conn = Some(conn);
                    self.reset_decoder();
                    self.clock.reset();
                    match self.hello() {
                        Ok(()) => {
                            self.session += 1;
                            return Ok(());
                        }
                        Err(Some(e)) => {
                            self.conn = None;
                            return Err(Reconnect::Failed(e));
                        }
                        Err(None) => {
                            self.conn = None;
                            "the device vanished during HELLO".to_string()
                        }
                    }
                }
                Err(e) => e.to_string(),
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

    /// Sends `command` and waits for its ACK, retransmitting with the same
    /// SEQ on timeout and re-opening the device if it disappeared.
    pub fn send(&mut self, command: Command) -> Result<Delivery, LinkError> {
        self.send_until(command, None)
    }

    /// [`HandLink::send`] for a command that must not be executed at or
    /// after `expires`: no transmission then, no reconnect waiting past it,
    /// and PRESHAPE and CLOSE carry it to the hand as a deadline.
    pub fn send_until(
        &mut self,
        command: Command,
        expires: Option<Instant>,
    ) -> Result<Delivery, LinkError> {
        self.send_unless_stopped(command, expires, None)
    }

    /// [`HandLink::send_until`] that transmits nothing more once `stop` is
    /// set ([`LinkError::Stopped`]).
    pub fn send_unless_stopped(
        &mut self,
        command: Command,
        expires: Option<Instant>,
        stop: Option<&AtomicBool>,
    ) -> Result<Delivery, LinkError> {
        let seq = self.alloc_seq();
        let started = Instant::now();
        let max_attempts = 1 + self.cfg.retries;
        let mut attempts = 0;
        let transmitted_before = self.stats.transmissions;
        let expired = |link: &HandLink| LinkError::Expired {
            command: command.name(),
            seq,
            transmissions: (link.stats.transmissions - transmitted_before) as u32,
            device: link.device(),
        };
        let stopped = |link: &HandLink| LinkError::Stopped {
            command: command.name(),
            seq,
            transmissions: (link.stats.transmissions - transmitted_before) as u32,
            device: link.device(),
        };
        // The frame, encoded once per session so retransmissions are
        // byte-identical (the hand's duplicate filter relies on it).
        let mut packet: Option<(u64, Vec<u8>)> = None;
        while attempts < max_attempts {
            if expires.is_some_and(|e| Instant::now() >= e) {
                return Err(expired(self));
            }
            if is_set(stop) {
                return Err(stopped(self));
            }
            if self.conn.is_none() {
                if !self.down_reported {
                    tracing::warn!(device = %self.device(), "link down: re-opening");
                    self.down_reported = true;
                }
                match self.connect_until(expires, stop) {
                    Ok(()) => {
                        self.stats.reconnects += 1;
                        self.down_reported = false;
                        tracing::info!(device = %self.device(), "link re-established");
                    }
                    Err(Reconnect::Failed(e)) => return Err(e),
                    Err(Reconnect::Expired) => return Err(expired(self)),
                    Err(Reconnect::Stopped) => return Err(stopped(self)),
                }
                continue; // the expiry is checked again after the wait
            }
            let bytes = match &packet {
                Some((session, bytes)) if *session == self.session => bytes.clone(),
                _ => {
                    let deadline = match command.has_deadline() {
                        true => self.deadline_on_hand(expires),
                        false => Some(HandTime(0)), // not carried
                    };
                    let Some(deadline) = deadline else {
                        self.drop_connection(); // no clock sample: start over
                        continue;
                    };
                    let bytes = command.packet(seq, deadline).encode();
                    packet = Some((self.session, bytes.clone()));
                    bytes
                }
            };
            attempts += 1;
            if attempts > 1 {
                self.stats.retransmissions += 1;
            }
            match self.exchange(&bytes, seq, command.code()) {
                Ok(Wait::Acked(ack)) => return self.accept(command, ack, attempts, started),
                Ok(Wait::TimedOut) => tracing::debug!(
                    command = command.name(),
                    seq,
                    attempt = attempts,
                    "no ACK within {} ms",
                    self.cfg.ack_timeout_ms
                ),
                Err(e) => {
                    tracing::warn!(device = %self.device(), error = %e, "device lost");
                    self.drop_connection();
                }
            }
        }
        Err(LinkError::NoAck {
            command: command.name(),
            seq,
            attempts,
            timeout_ms: self.cfg.ack_timeout_ms,
            device: self.device(),
        })
    }

    /// `expires` on the hand's clock (far ahead without an expiry).
    fn deadline_on_hand(&self, expires: Option<Instant>) -> Option<HandTime> {
        match expires {
            Some(e) => self.clock.to_hand(e),
            None => Some(self.clock.to_hand(Instant::now())?.plus_ms(NO_DEADLINE_MS)),
        }
    }

    fn accept(
        &mut self,
        command: Command,
        ack: Ack,
        attempts: u32,
        started: Instant,
    ) -> Result<Delivery, LinkError> {
        if ack.status != Status::Ok {
            return Err(LinkError::Rejected {
                command: command.name(),
                seq: ack.seq,
                status: ack.status,
                device: self.device(),
            });
        }
        self.stats.acked += 1;
        if command == Command::Heartbeat {
            self.stats.heartbeats += 1;
        }
        Ok(Delivery {
            ack,
            attempts,
            elapsed: started.elapsed(),
        })
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

    /// One transmission and the wait for its ACK.
    fn exchange(&mut self, packet: &[u8], seq: u8, code: u8) -> io::Result<Wait> {
        let conn = self.conn.as_mut().expect("exchange needs a connection");
        conn.write_all(packet)?;
        conn.flush()?;
        self.stats.transmissions += 1;
        self.last_tx = Instant::now();
        let deadline = self.last_tx + self.cfg.ack_timeout();
        let mut buf = [0u8; 256];
        loop {
            while let Some(p) = self.decoder.next_packet() {
                let ack = Ack::parse(&p);
                if let Some(a) = &ack {
                    // Any ACK of this session stamps the hand's clock.
                    self.clock.observe(a.hand_time, Instant::now());
                }
                match ack {
                    Some(ack) if ack.seq == seq && ack.cmd == code => return Ok(Wait::Acked(ack)),
                    _ => self.stats.stale_acks += 1,
                }
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(Wait::TimedOut);
            }
            let conn = self.conn.as_mut().expect("connection checked above");
            conn.set_read_timeout(deadline - now)?;
            match conn.read(&mut buf) {
                Ok(0) => {
                    return Err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "device closed",
                    ))
                }
                Ok(n) => self.decoder.push(&buf[..n]),
                Err(e) if is_timeout(&e) => {}
                Err(e) => return Err(e),
            }
        }
    }

    fn drop_connection(&mut self) {
        self.conn = None;
        self.reset_decoder();
    }

    fn reset_decoder(&mut self) {
        let d = self.decoder.stats();
        self.decoder_base.crc_errors += d.crc_errors;
        self.decoder_base.discarded_bytes += d.discarded_bytes;
        self.decoder = Decoder::new();
    }

    fn alloc_seq(&mut self) -> u8 {
        let seq = self.next_seq;
        self.next_seq = self.next_seq.wrapping_add(1);
        seq
    }
}

/// Why a reconnect ended without a session.
enum Reconnect {
    Failed(LinkError),
    /// The command's expiry came first.
    Expired,
    /// A stop was requested.
    Stopped,
}

fn is_set(flag: Option<&AtomicBool>) -> bool {
    flag.is_some_and(|f| f.load(Ordering::SeqCst))
}

/// A [`HandLink`] shared with a heartbeat thread.
pub struct Hand {
    link: Arc<Mutex<HandLink>>,
    stop: Arc<AtomicBool>,
    heartbeat: Option<JoinHandle<()>>,
}

impl Hand {
    /// Connects (HELLO) and starts the heartbeat.
    pub fn start(mut link: HandLink) -> anyhow::Result<Hand> {
        link.cfg.validate()?;
        link.connect()?;
        let interval = Duration::from_millis(link.cfg.heartbeat_interval_ms);
        let link = Arc::new(Mutex::new(link));
        let stop = Arc::new(AtomicBool::new(false));
        let heartbeat = {
            let (link, stop) = (link.clone(), stop.clone());
            std::thread::Builder::new()
                .name("hannes-heartbeat".into())
                .spawn(move || heartbeat_loop(&link, &stop, interval))?
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand whose clock reads `hand_zero_ms` at the host clock's epoch.
    fn sample(clock: &mut HandClock, hand_zero_ms: u32, sent_ms: u64, travel_us: u64) {
        let stamped = HandTime(hand_zero_ms.wrapping_add(sent_ms as u32));
        let received =
            clock.epoch + Duration::from_millis(sent_ms) + Duration::from_micros(travel_us);
        clock.observe(stamped, received);
    }

    #[test]
    fn the_estimate_never_runs_ahead_of_the_hand() {
        let mut clock = HandClock::new();
        assert_eq!(clock.to_hand(clock.epoch), None, "no sample yet");
        // ACKs sent at whole hand milliseconds, delayed 0.3 to 80 ms.
        for (i, travel_us) in [80_000, 300, 5_000, 40_000].iter().enumerate() {
            sample(&mut clock, 1_000, 100 * i as u64, *travel_us);
        }
        for at_ms in [0, 250, 10_000] {
            let t = clock.epoch + Duration::from_millis(at_ms);
            let estimate = clock.to_hand(t).unwrap();
            let truth = HandTime(1_000 + at_ms as u32);
            assert!(!truth.is_before(estimate), "{estimate:?} after {truth:?}");
            // The quickest ACK (0.3 ms) makes it good to a millisecond.
            assert!(truth.since(estimate) <= 1, "{estimate:?} vs {truth:?}");
        }
    }

    #[test]
    fn the_estimate_follows_the_hand_clock_across_its_wrap() {
        let mut clock = HandClock::new();
        let zero = u32::MAX - 150; // wraps 150 ms after the host's epoch
        for i in 0..6 {
            sample(&mut clock, zero, 100 * i, 200);
        }
        let t = clock.epoch + Duration::from_millis(700);
        let truth = HandTime(zero.wrapping_add(700));
        assert_eq!(truth, HandTime(549), "past the wrap");
        // The 0.2 ms travel time rounds the estimate a millisecond early.
        assert_eq!(clock.to_hand(t), Some(HandTime(548)));
    }

    #[test]
    fn a_new_session_forgets_the_old_hand() {
        let mut clock = HandClock::new();
        sample(&mut clock, 50_000, 0, 100);
        clock.reset();
        sample(&mut clock, 7, 10, 100);
        let t = clock.epoch + Duration::from_millis(20);
        // The new hand reads 27 then; the 0.1 ms travel time rounds down.
        assert_eq!(clock.to_hand(t), Some(HandTime(26)));
    }
}
