//! The Hannes link's wire format (docs/hannes-protocol.md is the reference):
//!
//! ```text
//! START(0xA5) LEN SEQ CMD PAYLOAD[LEN] CRC_HI CRC_LO
//! ```
//!
//! The CRC is CRC-16/CCITT-FALSE over `LEN SEQ CMD PAYLOAD`, sent big-endian.
//!
//! Version 2 stamps every ACK with the hand's clock and gives PRESHAPE and
//! CLOSE a deadline on that clock, so a command delayed on the way (a
//! Bluetooth link buffering for seconds) is refused instead of executed late.

use grasp_schema::taxonomy::{HandConfiguration, Preshape, Thumb};

/// First byte of every frame.
pub const START: u8 = 0xA5;
/// Protocol version carried by `HELLO`.
pub const VERSION: u8 = 2;
/// Largest payload a receiver accepts; a longer LEN means "not a frame".
pub const MAX_PAYLOAD: usize = 32;
/// START + LEN + SEQ + CMD.
pub const HEADER_LEN: usize = 4;
/// Bytes of a frame besides its payload.
pub const OVERHEAD: usize = HEADER_LEN + 2;

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, xorout 0),
/// catalogued by `crc` as CRC-16/IBM-3740. Check value: "123456789" -> 0x29B1.
pub const CRC16: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// Command codes.
pub mod cmd {
    pub const HELLO: u8 = 0x01;
    pub const HEARTBEAT: u8 = 0x02;
    pub const PRESHAPE: u8 = 0x10;
    pub const CLOSE: u8 = 0x11;
    pub const OPEN: u8 = 0x12;
    pub const ACK: u8 = 0x80;
}

/// One decoded frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    pub seq: u8,
    pub cmd: u8,
    pub payload: Vec<u8>,
}

impl Packet {
    /// Serialises the frame. Panics only on a programming error (payload
    /// longer than [`MAX_PAYLOAD`]), never on received data.
    pub fn encode(&self) -> Vec<u8> {
        assert!(self.payload.len() <= MAX_PAYLOAD, "payload too long");
        let mut out = Vec::with_capacity(OVERHEAD + self.payload.len());
        out.push(START);
        out.push(self.payload.len() as u8);
        out.push(self.seq);
        out.push(self.cmd);
        out.extend_from_slice(&self.payload);
        let crc = CRC16.checksum(&out[1..]);
        out.extend_from_slice(&crc.to_be_bytes());
        out
    }
}

/// A time on the hand's clock in milliseconds, wrapping at 2^32 (49.7
/// days). Times are compared within half that range.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub struct HandTime(pub u32);

impl HandTime {
    /// Whether `self` comes strictly before `other` on the wrapping clock.
    pub fn is_before(self, other: HandTime) -> bool {
        (other.0.wrapping_sub(self.0) as i32) > 0
    }

    /// `self` plus `ms` milliseconds (wrapping).
    pub fn plus_ms(self, ms: u32) -> HandTime {
        HandTime(self.0.wrapping_add(ms))
    }

    /// Milliseconds from `earlier` to `self` (negative if `self` is
    /// earlier).
    pub fn since(self, earlier: HandTime) -> i64 {
        i64::from(self.0.wrapping_sub(earlier.0) as i32)
    }
}

/// A command the host sends to the hand.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// Starts a session: resets the hand's duplicate filter and sets its
    /// watchdog (the longest silence before it opens the hand).
    Hello {
        watchdog_ms: u16,
    },
    Heartbeat,
    Preshape(HandConfiguration),
    Close,
    Open,
}

impl Command {
    /// Whether the command's frame carries a deadline (PRESHAPE, CLOSE):
    /// the commands that must never be executed late.
    pub fn has_deadline(&self) -> bool {
        matches!(self, Command::Preshape(_) | Command::Close)
    }

    pub fn code(&self) -> u8 {
        match self {
            Command::Hello { .. } => cmd::HELLO,
            Command::Heartbeat => cmd::HEARTBEAT,
            Command::Preshape(_) => cmd::PRESHAPE,
            Command::Close => cmd::CLOSE,
            Command::Open => cmd::OPEN,
        }
    }

