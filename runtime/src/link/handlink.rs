//! [`HandLink`]: the single-threaded host side of one device, its state
//! and counters. Connecting is in `connect.rs`, delivery in `send.rs`, one
//! transmission and its ACK in `exchange.rs`.

use super::{HandClock, LinkConfig, LinkStats};
use crate::decoder::{Decoder, DecoderStats};
use crate::protocol::Ack;
use crate::transport::{Connector, Duplex};
use grasp_schema::taxonomy::HandConfiguration;
use std::time::{Duration, Instant};

/// Single-threaded link. Wrap it in [`super::Hand`] for the heartbeat.
pub struct HandLink {
    pub(super) connector: Box<dyn Connector>,
    pub(super) conn: Option<Box<dyn Duplex>>,
    pub(super) decoder: Decoder,
    pub(super) cfg: LinkConfig,
    next_seq: u8,
    pub(super) last_tx: Instant,
    pub(super) stats: LinkStats,
    decoder_base: DecoderStats,
    pub(super) clock: HandClock,
    /// Counts sessions (HELLOs acknowledged): frames are re-encoded for a
    /// new one, whose hand clock may differ.
    pub(super) session: u64,
    /// The loss of the device was logged (once per outage).
    pub(super) down_reported: bool,
    /// The last ACK of a command the hand answered (its state and
    /// configuration then); a new connection starts with its HELLO's.
    pub(super) last_ack: Option<Ack>,
    /// The configuration of the last PRESHAPE the hand executed (status
    /// OK); a CLOSE is sent only while the hand says it is in it.
    pub(super) shaped: Option<HandConfiguration>,
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
            last_ack: None,
            shaped: None,
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

    /// What the hand last acknowledged (HELLO included): its state and
    /// configuration as of that ACK. After a reconnect, the new session's
    /// HELLO, read before any further command.
    pub fn last_ack(&self) -> Option<Ack> {
        self.last_ack
    }

    /// Sessions started (HELLOs acknowledged) since the link was made.
    pub fn session(&self) -> u64 {
        self.session
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

    pub(super) fn drop_connection(&mut self) {
        self.conn = None;
        self.reset_decoder();
    }

    /// A fresh decoder (a new connection starts mid-nothing); its counts
    /// carry over into [`HandLink::stats`].
    pub(super) fn reset_decoder(&mut self) {
        let d = self.decoder.stats();
        self.decoder_base.crc_errors += d.crc_errors;
        self.decoder_base.discarded_bytes += d.discarded_bytes;
        self.decoder = Decoder::new();
    }

    pub(super) fn alloc_seq(&mut self) -> u8 {
        let seq = self.next_seq;
        self.next_seq = self.next_seq.wrapping_add(1);
        seq
    }
}
