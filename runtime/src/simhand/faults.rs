//! Seeded link faults for the simulated hand: frames from the host lost,
//! corrupted, held back or duplicated on their way to the hand, the hand's
//! ACKs likewise on their way back, and the hand's side of the link
//! unplugged for a while. The same seed and the same sequence of frames give
//! the same faults.
//!
//! A spec is `key=value` pairs separated by commas, e.g.
//! `drop=0.2,delay=0.1:400,on=preshape+close,seed=7`:
//!
//! | key | value | meaning |
//! |---|---|---|
//! | `drop` | P | a frame is lost (either direction) with probability P |
//! | `corrupt` | P | one bit of a frame is flipped with probability P |
//! | `duplicate` | P | a frame arrives twice with probability P |
//! | `delay` | P:MS | a frame, and the frames queued behind it, are held MS ms |
//! | `disconnect` | P:MS | on a frame from the host, unplug for MS ms |
//! | `outage` | AT:MS | unplug AT ms after the hand started, for MS ms |
//! | `after` | MS | probabilistic faults start AT ms after the hand started |
//! | `until` | MS | and end then |
//! | `on` | CMD+CMD | only frames of these commands (ACKs by the command they acknowledge): hello, heartbeat, preshape, close, open |
//! | `seed` | N | random stream (default 0) |
//!
//! Durations are milliseconds, optionally written `250ms` or `1.5s`.

use crate::protocol::{cmd, Packet};
use serde::Serialize;
use std::fmt;
use std::str::FromStr;
use std::time::{Duration, Instant};

/// Which way a frame travels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Toward {
    /// A command from the host.
    Hand,
    /// An ACK from the hand.
    Host,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    Drop,
    Corrupt,
    Delay,
    Duplicate,
    Disconnect,
}

/// Which faults to inject; the default injects none.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FaultSpec {
    pub seed: u64,
    pub drop: f64,
    pub corrupt: f64,
    pub duplicate: f64,
    /// Probability and hold time.
    pub delay: Option<(f64, Duration)>,
    /// Probability per frame from the host, and how long to stay unplugged.
    pub disconnect: Option<(f64, Duration)>,
    /// A scheduled outage: when (after the hand started), and how long.
    pub outage: Option<(Duration, Duration)>,
    /// Window of the probabilistic faults, from the hand's start.
    pub after: Duration,
    pub until: Option<Duration>,
    /// Command codes the faults apply to; `None`: every frame.
    pub on: Option<Vec<u8>>,
}

impl FaultSpec {
    /// Whether any fault is configured.
    pub fn is_active(&self) -> bool {
        self.drop > 0.0
            || self.corrupt > 0.0
            || self.duplicate > 0.0
            || self.delay.is_some_and(|(p, _)| p > 0.0)
            || self.disconnect.is_some_and(|(p, _)| p > 0.0)
            || self.outage.is_some()
    }

    fn applies_to(&self, p: &Packet) -> bool {
        let code = match p.cmd {
            cmd::ACK => p.payload.first().copied().unwrap_or(cmd::ACK),
            c => c,
        };
        self.on.as_ref().is_none_or(|codes| codes.contains(&code))
    }
}

const COMMANDS: [(&str, u8); 5] = [
    ("hello", cmd::HELLO),
    ("heartbeat", cmd::HEARTBEAT),
    ("preshape", cmd::PRESHAPE),
    ("close", cmd::CLOSE),
    ("open", cmd::OPEN),
];

