//! The host link against the simulated hand over pseudo-terminal pairs:
//! whole approaches, corruption, missing ACKs, unplugging, NaN outputs,
//! the watchdog and stale-frame dropping.

use crate::common::{eventually, fast_link, frames_of, start_hand, FakeModel};
use grasp_schema::taxonomy::{Class, Preshape, Thumb};
use image::RgbImage;
use runtime::approach::{actuate, classify_window, ApproachReport};
use runtime::decoder::Decoder;
use runtime::feed::FeedMode;
use runtime::link::{Hand, HandLink, LinkConfig, LinkError};
use runtime::policy::{Outcome, PolicyConfig};
use runtime::protocol::{cmd, preshape_command, Ack, Command, HandState, HandTime, Packet, Status};
use runtime::simhand::{pty_pair, HandEvent, PtyHand};
use runtime::source::{MemorySource, Pacing};
use runtime::transport::{is_timeout, Connector, Duplex, SerialConnector};
use runtime::trigger::Timer;
use std::io::{self, Read, Write};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn approach(
    hand: &Hand,
    model: &mut FakeModel,
    frames: Vec<RgbImage>,
    pacing: Pacing,
    mode: FeedMode,
) -> ApproachReport {
    let source = MemorySource::new(frames, 30.0, pacing).unwrap();
    let t0 = Instant::now();
    let (_, window) = classify_window(
        Box::new(source),
        mode,
        model,
        &PolicyConfig::default(),
        t0,
        &mut |_| {},
    )
    .unwrap();
    let mut closure = Timer(Duration::from_millis(20));
    let stop = AtomicBool::new(false);
    // An age limit no loaded machine reaches: these tests are not about it
    // (tests/it/faults.rs is).
    let max_age = Duration::from_secs(30);
    actuate(hand, window, Some(&mut closure), &stop, t0, max_age).unwrap()
}

fn preshape_events(events: &[HandEvent]) -> Vec<Option<Preshape>> {
    events
        .iter()
        .filter_map(|e| match e {
            HandEvent::Preshape { preshape, .. } => Some(*preshape),
            _ => None,
        })
        .collect()
}

#[test]
fn a_replayed_approach_commands_the_voted_preshape_then_closes() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let hand = start_hand(pty.path(), fast_link());
    // Reach: no_grasp at the start, mostly pinch3, some confusion with
    // pinch, no_grasp at contact; 3 s at 30 fps, the window sees 2 s.
    let mut classes = vec![Class::NoGrasp; 10];
    classes.extend([Class::Pinch3, Class::Pinch3, Class::Pinch].repeat(15));
    classes.extend(vec![Class::NoGrasp; 35]);
    let report = approach(
        &hand,
        &mut FakeModel::new(),
        frames_of(&classes),
        Pacing::AsFastAsPossible,
        FeedMode::Lockstep,
    );
    let d = &report.window.decision;
    assert_eq!(
        d.outcome,
        Outcome::Majority {
            preshape: Preshape::Pinch3
        }
    );
    assert_eq!(d.frames, 60, "2 s window at 30 fps");
    assert_eq!(d.votes, [0, 0, 15, 30, 15]);
    let sent = report.preshape.expect("pre-shape acknowledged");
    assert_eq!(sent.preshape, Some(Preshape::Pinch3));
    assert_eq!(sent.hand_state, HandState::Preshaped);
    assert_eq!(
        report.closure.expect("closure acknowledged").hand_state,
        HandState::Closed
    );
    let (state, config) = pty.hand.state();
    assert_eq!(state, HandState::Closed);
    assert_eq!((config.thumb, config.three_digit), (Thumb::Abducted, true));
    assert_eq!(
        preshape_events(&pty.hand.events()),
        vec![Some(Preshape::Pinch3)]
    );
}

#[test]
fn nan_model_output_never_actuates() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let hand = start_hand(pty.path(), fast_link());
    let mut model = FakeModel::new();
    model.nan_at = Some(12);
    let report = approach(
        &hand,
        &mut model,
        frames_of(&[Class::Power; 60]),
        Pacing::AsFastAsPossible,
        FeedMode::Lockstep,
    );
    let d = &report.window.decision;
    assert!(matches!(&d.outcome, Outcome::Aborted { error } if error.contains("non-finite")));
    assert_eq!(d.invalid_frames, 1);
    assert!(report.preshape.is_none() && report.closure.is_none());
    // Give a stray command time to arrive before checking nothing came.
    std::thread::sleep(Duration::from_millis(100));
    let events = pty.hand.events();
    assert!(preshape_events(&events).is_empty(), "{events:?}");
    assert!(!events.iter().any(|e| matches!(e, HandEvent::Close { .. })));
    assert_eq!(pty.hand.state().0, HandState::Open);
}

