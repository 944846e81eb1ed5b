//! Why a command was not delivered, or the link not started.

use crate::protocol::{HandState, Status};
use grasp_policy::setting::InvalidSetting;
use grasp_schema::taxonomy::{HandConfiguration, Preshape};

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
    /// A CLOSE not sent because the hand is not in the pre-shape it
    /// executed (a reconnect: its HELLO says it is open, closed or in
    /// another configuration, e.g. after its watchdog opened it, or it is
    /// another hand). `transmissions` > 0: an earlier copy may have
    /// reached it.
    #[error("{command} (seq {seq}) not sent to the hand on {device}: it reports {} in the {} configuration, not pre-shaped in the {} one it executed ({transmissions} transmissions)", state_name(state), describe(config), describe(expected))]
    NotShaped {
        command: &'static str,
        seq: u8,
        state: Option<HandState>,
        config: Option<HandConfiguration>,
        expected: Option<HandConfiguration>,
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

/// Which pre-shape a configuration is (Table 1), for messages.
fn describe(config: &Option<HandConfiguration>) -> String {
    match config {
        Some(c) => match Preshape::of_configuration(*c) {
            Some(p) => p.to_string(),
            None => format!("{c:?}"),
        },
        None => "none".into(),
    }
}

fn state_name(state: &Option<HandState>) -> String {
    match state {
        Some(s) => format!("{s:?}").to_lowercase(),
        None => "unknown".into(),
    }
}

/// Why [`super::Hand::start`] gave no hand.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// Timing under which the hand would open itself between heartbeats.
    #[error(transparent)]
    Config(#[from] InvalidSetting),
    /// The hand could not be reached, or did not acknowledge HELLO.
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error("cannot start the heartbeat thread")]
    Heartbeat(#[source] std::io::Error),
}