impl FromStr for FaultSpec {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let mut spec = FaultSpec::default();
        for item in s.split(',').map(str::trim).filter(|i| !i.is_empty()) {
            let (key, value) = item
                .split_once('=')
                .ok_or_else(|| format!("fault '{item}': expected KEY=VALUE"))?;
            let bad = |why: String| format!("fault '{item}': {why}");
            match key {
                "seed" => spec.seed = value.parse().map_err(|e| bad(format!("{e}")))?,
                "drop" => spec.drop = probability(value).map_err(bad)?,
                "corrupt" => spec.corrupt = probability(value).map_err(bad)?,
                "duplicate" => spec.duplicate = probability(value).map_err(bad)?,
                "delay" => spec.delay = Some(chance_and_time(value).map_err(bad)?),
                "disconnect" => spec.disconnect = Some(chance_and_time(value).map_err(bad)?),
                "outage" => {
                    let (at, len) = value
                        .split_once(':')
                        .ok_or_else(|| bad("expected AT:MS".into()))?;
                    spec.outage = Some((duration(at).map_err(bad)?, duration(len).map_err(bad)?));
                }
                "after" => spec.after = duration(value).map_err(bad)?,
                "until" => spec.until = Some(duration(value).map_err(bad)?),
                "on" => {
                    let codes = value
                        .split('+')
                        .map(|name| {
                            COMMANDS
                                .iter()
                                .find(|(n, _)| *n == name)
                                .map(|(_, c)| *c)
                                .ok_or_else(|| bad(format!("unknown command '{name}'")))
                        })
                        .collect::<Result<Vec<u8>, String>>()?;
                    spec.on = Some(codes);
                }
                other => {
                    return Err(format!(
                        "unknown fault '{other}' (expected drop, corrupt, duplicate, delay, \
                         disconnect, outage, after, until, on or seed)"
                    ))
                }
            }
        }
        Ok(spec)
    }
}

impl fmt::Display for FaultSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ms = |d: Duration| d.as_millis();
        let mut parts = vec![format!("seed={}", self.seed)];
        for (name, p) in [
            ("drop", self.drop),
            ("corrupt", self.corrupt),
            ("duplicate", self.duplicate),
        ] {
            if p > 0.0 {
                parts.push(format!("{name}={p}"));
            }
        }
        if let Some((p, d)) = self.delay {
            parts.push(format!("delay={p}:{}", ms(d)));
        }
        if let Some((p, d)) = self.disconnect {
            parts.push(format!("disconnect={p}:{}", ms(d)));
        }
        if let Some((at, d)) = self.outage {
            parts.push(format!("outage={}:{}", ms(at), ms(d)));
        }
        if !self.after.is_zero() {
            parts.push(format!("after={}", ms(self.after)));
        }
        if let Some(u) = self.until {
            parts.push(format!("until={}", ms(u)));
        }
        if let Some(on) = &self.on {
            let names: Vec<&str> = on
                .iter()
                .filter_map(|c| COMMANDS.iter().find(|(_, k)| k == c).map(|(n, _)| *n))
                .collect();
            parts.push(format!("on={}", names.join("+")));
        }
        f.write_str(&parts.join(","))
    }
}

fn probability(s: &str) -> Result<f64, String> {
    let p: f64 = s
        .parse()
        .map_err(|_| format!("'{s}' is not a probability"))?;
    if (0.0..=1.0).contains(&p) {
        Ok(p)
    } else {
        Err(format!("probability {p} is not in [0, 1]"))
    }
}

fn chance_and_time(s: &str) -> Result<(f64, Duration), String> {
    let (p, d) = s
        .split_once(':')
        .ok_or_else(|| "expected PROBABILITY:MS".to_string())?;
    Ok((probability(p)?, duration(d)?))
}

/// `250`, `250ms` or `1.5s`.
fn duration(s: &str) -> Result<Duration, String> {
    let (number, scale) = if let Some(ms) = s.strip_suffix("ms") {
        (ms, 1e-3)
    } else if let Some(secs) = s.strip_suffix('s') {
        (secs, 1.0)
    } else {
        (s, 1e-3)
    };
    let v: f64 = number
        .parse()
        .map_err(|_| format!("'{s}' is not a duration (MS, MSms or Ss)"))?;
    let secs = v * scale;
    if secs.is_finite() && (0.0..=86_400.0).contains(&secs) {
        Ok(Duration::from_secs_f64(secs))
    } else {
        Err(format!("duration '{s}' is not in [0, 1 day]"))
    }
}

/// What happens to one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Fate {
    /// Unplug for this long (frames from the host only); the frame is lost.
    pub disconnect: Option<Duration>,
    pub drop: bool,
    /// Bit to flip, counted from the byte after START.
    pub corrupt_bit: Option<usize>,
    pub delay: Option<Duration>,
    pub duplicate: bool,
}

impl Fate {
    fn is_clean(&self) -> bool {
        *self == Fate::default()
    }