#[test]
fn a_slow_classifier_drops_stale_frames_and_still_decides() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let hand = start_hand(pty.path(), fast_link());
    let mut model = FakeModel::new();
    model.delay = Duration::from_millis(80); // far slower than 30 fps
    let report = approach(
        &hand,
        &mut model,
        frames_of(&[Class::Lateral; 60]),
        Pacing::RealTime,
        FeedMode::Latest,
    );
    let feed = report.window.feed;
    assert!(feed.dropped > 0, "{feed:?}");
    assert!(feed.delivered < 60);
    assert_eq!(feed.delivered + feed.dropped, feed.captured);
    // Frames classified are fresh: indices strictly increase with gaps.
    let idx: Vec<u64> = report.window.predictions.iter().map(|p| p.index).collect();
    assert!(idx.windows(2).all(|w| w[1] > w[0]));
    assert!(idx.windows(2).any(|w| w[1] > w[0] + 1), "{idx:?}");
    let sent = report.preshape.expect("pre-shape acknowledged");
    assert_eq!(sent.preshape, Some(Preshape::Lateral));
}

/// A connector whose connection flips a bit in selected writes (by count).
struct Corrupting {
    inner: SerialConnector,
    corrupt_writes: Arc<Mutex<Vec<usize>>>,
    writes: Arc<Mutex<usize>>,
}

struct CorruptingPort {
    inner: Box<dyn Duplex>,
    corrupt_writes: Arc<Mutex<Vec<usize>>>,
    writes: Arc<Mutex<usize>>,
}

impl Read for CorruptingPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.inner.read(buf)
    }
}

impl Write for CorruptingPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = {
            let mut w = self.writes.lock().unwrap();
            *w += 1;
            *w
        };
        if self.corrupt_writes.lock().unwrap().contains(&n) {
            let mut bad = buf.to_vec();
            let last = bad.len() - 3;
            bad[last] ^= 0x10;
            // Noise before the frame too: the hand must resynchronise.
            self.inner.write_all(&[0x00, 0xA5, 0x20, 0xA5])?;
            self.inner.write_all(&bad)?;
            return Ok(buf.len());
        }
        self.inner.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl Duplex for CorruptingPort {
    fn set_read_timeout(&mut self, t: Duration) -> io::Result<()> {
        self.inner.set_read_timeout(t)
    }
}

impl Connector for Corrupting {
    fn open(&mut self) -> io::Result<Box<dyn Duplex>> {
        Ok(Box::new(CorruptingPort {
            inner: self.inner.open()?,
            corrupt_writes: self.corrupt_writes.clone(),
            writes: self.writes.clone(),
        }))
    }
    fn describe(&self) -> String {
        format!("corrupting {}", self.inner.describe())
    }
}

#[test]
fn corrupted_frames_are_dropped_by_crc_and_recovered_by_retransmission() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let corrupt = Arc::new(Mutex::new(Vec::new()));
    let writes = Arc::new(Mutex::new(0));
    let connector = Corrupting {
        inner: SerialConnector::new(pty.path(), 115_200),
        corrupt_writes: corrupt.clone(),
        writes: writes.clone(),
    };
    let cfg = LinkConfig {
        heartbeat_interval_ms: 500, // keep heartbeats out of the write count
        ..fast_link()
    };
    let mut link = HandLink::new(Box::new(connector), cfg);
    link.connect().unwrap();
    // Corrupt the next write: the first transmission of PRESHAPE.
    let next = *writes.lock().unwrap() + 1;
    corrupt.lock().unwrap().push(next);
    let d = link.send(preshape_command(Preshape::Pinch)).unwrap();
    assert_eq!(d.attempts, 2, "the corrupted copy got no ACK");
    assert_eq!(d.ack.config, Preshape::Pinch.hand_configuration());
    let events = pty.hand.events();
    assert_eq!(preshape_events(&events), vec![Some(Preshape::Pinch)]);
    assert!(!events
        .iter()
        .any(|e| matches!(e, HandEvent::Duplicate { .. })));
}

