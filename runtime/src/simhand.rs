//! A simulated Hannes hand: the device side of docs/hannes-protocol.md.
//! It decodes frames (resynchronising on the start byte), checks CRC and
//! sequence numbers, acknowledges (duplicates idempotently, without executing
//! them again), logs every commanded configuration, and opens the hand when
//! the link stays silent longer than the watchdog.

use crate::decoder::Decoder;
use crate::protocol::{cmd, Ack, Command, HandState, Packet, Status};
use crate::transport::{is_timeout, Duplex};
use grasp_schema::taxonomy::{HandConfiguration, Preshape, Thumb};
use serde::Serialize;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Watchdog used until a HELLO sets one.
pub const DEFAULT_WATCHDOG: Duration = Duration::from_millis(1000);

/// Something the hand did, as logged (one JSON line each on the CLI).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum HandEvent {
    Hello {
        seq: u8,
        watchdog_ms: u16,
    },
    Preshape {
        seq: u8,
        thumb: Thumb,
        three_digit: bool,
        /// The pre-shape with this configuration (Table 1).
        preshape: Option<Preshape>,
    },
    Close {
        seq: u8,
    },
    Open {
        seq: u8,
    },
    /// A retransmission of the last executed frame: acknowledged again,
    /// not executed again.
    Duplicate {
        seq: u8,
        cmd: u8,
    },
    Rejected {
        seq: u8,
        cmd: u8,
        status: String,
    },
    /// The link was silent too long: the hand opened itself.
    WatchdogOpen {
        silent_ms: u64,
    },
}

/// The pre-shape whose Table 1 configuration is `c`.
pub fn preshape_of(c: HandConfiguration) -> Option<Preshape> {
    Preshape::ALL
        .into_iter()
        .find(|p| p.hand_configuration() == c)
}

/// The hand's state machine, free of I/O so it can be tested directly.
#[derive(Debug)]
pub struct SimHand {
    state: HandState,
    config: HandConfiguration,
    watchdog: Duration,
    last_rx: Option<Instant>,
    /// Last executed frame and its ACK, for idempotent retransmissions.
    last: Option<(Packet, Ack)>,
}

impl Default for SimHand {
    fn default() -> Self {
        SimHand {
            state: HandState::Open,
            config: Preshape::Power.hand_configuration(),
            watchdog: DEFAULT_WATCHDOG,
            last_rx: None,
            last: None,
        }
    }
}

impl SimHand {
    pub fn state(&self) -> HandState {
        self.state
    }

    pub fn config(&self) -> HandConfiguration {
        self.config
    }

    /// Handles one valid frame; returns the ACK to send (if the frame is a
    /// command) and what happened.
    pub fn on_packet(&mut self, p: &Packet, now: Instant) -> (Option<Ack>, Option<HandEvent>) {
        self.last_rx = Some(now);
        if p.cmd == cmd::ACK {
            return (None, None); // not ours: the hand never receives ACKs
        }
        if let Some((last, ack)) = &self.last {
            if last == p {
                let event = HandEvent::Duplicate {
                    seq: p.seq,
                    cmd: p.cmd,
                };
                return (Some(*ack), Some(event));
            }
        }
        let (status, event) = match Command::parse(p) {
            Ok(c) => (Status::Ok, self.execute(p.seq, c)),
            Err(status) => (
                status,
                Some(HandEvent::Rejected {
                    seq: p.seq,
                    cmd: p.cmd,
                    status: format!("{status:?}"),
                }),
            ),
        };
        let ack = Ack {
            seq: p.seq,
            cmd: p.cmd,
            status,
            state: self.state,
            config: self.config,
        };
        self.last = match p.cmd {
            cmd::HELLO => None, // a new session: nothing to deduplicate against
            _ => Some((p.clone(), ack)),
        };
        (Some(ack), event)
    }

    fn execute(&mut self, seq: u8, c: Command) -> Option<HandEvent> {
        match c {
            Command::Hello { watchdog_ms } => {
                self.watchdog = Duration::from_millis(u64::from(watchdog_ms));
                Some(HandEvent::Hello { seq, watchdog_ms })
            }
            Command::Heartbeat => None,
            Command::Preshape(config) => {
                self.config = config;
                self.state = HandState::Preshaped;
                Some(HandEvent::Preshape {
                    seq,
                    thumb: config.thumb,
                    three_digit: config.three_digit,
                    preshape: preshape_of(config),
                })
            }
            Command::Close => {
                self.state = HandState::Closed;
                Some(HandEvent::Close { seq })
            }
            Command::Open => {
                self.state = HandState::Open;
                Some(HandEvent::Open { seq })
            }
        }
    }

