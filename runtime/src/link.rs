//! The host side of the Hannes link: stop-and-wait delivery with an ACK
//! timeout and bounded retries, reconnection when the device disappears, and
//! a heartbeat thread that keeps the hand's watchdog fed.
//!
//! A command counts as executed only once its ACK (same SEQ, same CMD,
//! status OK) came back.

use crate::decoder::{Decoder, DecoderStats};
use crate::protocol::{Ack, Command, Status};
use crate::transport::{is_timeout, Connector, Duplex};
use serde::{Deserialize, Serialize};
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
    pub reconnects: u64,
    pub rx_crc_errors: u64,
    pub rx_discarded_bytes: u64,
}

enum Wait {
    Acked(Ack),
    TimedOut,
}

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
        if self.conn.is_some() {
            return Ok(());
        }
        let started = Instant::now();
        let budget = Duration::from_millis(self.cfg.reconnect_timeout_ms);
        loop {
            let last_error = match self.connector.open() {
                Ok(conn) => {
                    self.conn = Some(conn);
                    self.reset_decoder();
                    match self.hello() {
                        Ok(()) => return Ok(()),
                        Err(Some(e)) => {
                            self.conn = None;
                            return Err(e);
                        }
                        Err(None) => {
                            self.conn = None;
                            "the device vanished during HELLO".to_string()
                        }
                    }
                }
                Err(e) => e.to_string(),
            };
            if started.elapsed() >= budget {
                return Err(LinkError::Disconnected {
                    device: self.device(),
                    waited_ms: started.elapsed().as_millis() as u64,
                    last_error,
                });
            }
            std::thread::sleep(Duration::from_millis(self.cfg.reconnect_interval_ms));
        }
    }

    /// Sends `command` and waits for its ACK, retransmitting with the same
    /// SEQ on timeout and re-opening the device if it disappeared.
    pub fn send(&mut self, command: Command) -> Result<Delivery, LinkError> {
        let seq = self.alloc_seq();
        let packet = command.packet(seq).encode();
        let started = Instant::now();
        let max_attempts = 1 + self.cfg.retries;
        let mut attempts = 0;
        while attempts < max_attempts {
            if self.conn.is_none() {
                self.stats.reconnects += 1;
                tracing::warn!(device = %self.device(), "link down: re-opening");
                self.connect()?;
                tracing::info!(device = %self.device(), "link re-established");
            }
            attempts += 1;
            if attempts > 1 {
                self.stats.retransmissions += 1;
            }
            match self.exchange(&packet, seq, command.code()) {
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
        let packet = command.packet(seq).encode();
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
                match Ack::parse(&p) {
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
        let delivery = lock(&self.link).send(command);
        match &delivery {
            Ok(d) => tracing::info!(
                command = command.name(),
                seq = d.ack.seq,
                attempts = d.attempts,
                latency_ms = d.elapsed.as_secs_f64() * 1e3,
                state = ?d.ack.state,
                "acknowledged"
            ),
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
        if let Err(e) = link.send(Command::Heartbeat) {
            tracing::warn!("heartbeat failed: {e}");
        }
    }
}