    /// The payload; `deadline` is carried by PRESHAPE and CLOSE only (see
    /// [`Command::has_deadline`]) and ignored by the other commands.
    pub fn payload(&self, deadline: HandTime) -> Vec<u8> {
        let deadline = deadline.0.to_be_bytes();
        match *self {
            Command::Hello { watchdog_ms } => {
                let [hi, lo] = watchdog_ms.to_be_bytes();
                vec![VERSION, hi, lo]
            }
            Command::Preshape(c) => {
                let mut p = vec![thumb_code(c.thumb), u8::from(c.three_digit)];
                p.extend_from_slice(&deadline);
                p
            }
            Command::Close => deadline.to_vec(),
            Command::Heartbeat | Command::Open => Vec::new(),
        }
    }

    /// The frame with sequence number `seq`; `deadline` as in
    /// [`Command::payload`].
    pub fn packet(&self, seq: u8, deadline: HandTime) -> Packet {
        Packet {
            seq,
            cmd: self.code(),
            payload: self.payload(deadline),
        }
    }

    /// Parses a received command frame; returns the command and, for
    /// PRESHAPE and CLOSE, its deadline.
    pub fn parse(p: &Packet) -> Result<(Command, Option<HandTime>), Status> {
        let exact = |n: usize| {
            if p.payload.len() == n {
                Ok(())
            } else {
                Err(Status::BadPayload)
            }
        };
        let deadline_at = |at: usize| {
            let b = &p.payload[at..at + 4];
            HandTime(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
        };
        match p.cmd {
            cmd::HELLO => {
                // The version first: a newer or older host learns why.
                if p.payload.first().is_some_and(|v| *v != VERSION) {
                    return Err(Status::BadVersion);
                }
                exact(3)?;
                let watchdog_ms = u16::from_be_bytes([p.payload[1], p.payload[2]]);
                Ok((Command::Hello { watchdog_ms }, None))
            }
            cmd::HEARTBEAT => exact(0).map(|_| (Command::Heartbeat, None)),
            cmd::PRESHAPE => {
                exact(6)?;
                let thumb = thumb_from_code(p.payload[0]).ok_or(Status::BadPayload)?;
                let three_digit = match p.payload[1] {
                    0 => false,
                    1 => true,
                    _ => return Err(Status::BadPayload),
                };
                let config = HandConfiguration { thumb, three_digit };
                Ok((Command::Preshape(config), Some(deadline_at(2))))
            }
            cmd::CLOSE => exact(4).map(|_| (Command::Close, Some(deadline_at(0)))),
            cmd::OPEN => exact(0).map(|_| (Command::Open, None)),
            _ => Err(Status::UnknownCommand),
        }
    }

    /// Short name for logs.
    pub fn name(&self) -> &'static str {
        match self {
            Command::Hello { .. } => "HELLO",
            Command::Heartbeat => "HEARTBEAT",
            Command::Preshape(_) => "PRESHAPE",
            Command::Close => "CLOSE",
            Command::Open => "OPEN",
        }
    }
}

/// The name of the command with code `code` ("0x42" if none has it).
pub fn command_name(code: u8) -> String {
    match code {
        cmd::HELLO => "HELLO".into(),
        cmd::HEARTBEAT => "HEARTBEAT".into(),
        cmd::PRESHAPE => "PRESHAPE".into(),
        cmd::CLOSE => "CLOSE".into(),
        cmd::OPEN => "OPEN".into(),
        c => format!("0x{c:02X}"),
    }
}

/// The pre-shape -> hand configuration table sent on the wire (Table 1).
pub fn preshape_command(p: Preshape) -> Command {
    Command::Preshape(p.hand_configuration())
}

pub fn thumb_code(t: Thumb) -> u8 {
    match t {
        Thumb::Adducted => 0,
        Thumb::Central => 1,
        Thumb::Abducted => 2,
    }
}

pub fn thumb_from_code(c: u8) -> Option<Thumb> {
    match c {
        0 => Some(Thumb::Adducted),
        1 => Some(Thumb::Central),
        2 => Some(Thumb::Abducted),
        _ => None,
    }
}

/// Result code carried by an ACK.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    Ok = 0,
    BadPayload = 1,
    UnknownCommand = 2,
    BadVersion = 3,
    /// The command's deadline had passed when it arrived: not executed.
    Expired = 4,
}

