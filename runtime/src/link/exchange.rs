//! One transmission and the wait for its ACK: the bytes on the wire,
//! decoded back into packets.

use super::HandLink;
use crate::protocol::Ack;
use crate::transport::is_timeout;
use std::io;
use std::time::{Duration, Instant};

pub(super) enum Wait {
    Acked(Ack),
    TimedOut,
}

impl HandLink {
    /// One transmission and the wait for its ACK.
    pub(super) fn exchange(&mut self, packet: &[u8], seq: u8, code: u8) -> io::Result<Wait> {
        self.transmit(packet)?;
        let deadline = self.last_tx + self.cfg.ack_timeout();
        let mut buf = [0u8; 256];
        loop {
            if let Some(ack) = self.matching_ack(seq, code) {
                return Ok(Wait::Acked(ack));
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(Wait::TimedOut);
            }
            self.receive(&mut buf, deadline - now)?;
        }
    }

    fn transmit(&mut self, packet: &[u8]) -> io::Result<()> {
        let conn = self.conn.as_mut().expect("exchange needs a connection");
        conn.write_all(packet)?;
        conn.flush()?;
        self.stats.transmissions += 1;
        self.last_tx = Instant::now();
        Ok(())
    }

    /// The ACK of (`seq`, `code`) among the packets decoded so far; any
    /// other packet is counted stale and dropped.
    fn matching_ack(&mut self, seq: u8, code: u8) -> Option<Ack> {
        while let Some(p) = self.decoder.next_packet() {
            let ack = Ack::parse(&p);
            if let Some(a) = &ack {
                // Any ACK of this session stamps the hand's clock.
                self.clock.observe(a.hand_time, Instant::now());
            }
            match ack {
                Some(ack) if ack.seq == seq && ack.cmd == code => return Some(ack),
                _ => self.stats.stale_acks += 1,
            }
        }
        None
    }

    /// Feeds the decoder what arrives within `timeout` (nothing is fine).
    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<()> {
        let conn = self.conn.as_mut().expect("connection checked above");
        conn.set_read_timeout(timeout)?;
        match conn.read(buf) {
            Ok(0) => Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "device closed",
            )),
            Ok(n) => {
                self.decoder.push(&buf[..n]);
                Ok(())
            }
            Err(e) if is_timeout(&e) => Ok(()),
            Err(e) => Err(e),
        }
    }
}