#[test]
fn hand_resynchronises_on_raw_noise_and_acks_duplicates_idempotently() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let mut port = runtime::transport::open_serial(pty.path(), 115_200, false).unwrap();
    // A deadline days ahead on the fresh hand's clock.
    let later = HandTime(1 << 30);
    let preshape = preshape_command(Preshape::Lateral)
        .packet(9, later)
        .encode();
    let mut bytes = vec![0xA5, 0xFF, 0x13, 0xA5, 0x02, 0x09]; // noise, a bogus start
    bytes.extend(&preshape[..5]); // a truncated copy...
    bytes.extend(&preshape); // ...then the real frame
    bytes.extend(&preshape); // and a retransmission
    bytes.extend(Command::Close.packet(10, later).encode());
    port.write_all(&bytes).unwrap();
    let acks = read_acks(&mut port, 3, Duration::from_secs(5));
    assert_eq!(
        acks.iter()
            .map(|a| (a.seq, a.cmd, a.status))
            .collect::<Vec<_>>(),
        vec![
            (9, cmd::PRESHAPE, Status::Ok),
            (9, cmd::PRESHAPE, Status::Ok),
            (10, cmd::CLOSE, Status::Ok)
        ]
    );
    assert_eq!(acks[0], acks[1], "a duplicate gets the same ACK");
    let events = pty.hand.events();
    assert_eq!(preshape_events(&events), vec![Some(Preshape::Lateral)]);
    assert!(events.contains(&HandEvent::Duplicate {
        seq: 9,
        cmd: cmd::PRESHAPE
    }));
    assert_eq!(pty.hand.state().0, HandState::Closed);
}

fn read_acks(port: &mut dyn Duplex, n: usize, limit: Duration) -> Vec<Ack> {
    let mut decoder = Decoder::new();
    let mut acks = Vec::new();
    let t = Instant::now();
    let mut buf = [0u8; 64];
    port.set_read_timeout(Duration::from_millis(10)).unwrap();
    while acks.len() < n && t.elapsed() < limit {
        match port.read(&mut buf) {
            Ok(k) => decoder.push(&buf[..k]),
            Err(e) if is_timeout(&e) => {}
            Err(e) => panic!("{e}"),
        }
        while let Some(p) = decoder.next_packet() {
            acks.extend(Ack::parse(&p));
        }
    }
    acks
}

/// A hand that acknowledges HELLO and HEARTBEAT but never PRESHAPE, and
/// counts what it received.
fn mute_for_preshape(mut port: serialport::TTYPort, received: Arc<Mutex<Vec<Packet>>>) {
    let mut decoder = Decoder::new();
    let mut buf = [0u8; 64];
    let _ = port.set_read_timeout(Duration::from_millis(10));
    loop {
        match port.read(&mut buf) {
            Ok(k) => decoder.push(&buf[..k]),
            Err(e) if is_timeout(&e) => {}
            Err(_) => return,
        }
        while let Some(p) = decoder.next_packet() {
            received.lock().unwrap().push(p.clone());
            if p.cmd == cmd::PRESHAPE {
                continue;
            }
            let ack = Ack {
                seq: p.seq,
                cmd: p.cmd,
                status: Status::Ok,
                state: HandState::Open,
                config: Preshape::Power.hand_configuration(),
                hand_time: HandTime(0),
            };
            if port.write_all(&ack.packet().encode()).is_err() {
                return;
            }
        }
    }
}

#[test]
fn a_missing_ack_is_retried_then_reported_as_not_executed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hand");
    let (master, slave) = pty_pair(&path).unwrap();
    let received = Arc::new(Mutex::new(Vec::new()));
    let r = received.clone();
    std::thread::spawn(move || mute_for_preshape(master, r));
    let cfg = LinkConfig {
        heartbeat_interval_ms: 1000, // no heartbeat in between
        ..fast_link()
    };
    let mut link = HandLink::new(Box::new(SerialConnector::new(&path, 115_200)), cfg.clone());
    link.connect().unwrap();
    let err = link.send(preshape_command(Preshape::Power)).unwrap_err();
    match &err {
        LinkError::NoAck {
            command, attempts, ..
        } => {
            assert_eq!(*command, "PRESHAPE");
            assert_eq!(*attempts, 1 + cfg.retries);
        }
        other => panic!("{other}"),
    }
    assert!(err.to_string().contains("not acknowledged"));
    let preshapes: Vec<Packet> = received
        .lock()
        .unwrap()
        .iter()
        .filter(|p| p.cmd == cmd::PRESHAPE)
        .cloned()
        .collect();
    assert_eq!(preshapes.len() as u32, 1 + cfg.retries);
    assert!(
        preshapes.windows(2).all(|w| w[0] == w[1]),
        "same SEQ, same bytes"
    );
    assert_eq!(link.stats().retransmissions, u64::from(cfg.retries));
    drop(slave);
}