impl Status {
    pub fn from_code(c: u8) -> Option<Status> {
        match c {
            0 => Some(Status::Ok),
            1 => Some(Status::BadPayload),
            2 => Some(Status::UnknownCommand),
            3 => Some(Status::BadVersion),
            4 => Some(Status::Expired),
            _ => None,
        }
    }
}

/// What the fingers are doing, as reported in every ACK.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HandState {
    Open = 0,
    Preshaped = 1,
    Closed = 2,
}

impl HandState {
    pub fn from_code(c: u8) -> Option<HandState> {
        match c {
            0 => Some(HandState::Open),
            1 => Some(HandState::Preshaped),
            2 => Some(HandState::Closed),
            _ => None,
        }
    }
}

/// The hand's acknowledgement of the frame with sequence number `seq`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ack {
    pub seq: u8,
    pub cmd: u8,
    pub status: Status,
    pub state: HandState,
    pub config: HandConfiguration,
    /// The hand's clock when it sent the ACK.
    pub hand_time: HandTime,
}

impl Ack {
    pub fn packet(&self) -> Packet {
        let mut payload = vec![
            self.cmd,
            self.status as u8,
            self.state as u8,
            thumb_code(self.config.thumb),
            u8::from(self.config.three_digit),
        ];
        payload.extend_from_slice(&self.hand_time.0.to_be_bytes());
        Packet {
            seq: self.seq,
            cmd: cmd::ACK,
            payload,
        }
    }