    /// The faults that hit, in the order they apply.
    pub fn kinds(&self) -> Vec<FaultKind> {
        let mut k = Vec::new();
        if self.disconnect.is_some() {
            k.push(FaultKind::Disconnect);
            return k;
        }
        if self.drop {
            k.push(FaultKind::Drop);
            return k;
        }
        if self.corrupt_bit.is_some() {
            k.push(FaultKind::Corrupt);
        }
        if self.delay.is_some() {
            k.push(FaultKind::Delay);
        }
        if self.duplicate {
            k.push(FaultKind::Duplicate);
        }
        k
    }

    /// Applies corruption to an encoded frame.
    pub fn corrupt(&self, frame: &mut [u8]) {
        if let (Some(bit), true) = (self.corrupt_bit, frame.len() > 1) {
            let bit = bit % ((frame.len() - 1) * 8);
            frame[1 + bit / 8] ^= 1 << (bit % 8);
        }
    }
}

/// Draws the fate of each frame from the spec and the seed.
#[derive(Debug)]
pub struct Injector {
    spec: FaultSpec,
    started: Instant,
    to_hand: SplitMix64,
    to_host: SplitMix64,
    outage_done: bool,
}

impl Injector {
    pub fn new(spec: FaultSpec, started: Instant) -> Self {
        Injector {
            to_hand: SplitMix64(spec.seed ^ 0x68616e64), // "hand"
            to_host: SplitMix64(spec.seed ^ 0x686f7374), // "host"
            spec,
            started,
            outage_done: false,
        }
    }

    pub fn is_active(&self) -> bool {
        self.spec.is_active()
    }

    fn in_window(&self, now: Instant) -> bool {
        let t = now.saturating_duration_since(self.started);
        t >= self.spec.after && self.spec.until.is_none_or(|u| t < u)
    }

    /// The fate of frame `p`; `None` when no fault hits it. `enabled` is the
    /// run-time switch ([`super::RunningHand::set_faults`]).
    pub fn fate(
        &mut self,
        toward: Toward,
        p: &Packet,
        now: Instant,
        enabled: bool,
    ) -> Option<Fate> {
        if !enabled || !self.in_window(now) || !self.spec.applies_to(p) {
            return None;
        }
        let rng = match toward {
            Toward::Hand => &mut self.to_hand,
            Toward::Host => &mut self.to_host,
        };
        // Always the same number of draws, so one frame's fate does not
        // shift the stream for the next.
        let u: [f64; 5] = std::array::from_fn(|_| rng.unit());
        let bit = rng.next_u64() as usize;
        let s = &self.spec;
        let fate = Fate {
            disconnect: match (toward, s.disconnect) {
                (Toward::Hand, Some((p, d))) if u[0] < p => Some(d),
                _ => None,
            },
            drop: u[1] < s.drop,
            corrupt_bit: (u[2] < s.corrupt).then_some(bit),
            delay: s.delay.and_then(|(p, d)| (u[3] < p).then_some(d)),
            duplicate: u[4] < s.duplicate,
        };
        (!fate.is_clean()).then_some(fate)
    }

    /// The scheduled outage's length, once, when it is due.
    pub fn outage_due(&mut self, now: Instant) -> Option<Duration> {
        let (at, len) = self.spec.outage?;
        if self.outage_done || now < self.started + at {
            return None;
        }
        self.outage_done = true;
        Some(len)
    }
}

