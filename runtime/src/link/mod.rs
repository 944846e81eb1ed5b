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
//!
//! [`HandLink`] is the link itself (`handlink.rs`): it connects
//! (`connect.rs`), delivers (`send.rs`) one exchange at a time
//! (`exchange.rs`), stamping the hand's clock ([`HandClock`], `clock.rs`);
//! [`Hand`] (`hand.rs`) shares it with the heartbeat thread.

mod clock;
mod config;
mod connect;
mod error;
mod exchange;
mod hand;
mod handlink;
mod send;

pub use clock::HandClock;
pub use config::LinkConfig;
pub use error::{LinkError, StartError};
pub use hand::Hand;
pub use handlink::HandLink;

use crate::protocol::Ack;
use serde::Serialize;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

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

fn is_set(flag: Option<&AtomicBool>) -> bool {
    flag.is_some_and(|f| f.load(Ordering::SeqCst))
}
