//! The link's timing settings (`[link]` in the config file).

use grasp_policy::setting::{ensure, InvalidSetting};
use serde::{Deserialize, Serialize};
use std::time::Duration;

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
    pub(super) fn ack_timeout(&self) -> Duration {
        Duration::from_millis(self.ack_timeout_ms)
    }

    /// Rejects settings under which the hand would open itself between two
    /// heartbeats.
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        ensure(self.ack_timeout_ms > 0, "link.ack_timeout_ms", || {
            "must be > 0".into()
        })?;
        ensure(
            self.heartbeat_interval_ms > 0
                && self.heartbeat_interval_ms * 2 <= u64::from(self.watchdog_ms),
            "link.heartbeat_interval_ms",
            || {
                format!(
                    "({}) must be > 0 and at most half of link.watchdog_ms ({})",
                    self.heartbeat_interval_ms, self.watchdog_ms
                )
            },
        )
    }
}