    /// Parses an ACK frame; `None` if the frame is not a well-formed ACK.
    pub fn parse(p: &Packet) -> Option<Ack> {
        if p.cmd != cmd::ACK || p.payload.len() != 9 {
            return None;
        }
        let b = &p.payload;
        Some(Ack {
            seq: p.seq,
            cmd: b[0],
            status: Status::from_code(b[1])?,
            state: HandState::from_code(b[2])?,
            config: HandConfiguration {
                thumb: thumb_from_code(b[3])?,
                three_digit: match b[4] {
                    0 => false,
                    1 => true,
                    _ => return None,
                },
            },
            hand_time: HandTime(u32::from_be_bytes([b[5], b[6], b[7], b[8]])),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_is_ccitt_false() {
        assert_eq!(CRC16.checksum(b"123456789"), 0x29B1);
        assert_eq!(CRC16.checksum(b""), 0xFFFF);
    }

    /// The worked example's deadline: 7,520 ms on the hand's clock.
    const DOC_DEADLINE: HandTime = HandTime(0x0000_1D60);

    #[test]
    fn preshape_frame_matches_the_documented_bytes() {
        // The worked example of docs/hannes-protocol.md: PRESHAPE pinch3
        // (thumb abducted, three-digit on) with sequence number 7 and a
        // deadline of 7520 ms (0x00001D60) on the hand's clock.
        let bytes = preshape_command(Preshape::Pinch3)
            .packet(7, DOC_DEADLINE)
            .encode();
        let crc = CRC16.checksum(&[0x06, 0x07, 0x10, 0x02, 0x01, 0x00, 0x00, 0x1D, 0x60]);
        let [hi, lo] = crc.to_be_bytes();
        assert_eq!(
            bytes,
            vec![0xA5, 0x06, 0x07, 0x10, 0x02, 0x01, 0x00, 0x00, 0x1D, 0x60, hi, lo]
        );
        assert_eq!(crc, DOC_EXAMPLE_CRC);
    }

    /// Written into the protocol document; the test keeps them in sync.
    const DOC_EXAMPLE_CRC: u16 = 0x8A01;

    fn hex(p: Packet) -> String {
        p.encode()
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    #[test]
    fn documented_example_frames_are_byte_exact() {
        let none = HandTime(0);
        let hello = Command::Hello { watchdog_ms: 1000 }.packet(0, none);
        assert_eq!(hex(hello), "A5 03 00 01 02 03 E8 F1 51");
        assert_eq!(hex(Command::Heartbeat.packet(1, none)), "A5 00 01 02 DF EF");
        assert_eq!(
            hex(Command::Close.packet(8, HandTime(0x0000_1F40))),
            "A5 04 08 11 00 00 1F 40 C8 C8"
        );
        let ack = Ack {
            seq: 7,
            cmd: cmd::PRESHAPE,
            status: Status::Ok,
            state: HandState::Preshaped,
            config: Preshape::Pinch3.hand_configuration(),
            hand_time: HandTime(0x0000_1D4E),
        };
        assert_eq!(
            hex(ack.packet()),
            "A5 09 07 80 10 00 01 02 01 00 00 1D 4E 47 06"
        );
        let hello_ack = Ack {
            seq: 0,
            cmd: cmd::HELLO,
            status: Status::Ok,
            state: HandState::Open,
            config: Preshape::Power.hand_configuration(),
            hand_time: HandTime(0x0000_0FA0),
        };
        assert_eq!(
            hex(hello_ack.packet()),
            "A5 09 00 80 01 00 00 01 00 00 00 0F A0 73 47"
        );
        let expired = Ack {
            seq: 7,
            cmd: cmd::PRESHAPE,
            status: Status::Expired,
            state: HandState::Open,
            config: Preshape::Power.hand_configuration(),
            hand_time: HandTime(0x0000_1D61),
        };
        assert_eq!(
            hex(expired.packet()),
            "A5 09 07 80 10 04 00 01 00 00 00 1D 61 41 36"
        );
    }

    #[test]
    fn every_preshape_follows_table1() {
        let cfg = |p| match Command::parse(&preshape_command(p).packet(0, HandTime(9))) {
            Ok((Command::Preshape(c), Some(HandTime(9)))) => (c.thumb, c.three_digit),
            other => panic!("{other:?}"),
        };
        assert_eq!(cfg(Preshape::Power), (Thumb::Central, false));
        assert_eq!(cfg(Preshape::Lateral), (Thumb::Adducted, false));
        assert_eq!(cfg(Preshape::Pinch), (Thumb::Abducted, false));
        assert_eq!(cfg(Preshape::Pinch3), (Thumb::Abducted, true));
    }

    #[test]
    fn commands_round_trip_and_bad_payloads_are_rejected() {
        let deadline = HandTime(0xFFFF_FFF0);
        let all = [
            (Command::Hello { watchdog_ms: 750 }, None),
            (Command::Heartbeat, None),
            (preshape_command(Preshape::Lateral), Some(deadline)),
            (Command::Close, Some(deadline)),
            (Command::Open, None),
        ];
        for (c, d) in all {
            assert_eq!(Command::parse(&c.packet(3, deadline)), Ok((c, d)));
            assert_eq!(c.has_deadline(), d.is_some());
        }
        let bad = |cmd, payload: &[u8]| {
            Command::parse(&Packet {
                seq: 0,
                cmd,
                payload: payload.to_vec(),
            })
        };
        assert_eq!(
            bad(cmd::PRESHAPE, &[3, 0, 0, 0, 0, 1]),
            Err(Status::BadPayload)
        );
        assert_eq!(
            bad(cmd::PRESHAPE, &[1, 2, 0, 0, 0, 1]),
            Err(Status::BadPayload)
        );
        // A version-1 PRESHAPE (no deadline) is not executed.
        assert_eq!(bad(cmd::PRESHAPE, &[1, 0]), Err(Status::BadPayload));
        assert_eq!(bad(cmd::CLOSE, &[]), Err(Status::BadPayload));
        assert_eq!(bad(cmd::HELLO, &[9, 0, 1]), Err(Status::BadVersion));
        assert_eq!(bad(cmd::HELLO, &[1, 0, 1]), Err(Status::BadVersion));
        assert_eq!(bad(0x42, &[]), Err(Status::UnknownCommand));
    }

    #[test]
    fn ack_round_trips() {
        let ack = Ack {
            seq: 255,
            cmd: cmd::PRESHAPE,
            status: Status::Expired,
            state: HandState::Preshaped,
            config: Preshape::Pinch.hand_configuration(),
            hand_time: HandTime(0xDEAD_BEEF),
        };
        assert_eq!(Ack::parse(&ack.packet()), Some(ack));
        let mut p = ack.packet();
        p.payload[2] = 9;
        assert_eq!(Ack::parse(&p), None);
    }

    #[test]
    fn hand_time_compares_across_the_wrap() {
        let late = HandTime(u32::MAX - 5);
        let wrapped = late.plus_ms(10);
        assert_eq!(wrapped, HandTime(4));
        assert!(late.is_before(wrapped));
        assert!(!wrapped.is_before(late));
        assert!(!wrapped.is_before(wrapped));
        assert_eq!(wrapped.since(late), 10);
        assert_eq!(late.since(wrapped), -10);
    }
}