    /// Opens the hand if the link has been silent longer than the watchdog.
    pub fn on_tick(&mut self, now: Instant) -> Option<HandEvent> {
        let last = self.last_rx?;
        let silent = now.saturating_duration_since(last);
        if self.state == HandState::Open || silent <= self.watchdog {
            return None;
        }
        self.state = HandState::Open;
        Some(HandEvent::WatchdogOpen {
            silent_ms: silent.as_millis() as u64,
        })
    }
}

/// Serves one open port until `stop` is set or the port fails.
pub fn serve(
    port: &mut dyn Duplex,
    hand: &Mutex<SimHand>,
    stop: &AtomicBool,
    on_event: &mut dyn FnMut(HandEvent),
) -> io::Result<()> {
    let mut decoder = Decoder::new();
    let mut buf = [0u8; 256];
    port.set_read_timeout(Duration::from_millis(5))?;
    while !stop.load(Ordering::Relaxed) {
        match port.read(&mut buf) {
            Ok(0) => return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "port closed")),
            Ok(n) => decoder.push(&buf[..n]),
            Err(e) if is_timeout(&e) => {}
            Err(e) => return Err(e),
        }
        while let Some(p) = decoder.next_packet() {
            let (ack, event) = lock(hand).on_packet(&p, Instant::now());
            if let Some(ack) = ack {
                port.write_all(&ack.packet().encode())?;
                port.flush()?;
            }
            event.into_iter().for_each(&mut *on_event);
        }
        if let Some(e) = lock(hand).on_tick(Instant::now()) {
            on_event(e);
        }
    }
    Ok(())
}

fn lock(hand: &Mutex<SimHand>) -> std::sync::MutexGuard<'_, SimHand> {
    hand.lock().unwrap_or_else(|p| p.into_inner())
}

/// A simulated hand running on its own thread, with its event log.
pub struct RunningHand {
    hand: Arc<Mutex<SimHand>>,
    events: Arc<Mutex<Vec<HandEvent>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<()>>>,
}

impl RunningHand {
    /// Serves `port` on a new thread; `sink` also sees every event.
    pub fn spawn(
        mut port: Box<dyn Duplex>,
        mut sink: impl FnMut(&HandEvent) + Send + 'static,
    ) -> io::Result<RunningHand> {
        let hand = Arc::new(Mutex::new(SimHand::default()));
        let events = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (hand, events, stop) = (hand.clone(), events.clone(), stop.clone());
            std::thread::Builder::new()
                .name("simulated-hand".into())
                .spawn(move || {
                    serve(&mut *port, &hand, &stop, &mut |e| {
                        sink(&e);
                        events.lock().unwrap_or_else(|p| p.into_inner()).push(e);
                    })
                })?
        };
        Ok(RunningHand {
            hand,
            events,
            stop,
            thread: Some(thread),
        })
    }

    pub fn state(&self) -> (HandState, HandConfiguration) {
        let h = lock(&self.hand);
        (h.state(), h.config())
    }

    pub fn events(&self) -> Vec<HandEvent> {
        self.events
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    /// Whether the serving thread ended (port failure).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Stops serving and returns how the serving loop ended.
    pub fn stop(mut self) -> io::Result<()> {
        self.halt()
    }

    fn halt(&mut self) -> io::Result<()> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take() {
            Some(t) => t
                .join()
                .unwrap_or_else(|_| Err(io::Error::other("simulated hand panicked"))),
            None => Ok(()),
        }
    }
}

impl Drop for RunningHand {
    fn drop(&mut self) {
        let _ = self.halt();
    }
}

/// A simulated hand on a fresh pseudo-terminal pair. The host opens
/// [`PtyHand::path`], a symlink to the slave side, the way udev's
/// `/dev/serial/by-id` links name a real adapter. Dropping it "unplugs" the
/// device: the slave side hangs up and the link disappears.
pub struct PtyHand {
    pub hand: RunningHand,
    path: PathBuf,
    /// Keeps the slave side open so the master never sees a hangup while
    /// the host is between connections.
    _slave: std::fs::File,
}

