//! Streaming frame decoder. Bytes arrive in arbitrary chunks, possibly with
//! noise; the decoder resynchronises on the start byte: whenever a candidate
//! frame fails (LEN out of range, bad CRC) it drops only that start byte and
//! scans on, so a real frame hidden behind garbage is still found.

use crate::protocol::{Packet, CRC16, HEADER_LEN, MAX_PAYLOAD, OVERHEAD, START};

/// Counters of what the decoder had to throw away.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DecoderStats {
    pub frames: u64,
    /// Bytes skipped while looking for a start byte or after a bad candidate.
    pub discarded_bytes: u64,
    pub crc_errors: u64,
    pub length_errors: u64,
}

#[derive(Debug, Default)]
pub struct Decoder {
    buf: Vec<u8>,
    stats: DecoderStats,
}

impl Decoder {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Returns the next complete, CRC-valid frame, or `None` if more bytes
    /// are needed.
    pub fn next_packet(&mut self) -> Option<Packet> {
        loop {
            self.skip_to_start();
            if self.buf.len() < 2 {
                return None;
            }
            let len = self.buf[1] as usize;
            if len > MAX_PAYLOAD {
                self.stats.length_errors += 1;
                self.drop_front(1);
                continue;
            }
            let total = OVERHEAD + len;
            if self.buf.len() < total {
                // A noise start byte with a large LEN must not hold back a
                // complete valid frame that follows it.
                match self.later_valid_frame() {
                    Some(at) => {
                        self.stats.length_errors += 1;
                        self.drop_front(at);
                        continue;
                    }
                    None => return None,
                }
            }
            if !valid_at(&self.buf, 0) {
                self.stats.crc_errors += 1;
                self.drop_front(1);
                continue;
            }
            let packet = Packet {
                seq: self.buf[2],
                cmd: self.buf[3],
                payload: self.buf[HEADER_LEN..HEADER_LEN + len].to_vec(),
            };
            self.buf.drain(..total);
            self.stats.frames += 1;
            return Some(packet);
        }
    }

    /// Drops everything buffered (used after a reconnect).
    pub fn clear(&mut self) {
        self.buf.clear();
    }

    fn later_valid_frame(&self) -> Option<usize> {
        (1..self.buf.len()).find(|&i| self.buf[i] == START && valid_at(&self.buf, i))
    }

    fn skip_to_start(&mut self) {
        let n = self
            .buf
            .iter()
            .position(|&b| b == START)
            .unwrap_or(self.buf.len());
        self.drop_front(n);
    }

    fn drop_front(&mut self, n: usize) {
        self.stats.discarded_bytes += n as u64;
        self.buf.drain(..n);
    }
}

/// Whether a complete frame with a correct CRC starts at `buf[at]`.
fn valid_at(buf: &[u8], at: usize) -> bool {
    let b = &buf[at..];
    if b.len() < 2 || b[0] != START || b[1] as usize > MAX_PAYLOAD {
        return false;
    }
    let total = OVERHEAD + b[1] as usize;
    if b.len() < total {
        return false;
    }
    let got = u16::from_be_bytes([b[total - 2], b[total - 1]]);
    CRC16.checksum(&b[1..total - 2]) == got
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{preshape_command, Command, HandTime};
    use grasp_schema::taxonomy::Preshape;

    fn decode_all(bytes: &[u8], chunk: usize) -> (Vec<Packet>, DecoderStats) {
        let mut d = Decoder::new();
        let mut out = Vec::new();
        for c in bytes.chunks(chunk.max(1)) {
            d.push(c);
            while let Some(p) = d.next_packet() {
                out.push(p);
            }
        }
        (out, d.stats())
    }

    #[test]
    fn decodes_back_to_back_frames_in_any_chunking() {
        let a = preshape_command(Preshape::Lateral).packet(1, HandTime(7000));
        let b = Command::Close.packet(2, HandTime(7000));
        let mut bytes = a.encode();
        bytes.extend(b.encode());
        for chunk in [1, 2, 3, 7, 100] {
            let (got, stats) = decode_all(&bytes, chunk);
            assert_eq!(got, vec![a.clone(), b.clone()], "chunk {chunk}");
            assert_eq!(stats.discarded_bytes, 0);
        }
    }

    #[test]
    fn resynchronises_after_noise_and_corruption() {
        let good = preshape_command(Preshape::Pinch).packet(9, HandTime(7000));
        let mut corrupt = Command::Open.packet(8, HandTime(7000)).encode();
        corrupt[3] ^= 0x40; // flipped bit in CMD: CRC fails
        let mut bytes = vec![0x00, START, 0xFF, START, START];
        bytes.extend(corrupt);
        bytes.extend([START, 0x01]);
        bytes.extend(good.encode());
        let (got, stats) = decode_all(&bytes, 3);
        assert_eq!(got, vec![good]);
        assert!(stats.crc_errors >= 1);
        assert!(stats.length_errors >= 1);
        assert!(stats.discarded_bytes > 0);
    }

    #[test]
    fn a_start_byte_inside_a_payload_or_crc_is_harmless() {
        // seq = START and a CRC that may contain START: still one frame.
        for seq in 0..=255u8 {
            let p = Command::Hello {
                watchdog_ms: 0xA5A5,
            }
            .packet(seq, HandTime(7000));
            let (got, _) = decode_all(&p.encode(), 1);
            assert_eq!(got, vec![p]);
        }
    }

    #[test]
    fn a_noise_start_with_a_long_len_does_not_hold_back_a_frame() {
        let good = Command::Close.packet(5, HandTime(7000));
        let mut bytes = vec![START, MAX_PAYLOAD as u8];
        bytes.extend(good.encode());
        let (got, _) = decode_all(&bytes, 1);
        assert_eq!(got, vec![good]);
    }

    #[test]
    fn truncated_frame_waits_for_more_bytes() {
        let bytes = Command::Heartbeat.packet(4, HandTime(7000)).encode();
        let mut d = Decoder::new();
        d.push(&bytes[..bytes.len() - 1]);
        assert_eq!(d.next_packet(), None);
        d.push(&bytes[bytes.len() - 1..]);
        assert_eq!(
            d.next_packet(),
            Some(Command::Heartbeat.packet(4, HandTime(7000)))
        );
    }
}
