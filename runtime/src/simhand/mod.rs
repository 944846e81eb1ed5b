//! A simulated Hannes hand: the device side of docs/hannes-protocol.md.
//! It decodes frames (resynchronising on the start byte), checks CRC and
//! sequence numbers, acknowledges (duplicates idempotently, without executing
//! them again), refuses commands whose deadline passed, logs every commanded
//! configuration, and opens the hand when the link stays silent longer than
//! the watchdog.
//!
//! - [`SimHand`]: the state machine, free of I/O;
//! - [`RunningHand`] (`server`): serves it on a port in a thread, unplugs
//!   and re-plugs it, and injects link faults ([`FaultSpec`], `faults`);
//! - [`PtyHand`] (`pty`): a hand on a fresh pseudo-terminal reached through
//!   a link whose owner is recorded (`crate::ptylink`).

mod faults;
mod pty;
mod server;

pub use crate::ptylink::{pty_pair, replace_symlink};
pub use faults::{FaultKind, FaultSpec, Toward};
pub use pty::{PtyHand, PtyHandError, PtyPlug};
pub use server::{DevicePort, OpenPort, Plug, RunningHand};

use crate::protocol::{cmd, Ack, Command, HandState, HandTime, Packet, Status};
use grasp_schema::taxonomy::{HandConfiguration, Preshape, Thumb};
use serde::Serialize;
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
    /// A PRESHAPE or CLOSE that arrived after its deadline: refused, not
    /// executed.
    Expired {
        seq: u8,
        cmd: u8,
        /// How long after the deadline it arrived.
        late_ms: i64,
    },
    /// The link was silent too long: the hand opened itself.
    WatchdogOpen {
        silent_ms: u64,
    },
    /// The hand's side of the link was disconnected (an injected fault, a
    /// request, or the port failed).
    Unplugged {
        reason: String,
        /// When it plugs back in by itself.
        for_ms: Option<u64>,
    },
    /// Connected again after [`HandEvent::Unplugged`].
    Replugged {
        device: String,
    },
    /// An injected link fault hit a frame.
    Fault {
        fault: FaultKind,
        toward: Toward,
        seq: u8,
        cmd: u8,
    },
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
    /// Zero of the hand's clock.
    epoch: Instant,
}

impl Default for SimHand {
    fn default() -> Self {
        SimHand::new(Instant::now())
    }
}

impl SimHand {
    /// A hand whose clock reads 0 at `epoch`.
    pub fn new(epoch: Instant) -> Self {
        SimHand {
            state: HandState::Open,
            config: Preshape::Power.hand_configuration(),
            watchdog: DEFAULT_WATCHDOG,
            last_rx: None,
            last: None,
            epoch,
        }
    }

    pub fn state(&self) -> HandState {
        self.state
    }

    pub fn config(&self) -> HandConfiguration {
        self.config
    }

    /// The hand's clock at `now`.
    pub fn clock(&self, now: Instant) -> HandTime {
        // Truncating to 32 bits is the clock's wrap-around.
        HandTime(now.saturating_duration_since(self.epoch).as_millis() as u32)
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
        let clock = self.clock(now);
        let (status, event) = match Command::parse(p) {
            Ok((_, Some(deadline))) if !clock.is_before(deadline) => (
                Status::Expired,
                Some(HandEvent::Expired {
                    seq: p.seq,
                    cmd: p.cmd,
                    late_ms: clock.since(deadline),
                }),
            ),
            Ok((c, _)) => (Status::Ok, self.execute(p.seq, c)),
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
            hand_time: clock,
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
                    preshape: Preshape::of_configuration(config),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::preshape_command;

    /// A deadline far ahead of a fresh hand's clock.
    const LATER: HandTime = HandTime(1 << 30);

    #[test]
    fn executes_acks_and_deduplicates_retransmissions() {
        let mut hand = SimHand::default();
        let t = Instant::now();
        let (ack, ev) = hand.on_packet(&Command::Hello { watchdog_ms: 50 }.packet(0, LATER), t);
        assert_eq!(ack.unwrap().status, Status::Ok);
        assert_eq!(
            ev,
            Some(HandEvent::Hello {
                seq: 0,
                watchdog_ms: 50
            })
        );
        let p = preshape_command(Preshape::Lateral).packet(1, LATER);
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
        hand.on_packet(&Command::Close.packet(2, LATER), t);
        let (again, ev) = hand.on_packet(&Command::Close.packet(2, LATER), t);
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
            payload: vec![7, 0, 0, 0, 0, 0],
        };
        let (ack, ev) = hand.on_packet(&bad, Instant::now());
        assert_eq!(ack.unwrap().status, Status::BadPayload);
        assert!(matches!(ev, Some(HandEvent::Rejected { .. })));
        assert_eq!(hand.state(), HandState::Open);
    }

    #[test]
    fn a_command_arriving_at_or_after_its_deadline_is_refused() {
        let epoch = Instant::now();
        let mut hand = SimHand::new(epoch);
        let at = |ms| epoch + Duration::from_millis(ms);
        let deadline = HandTime(500);
        let late = preshape_command(Preshape::Pinch).packet(1, deadline);
        let (ack, ev) = hand.on_packet(&late, at(500));
        let ack = ack.unwrap();
        assert_eq!((ack.status, ack.state), (Status::Expired, HandState::Open));
        assert_eq!(ack.hand_time, HandTime(500));
        assert_eq!(
            ev,
            Some(HandEvent::Expired {
                seq: 1,
                cmd: cmd::PRESHAPE,
                late_ms: 0
            })
        );
        // One millisecond earlier it would have been executed.
        let in_time = preshape_command(Preshape::Pinch).packet(2, HandTime(501));
        let (ack, _) = hand.on_packet(&in_time, at(500));
        assert_eq!(ack.unwrap().state, HandState::Preshaped);
        let (ack, ev) = hand.on_packet(&Command::Close.packet(3, deadline), at(900));
        assert_eq!(ack.unwrap().status, Status::Expired);
        assert!(matches!(ev, Some(HandEvent::Expired { late_ms: 400, .. })));
        assert_eq!(hand.state(), HandState::Preshaped, "no late closure");
    }

    #[test]
    fn watchdog_opens_only_after_the_silence_exceeds_it() {
        let mut hand = SimHand::default();
        let t0 = Instant::now();
        hand.on_packet(&Command::Hello { watchdog_ms: 100 }.packet(0, LATER), t0);
        hand.on_packet(&preshape_command(Preshape::Pinch).packet(1, LATER), t0);
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
            assert_eq!(Preshape::of_configuration(p.hand_configuration()), Some(p));
        }
    }
}