impl PtyHand {
    pub fn plug(
        link_path: &Path,
        sink: impl FnMut(&HandEvent) + Send + 'static,
    ) -> anyhow::Result<PtyHand> {
        let (master, slave) = pty_pair(link_path)?;
        let hand = RunningHand::spawn(Box::new(master), sink)?;
        Ok(PtyHand {
            hand,
            path: link_path.to_path_buf(),
            _slave: slave,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// A pseudo-terminal pair whose slave side is reachable at `link_path`.
/// Returns the master and a plain handle keeping the slave open. The plain
/// handle takes no lock, so the host may open the slave exclusively.
pub fn pty_pair(link_path: &Path) -> anyhow::Result<(serialport::TTYPort, std::fs::File)> {
    use anyhow::Context;
    use std::os::unix::fs::OpenOptionsExt;
    let (master, slave) =
        serialport::TTYPort::pair().context("cannot create a pseudo-terminal pair")?;
    let target =
        serialport::SerialPort::name(&slave).context("the pseudo-terminal has no slave name")?;
    let keep = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOCTTY)
        .open(&target)
        .with_context(|| format!("cannot open {target}"))?;
    drop(slave);
    replace_symlink(Path::new(&target), link_path)?;
    Ok((master, keep))
}

/// Points `link` at `target`, atomically (temp link + rename).
pub fn replace_symlink(target: &Path, link: &Path) -> anyhow::Result<()> {
    use anyhow::Context;
    let tmp = link.with_extension(format!("tmp{}", std::process::id()));
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(target, &tmp)
        .with_context(|| format!("cannot create symlink {}", tmp.display()))?;
    std::fs::rename(&tmp, link)
        .with_context(|| format!("cannot move symlink into place at {}", link.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::preshape_command;

    #[test]
    fn executes_acks_and_deduplicates_retransmissions() {
        let mut hand = SimHand::default();
        let t = Instant::now();
        let (ack, ev) = hand.on_packet(&Command::Hello { watchdog_ms: 50 }.packet(0), t);
        assert_eq!(ack.unwrap().status, Status::Ok);
        assert_eq!(
            ev,
            Some(HandEvent::Hello {
                seq: 0,
                watchdog_ms: 50
            })
        );
        let p = preshape_command(Preshape::Lateral).packet(1);
        let (first, ev) = hand.on_packet(&p, t);
        assert!(matches!(
            ev,
            Some(HandEvent::Preshape {
                preshape: Some(Preshape::Lateral),
                ..
            })
        ));
        assert_eq!(hand.state(), HandState::Preshaped);
        // The hand closes; a late retransmission of the pre-shape must not
        // re-open the fingers into the pre-shape.
        hand.on_packet(&Command::Close.packet(2), t);
        let (again, ev) = hand.on_packet(&Command::Close.packet(2), t);
        assert_eq!(
            ev,
            Some(HandEvent::Duplicate {
                seq: 2,
                cmd: cmd::CLOSE
            })
        );
        assert_eq!(again.unwrap().state, HandState::Closed);
        assert_eq!(
            first.unwrap().config,
            Preshape::Lateral.hand_configuration()
        );
    }

    #[test]
    fn rejects_bad_payloads_with_a_status() {
        let mut hand = SimHand::default();
        let bad = Packet {
            seq: 4,
            cmd: cmd::PRESHAPE,
            payload: vec![7, 0],
        };
        let (ack, ev) = hand.on_packet(&bad, Instant::now());
        assert_eq!(ack.unwrap().status, Status::BadPayload);
        assert!(matches!(ev, Some(HandEvent::Rejected { .. })));
        assert_eq!(hand.state(), HandState::Open);
    }

    #[test]
    fn watchdog_opens_only_after_the_silence_exceeds_it() {
        let mut hand = SimHand::default();
        let t0 = Instant::now();
        hand.on_packet(&Command::Hello { watchdog_ms: 100 }.packet(0), t0);
        hand.on_packet(&preshape_command(Preshape::Pinch).packet(1), t0);
        assert_eq!(hand.on_tick(t0 + Duration::from_millis(100)), None);
        assert_eq!(
            hand.on_tick(t0 + Duration::from_millis(101)),
            Some(HandEvent::WatchdogOpen { silent_ms: 101 })
        );
        assert_eq!(hand.state(), HandState::Open);
        // Already open: no repeated event.
        assert_eq!(hand.on_tick(t0 + Duration::from_millis(500)), None);
    }

    #[test]
    fn every_configuration_maps_back_to_its_preshape() {
        for p in Preshape::ALL {
            assert_eq!(preshape_of(p.hand_configuration()), Some(p));
        }
    }
}