/// A small, well-mixed generator (Steele, Lea and Flood's SplitMix64):
/// reproducible everywhere, no dependency.
#[derive(Debug, Clone)]
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{preshape_command, Command, HandTime};
    use grasp_schema::taxonomy::Preshape;

    #[test]
    fn specs_parse_print_and_explain_mistakes() {
        let s: FaultSpec = "drop=0.2, delay=0.1:400ms,outage=1.5s:7500,on=preshape+close,seed=7"
            .parse()
            .unwrap();
        assert_eq!(s.drop, 0.2);
        assert_eq!(s.delay, Some((0.1, Duration::from_millis(400))));
        assert_eq!(
            s.outage,
            Some((Duration::from_millis(1500), Duration::from_millis(7500)))
        );
        assert_eq!(s.on, Some(vec![cmd::PRESHAPE, cmd::CLOSE]));
        assert_eq!(s.seed, 7);
        assert!(s.is_active());
        let again: FaultSpec = s.to_string().parse().unwrap();
        assert_eq!(again, s);
        assert!(!FaultSpec::default().is_active());
        for (bad, says) in [
            ("drop=2", "not in [0, 1]"),
            ("drop", "KEY=VALUE"),
            ("delay=0.5", "PROBABILITY:MS"),
            ("jam=1", "unknown fault 'jam'"),
            ("on=preshape+wave", "unknown command 'wave'"),
            ("until=-3", "not in [0, 1 day]"),
        ] {
            let e = bad.parse::<FaultSpec>().unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    fn fates(spec: &FaultSpec, n: usize) -> Vec<Option<Fate>> {
        let t = Instant::now();
        let mut inj = Injector::new(spec.clone(), t);
        let p = preshape_command(Preshape::Power).packet(1, HandTime(9));
        (0..n)
            .map(|_| inj.fate(Toward::Hand, &p, t, true))
            .collect()
    }

    #[test]
    fn the_seed_fixes_the_faults_and_the_rates_hold() {
        let spec: FaultSpec = "drop=0.25,duplicate=0.5,seed=3".parse().unwrap();
        let a = fates(&spec, 4000);
        assert_eq!(a, fates(&spec, 4000), "same seed, same faults");
        let other = FaultSpec { seed: 4, ..spec };
        assert_ne!(a, fates(&other, 4000), "another seed, other faults");
        let dropped = a.iter().flatten().filter(|f| f.drop).count() as f64 / 4000.0;
        // Binomial(4000, 0.25): std 0.007; 0.05 is 7 standard deviations.
        assert!((dropped - 0.25).abs() < 0.05, "{dropped}");
    }

    #[test]
    fn the_command_filter_and_the_window_limit_the_faults() {
        let spec: FaultSpec = "drop=1,on=preshape,after=100,until=200".parse().unwrap();
        let t = Instant::now();
        let mut inj = Injector::new(spec, t);
        let preshape = preshape_command(Preshape::Power).packet(1, HandTime(9));
        let heartbeat = Command::Heartbeat.packet(2, HandTime(0));
        let ack_of_preshape = Packet {
            seq: 1,
            cmd: cmd::ACK,
            payload: vec![cmd::PRESHAPE, 0, 1, 1, 0, 0, 0, 0, 0],
        };
        let at = |ms| t + Duration::from_millis(ms);
        assert_eq!(inj.fate(Toward::Hand, &preshape, at(50), true), None);
        assert!(
            inj.fate(Toward::Hand, &preshape, at(150), true)
                .unwrap()
                .drop
        );
        assert!(
            inj.fate(Toward::Host, &ack_of_preshape, at(150), true)
                .unwrap()
                .drop
        );
        assert_eq!(inj.fate(Toward::Hand, &heartbeat, at(150), true), None);
        assert_eq!(inj.fate(Toward::Hand, &preshape, at(150), false), None);
        assert_eq!(inj.fate(Toward::Hand, &preshape, at(200), true), None);
    }

    #[test]
    fn corruption_flips_one_bit_after_the_start_byte() {
        let frame = preshape_command(Preshape::Pinch)
            .packet(3, HandTime(9))
            .encode();
        for bit in 0..200 {
            let mut bad = frame.clone();
            let fate = Fate {
                corrupt_bit: Some(bit),
                ..Fate::default()
            };
            fate.corrupt(&mut bad);
            assert_eq!(bad[0], frame[0]);
            let flipped: u32 = bad
                .iter()
                .zip(&frame)
                .map(|(a, b)| (a ^ b).count_ones())
                .sum();
            assert_eq!(flipped, 1);
        }
    }

    #[test]
    fn the_outage_comes_once() {
        let spec: FaultSpec = "outage=100:50".parse().unwrap();
        let t = Instant::now();
        let mut inj = Injector::new(spec, t);
        assert_eq!(inj.outage_due(t + Duration::from_millis(99)), None);
        assert_eq!(
            inj.outage_due(t + Duration::from_millis(100)),
            Some(Duration::from_millis(50))
        );
        assert_eq!(inj.outage_due(t + Duration::from_millis(300)), None);
    }
}
