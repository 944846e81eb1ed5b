//! Stop-and-wait delivery of one command: the same frame retransmitted on
//! a timeout, the device re-opened when it disappeared, never a copy at or
//! after the command's expiry or once a stop is requested.

use super::connect::Reconnect;
use super::exchange::Wait;
use super::{is_set, Delivery, HandLink, LinkError};
use crate::protocol::{Ack, Command, HandState, HandTime, Status};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Deadline sent with a command that has no expiry: as far ahead as the
/// hand's wrapping clock can express (24.8 days).
const NO_DEADLINE_MS: u32 = i32::MAX as u32;

/// A command being delivered, and what its errors report.
struct InFlight {
    command: Command,
    seq: u8,
    /// The link's transmission count before the first copy.
    transmitted_before: u64,
}

impl InFlight {
    fn transmissions(&self, link: &HandLink) -> u32 {
        (link.stats.transmissions - self.transmitted_before) as u32
    }

    fn expired(&self, link: &HandLink) -> LinkError {
        LinkError::Expired {
            command: self.command.name(),
            seq: self.seq,
            transmissions: self.transmissions(link),
            device: link.device(),
        }
    }

    fn stopped(&self, link: &HandLink) -> LinkError {
        LinkError::Stopped {
            command: self.command.name(),
            seq: self.seq,
            transmissions: self.transmissions(link),
            device: link.device(),
        }
    }

    fn unreachable(&self, link: &HandLink, why: Reconnect) -> LinkError {
        match why {
            Reconnect::Failed(e) => e,
            Reconnect::Expired => self.expired(link),
            Reconnect::Stopped => self.stopped(link),
        }
    }
}

impl HandLink {
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
        let flight = InFlight {
            command,
            seq: self.alloc_seq(),
            transmitted_before: self.stats.transmissions,
        };
        let started = Instant::now();
        let max_attempts = 1 + self.cfg.retries;
        let mut attempts = 0;
        let mut packet = None;
        while attempts < max_attempts {
            if expires.is_some_and(|e| Instant::now() >= e) {
                return Err(flight.expired(self));
            }
            if is_set(stop) {
                return Err(flight.stopped(self));
            }
            if self.conn.is_none() {
                self.reconnect(expires, stop)
                    .map_err(|why| flight.unreachable(self, why))?;
                continue; // the expiry is checked again after the wait
            }
            if command == Command::Close {
                // Never close a hand that is not in the pre-shape it
                // acknowledged (after a reconnect: what its HELLO says).
                self.check_shaped(&flight)?;
            }
            let Some(bytes) = self.frame(&flight, expires, &mut packet) else {
                continue;
            };
            attempts += 1;
            if attempts > 1 {
                self.stats.retransmissions += 1;
            }
            match self.exchange(&bytes, flight.seq, command.code()) {
                Ok(Wait::Acked(ack)) => return self.accept(command, ack, attempts, started),
                Ok(Wait::TimedOut) => tracing::debug!(
                    command = command.name(),
                    seq = flight.seq,
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
            seq: flight.seq,
            attempts,
            timeout_ms: self.cfg.ack_timeout_ms,
            device: self.device(),
        })
    }

    /// Re-opens a vanished device; the outage is logged once.
    fn reconnect(
        &mut self,
        expires: Option<Instant>,
        stop: Option<&AtomicBool>,
    ) -> Result<(), Reconnect> {
        if !self.down_reported {
            tracing::warn!(device = %self.device(), "link down: re-opening");
            self.down_reported = true;
        }
        self.connect_until(expires, stop)?;
        self.stats.reconnects += 1;
        self.down_reported = false;
        tracing::info!(device = %self.device(), "link re-established");
        Ok(())
    }

    /// The frame of `flight` in this session. It is encoded once per
    /// session (`packet` keeps it) so retransmissions are byte-identical:
    /// the hand's duplicate filter relies on it. `None` when the deadline
    /// cannot be put on the hand's clock (no sample yet): the connection is
    /// dropped to start over.
    fn frame(
        &mut self,
        flight: &InFlight,
        expires: Option<Instant>,
        packet: &mut Option<(u64, Vec<u8>)>,
    ) -> Option<Vec<u8>> {
        if let Some((session, bytes)) = packet {
            if *session == self.session {
                return Some(bytes.clone());
            }
        }
        let deadline = match flight.command.has_deadline() {
            true => self.deadline_on_hand(expires),
            false => Some(HandTime(0)), // not carried
        };
        let Some(deadline) = deadline else {
            self.drop_connection(); // no clock sample: start over
            return None;
        };
        let bytes = flight.command.packet(flight.seq, deadline).encode();
        *packet = Some((self.session, bytes.clone()));
        Some(bytes)
    }

    /// `expires` on the hand's clock (far ahead without an expiry).
    fn deadline_on_hand(&self, expires: Option<Instant>) -> Option<HandTime> {
        match expires {
            Some(e) => self.clock.to_hand(e),
            None => Some(self.clock.to_hand(Instant::now())?.plus_ms(NO_DEADLINE_MS)),
        }
    }

    /// A CLOSE may go out only while the hand's last ACK says it is
    /// pre-shaped in the configuration of the last executed PRESHAPE.
    fn check_shaped(&self, flight: &InFlight) -> Result<(), LinkError> {
        let ack = self.last_ack;
        let ok =
            ack.is_some_and(|a| a.state == HandState::Preshaped && Some(a.config) == self.shaped);
        if ok {
            return Ok(());
        }
        Err(LinkError::NotShaped {
            command: flight.command.name(),
            seq: flight.seq,
            state: ack.map(|a| a.state),
            config: ack.map(|a| a.config),
            expected: self.shaped,
            transmissions: flight.transmissions(self),
            device: self.device(),
        })
    }

    /// A delivery, if the ACK says OK.
    pub(super) fn accept(
        &mut self,
        command: Command,
        ack: Ack,
        attempts: u32,
        started: Instant,
    ) -> Result<Delivery, LinkError> {
        self.last_ack = Some(ack);
        match command {
            Command::Preshape(c) if ack.status == Status::Ok => self.shaped = Some(c),
            Command::Open if ack.status == Status::Ok => self.shaped = None,
            _ => {}
        }
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
}