#[test]
fn an_unplugged_hand_is_reconnected_and_the_command_still_lands() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hand");
    let first = PtyHand::plug(&path, |_| {}).unwrap();
    let hand = start_hand(&path, fast_link());
    hand.send(preshape_command(Preshape::Power)).unwrap();
    drop(first); // unplugged: the host's pty hangs up
    let replug = {
        let path = path.clone();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(150));
            PtyHand::plug(&path, |_| {}).unwrap()
        })
    };
    // Sent while the device is gone: it must wait for the new device.
    let d = hand
        .send(preshape_command(Preshape::Lateral))
        .expect("delivered after the reconnect");
    assert_eq!(d.ack.config, Preshape::Lateral.hand_configuration());
    let second = replug.join().unwrap();
    assert!(hand.stats().reconnects >= 1);
    let events = second.hand.events();
    assert!(
        matches!(events.first(), Some(HandEvent::Hello { .. })),
        "{events:?}"
    );
    assert_eq!(preshape_events(&events), vec![Some(Preshape::Lateral)]);
    assert_eq!(second.hand.state().0, HandState::Preshaped);
}

#[test]
fn heartbeats_keep_the_hand_shaped_and_silence_opens_it() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let cfg = LinkConfig {
        heartbeat_interval_ms: 20,
        watchdog_ms: 300,
        ..fast_link()
    };
    let hand = start_hand(pty.path(), cfg);
    hand.send(preshape_command(Preshape::Pinch3)).unwrap();
    // Idle for several watchdog periods: heartbeats keep it pre-shaped.
    assert!(eventually(Duration::from_secs(10), || hand
        .stats()
        .heartbeats
        >= 40));
    assert_eq!(pty.hand.state().0, HandState::Preshaped);
    drop(hand); // the host goes silent
    assert!(
        eventually(Duration::from_secs(10), || pty.hand.state().0
            == HandState::Open),
        "the watchdog opened the hand"
    );
    let events = pty.hand.events();
    assert!(
        events
            .iter()
            // The hand opens once the silence exceeds 300 ms; the event
            // reports whole milliseconds (truncated), so 300.4 ms reads 300.
            .any(|e| matches!(e, HandEvent::WatchdogOpen { silent_ms } if *silent_ms >= 300)),
        "{events:?}"
    );
}

#[test]
fn a_send_after_a_stop_transmits_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let hand = start_hand(pty.path(), fast_link());
    let stop = AtomicBool::new(true);
    let before = hand.stats().transmissions;
    let sent = hand.send_unless_stopped(preshape_command(Preshape::Pinch), None, Some(&stop));
    assert!(
        matches!(
            sent,
            Err(LinkError::Stopped {
                transmissions: 0,
                ..
            })
        ),
        "{sent:?}"
    );
    // Heartbeats may go out meanwhile; the PRESHAPE never does.
    assert!(preshape_events(&pty.hand.events()).is_empty());
    assert!(hand.stats().transmissions >= before);
}

#[test]
fn a_stop_while_waiting_for_the_trigger_fails_the_run_with_the_stop_code() {
    use runtime::session::{ReportLog, Session, EXIT_STOPPED};
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let hand = start_hand(pty.path(), fast_link());
    let stop = AtomicBool::new(true);
    let policy = PolicyConfig::default();
    let mut model = FakeModel::new();
    let mut session = Session {
        hand: &hand,
        classifier: &mut model,
        policy: &policy,
        mode: FeedMode::Lockstep,
        stop: &stop,
    };
    let source = MemorySource::new(
        frames_of(&[Class::Power; 4]),
        30.0,
        Pacing::AsFastAsPossible,
    )
    .unwrap();
    let mut log = ReportLog::default();
    let (_, summary) = session
        .run(
            Box::new(source),
            1,
            &mut Timer(Duration::ZERO),
            None,
            &mut log,
        )
        .unwrap();
    assert!(log.0.is_empty(), "no approach ran");
    assert_eq!(summary.exit_code(), EXIT_STOPPED);
    assert_eq!(
        summary.failure_message().unwrap(),
        "stopped on request while waiting for the trigger of approach 1: no command in flight"
    );
    assert!(preshape_events(&pty.hand.events()).is_empty());
}
