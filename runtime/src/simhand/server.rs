//! Serving a [`SimHand`] on a port in its own thread: reading and answering
//! frames, passing them through the fault injector, unplugging and plugging
//! the hand's side of the link back in, and keeping the watchdog running
//! while unplugged (a hand whose cable is out still opens itself).

use super::faults::{FaultSpec, Injector, Toward};
use super::{HandEvent, SimHand};
use crate::decoder::Decoder;
use crate::protocol::{HandState, Packet};
use crate::transport::{is_timeout, open_serial, Duplex};
use grasp_schema::taxonomy::HandConfiguration;
use std::collections::VecDeque;
use std::io;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Longest wait for input before the loop looks at its timers.
const POLL: Duration = Duration::from_millis(5);
/// Pause before plugging in again after the port failed.
const REPLUG_AFTER_FAILURE: Duration = Duration::from_millis(200);
/// Pause between attempts to open a device that is not there (yet).
const PLUG_RETRY: Duration = Duration::from_millis(500);

/// Connects the hand's side of the link, and disconnects it.
pub trait Plug: Send {
    /// Connects; the host can reach the hand once this returns.
    fn plug(&mut self) -> io::Result<Box<dyn Duplex>>;
    /// Disconnects what `plug` connected (the port itself is already
    /// closed): the host sees the device vanish.
    fn unplug(&mut self);
    fn describe(&self) -> String;
    /// Whether a failed `plug` may succeed later.
    fn can_replug(&self) -> bool {
        true
    }
}

/// A port opened by the caller: served once, never re-opened.
pub struct OpenPort(Option<Box<dyn Duplex>>);

impl OpenPort {
    pub fn new(port: Box<dyn Duplex>) -> Self {
        OpenPort(Some(port))
    }
}

impl Plug for OpenPort {
    fn plug(&mut self) -> io::Result<Box<dyn Duplex>> {
        self.0.take().ok_or_else(|| {
            io::Error::new(io::ErrorKind::NotConnected, "the port was closed for good")
        })
    }

    fn unplug(&mut self) {}

    fn describe(&self) -> String {
        "the given port".into()
    }

    fn can_replug(&self) -> bool {
        self.0.is_some()
    }
}

/// A serial device (re-)opened by path: a USB adapter, one end of a
/// `socat` pair.
pub struct DevicePort {
    pub path: PathBuf,
    pub baud: u32,
}

impl Plug for DevicePort {
    fn plug(&mut self) -> io::Result<Box<dyn Duplex>> {
        Ok(Box::new(open_serial(&self.path, self.baud, true)?))
    }

    fn unplug(&mut self) {}

    fn describe(&self) -> String {
        self.path.display().to_string()
    }
}

/// Requests from the owning [`RunningHand`] to the serving thread.
#[derive(Debug)]
struct Control {
    faults_enabled: AtomicBool,
    requests: Mutex<VecDeque<Request>>,
}

#[derive(Debug, Clone, Copy)]
enum Request {
    Unplug,
    Replug,
}

type EventLog = Arc<Mutex<Vec<(Instant, HandEvent)>>>;

/// A simulated hand running on its own thread, with its event log.
pub struct RunningHand {
    hand: Arc<Mutex<SimHand>>,
    events: EventLog,
    control: Arc<Control>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<()>>>,
}

impl RunningHand {
    /// Serves an open port, without faults; `sink` also sees every event.
    pub fn spawn(
        port: Box<dyn Duplex>,
        sink: impl FnMut(&HandEvent) + Send + 'static,
    ) -> io::Result<RunningHand> {
        Self::start(Box::new(OpenPort::new(port)), FaultSpec::default(), sink)
    }

    /// Plugs in through `plug` and serves it on a new thread, injecting
    /// `faults`; `sink` also sees every event.
    pub fn start(
        plug: Box<dyn Plug>,
        faults: FaultSpec,
        mut sink: impl FnMut(&HandEvent) + Send + 'static,
    ) -> io::Result<RunningHand> {
        let started = Instant::now();
        let hand = Arc::new(Mutex::new(SimHand::new(started)));
        let events: EventLog = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let control = Arc::new(Control {
            faults_enabled: AtomicBool::new(true),
            requests: Mutex::new(VecDeque::new()),
        });
        let thread = {
            let (hand, events, stop, control) =
                (hand.clone(), events.clone(), stop.clone(), control.clone());
            std::thread::Builder::new()
                .name("simulated-hand".into())
                .spawn(move || {
                    // Stamped with the time the hand acted on, the one its
                    // deadline check saw.
                    let mut emit = |at: Instant, e: HandEvent| {
                        sink(&e);
                        lock(&events).push((at, e));
                    };
                    let mut server = Server {
                        hand: &hand,
                        plug,
                        port: None,
                        plug_at: Some(started),
                        plugged_before: false,
                        injector: Injector::new(faults, started),
                        control: &control,
                        framer: Decoder::new(),
                        decoder: Decoder::new(),
                        to_hand: DelayLine::default(),
                        to_host: DelayLine::default(),
                        emit: &mut emit,
                    };
                    server.run(&stop)
                })?
        };
        Ok(RunningHand {
            hand,
            events,
            control,
            stop,
            thread: Some(thread),
        })
    }

    pub fn state(&self) -> (HandState, HandConfiguration) {
        let h = lock(&self.hand);
        (h.state(), h.config())
    }

    pub fn events(&self) -> Vec<HandEvent> {
        lock(&self.events).iter().map(|(_, e)| e.clone()).collect()
    }

    /// The events with the time each happened.
    pub fn timed_events(&self) -> Vec<(Instant, HandEvent)> {
        lock(&self.events).clone()
    }

    /// Unplugs the hand's side of the link until [`RunningHand::replug`].
    pub fn unplug(&self) {
        lock(&self.control.requests).push_back(Request::Unplug);
    }

    /// Plugs the hand back in after [`RunningHand::unplug`].
    pub fn replug(&self) {
        lock(&self.control.requests).push_back(Request::Replug);
    }

    /// Turns the injected faults on or off (they start on).
    pub fn set_faults(&self, enabled: bool) {
        self.control.faults_enabled.store(enabled, Ordering::SeqCst);
    }

    /// Whether the serving thread ended (the port failed for good).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Stops serving and returns how the serving loop ended.
    pub fn stop(mut self) -> io::Result<()> {
        self.halt()
    }

    fn halt(&mut self) -> io::Result<()> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take() {
            Some(t) => t
                .join()
                .unwrap_or_else(|_| Err(io::Error::other("simulated hand panicked"))),
            None => Ok(()),
        }
    }
}

impl Drop for RunningHand {
    fn drop(&mut self) {
        let _ = self.halt();
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // The guarded values stay consistent if a holder panicked.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Bytes in transit, released in order: a held frame holds back the frames
/// behind it, as on a real link.
#[derive(Debug, Default)]
struct DelayLine {
    queue: VecDeque<(Instant, Vec<u8>)>,
}

impl DelayLine {
    fn push(&mut self, now: Instant, delay: Duration, bytes: Vec<u8>) {
        let behind = self.queue.back().map_or(now, |(t, _)| *t);
        self.queue.push_back(((now + delay).max(behind), bytes));
    }

    fn pop_due(&mut self, now: Instant) -> Option<Vec<u8>> {
        match self.queue.front() {
            Some((t, _)) if *t <= now => self.queue.pop_front().map(|(_, b)| b),
            _ => None,
        }
    }

    fn clear(&mut self) {
        self.queue.clear();
    }
}

struct Server<'a> {
    hand: &'a Mutex<SimHand>,
    plug: Box<dyn Plug>,
    port: Option<Box<dyn Duplex>>,
    /// While unplugged: when to plug in (again); `None` waits for a request.
    plug_at: Option<Instant>,
    plugged_before: bool,
    injector: Injector,
    control: &'a Control,
    /// Splits the host's bytes into frames for the injector.
    framer: Decoder,
    /// The hand's own decoder.
    decoder: Decoder,
    to_hand: DelayLine,
    to_host: DelayLine,
    emit: &'a mut dyn FnMut(Instant, HandEvent),
}

impl Server<'_> {
    fn run(&mut self, stop: &AtomicBool) -> io::Result<()> {
        let mut buf = [0u8; 256];
        while !stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            self.handle_requests(now);
            if let Some(len) = self.injector.outage_due(now) {
                self.unplug(now, "scheduled outage", Some(len));
            }
            if self.port.is_none() {
                self.try_plug(now)?;
            }
            let read = match self.port.as_mut() {
                Some(port) => Some(port.read(&mut buf)),
                None => {
                    std::thread::sleep(POLL);
                    None
                }
            };
            let now = Instant::now();
            match read {
                None => {}
                Some(Ok(0)) => self.port_failed(now, "port closed".into())?,
                Some(Ok(n)) => self.ingest(&buf[..n], now),
                Some(Err(e)) if is_timeout(&e) => {}
                Some(Err(e)) => self.port_failed(now, e.to_string())?,
            }
            self.deliver_due(now)?;
            self.send_due(now)?;
            self.tick(now);
        }
        Ok(())
    }

    fn handle_requests(&mut self, now: Instant) {
        let requests: Vec<Request> = lock(&self.control.requests).drain(..).collect();
        for r in requests {
            match r {
                Request::Unplug => self.unplug(now, "unplugged on request", None),
                Request::Replug => {
                    if self.port.is_none() {
                        self.plug_at = Some(now);
                    }
                }
            }
        }
    }

    /// Opens the hand if the link has been silent too long.
    fn tick(&mut self, now: Instant) {
        if let Some(e) = lock(self.hand).on_tick(now) {
            (self.emit)(now, e);
        }
    }

    fn try_plug(&mut self, now: Instant) -> io::Result<()> {
        if self.plug_at.is_none_or(|t| now < t) {
            return Ok(());
        }
        // The silence while unplugged counts before the plug: a stalled
        // loop must not log the replug ahead of the watchdog it missed.
        self.tick(now);
        match self.plug.plug() {
            Ok(mut port) => {
                port.set_read_timeout(POLL)?;
                self.port = Some(port);
                self.plug_at = None;
                if self.plugged_before {
                    (self.emit)(
                        now,
                        HandEvent::Replugged {
                            device: self.plug.describe(),
                        },
                    );
                }
                self.plugged_before = true;
                Ok(())
            }
            Err(e) if self.plug.can_replug() => {
                tracing::warn!("waiting for {}: {e}", self.plug.describe());
                self.plug_at = Some(now + PLUG_RETRY);
                Ok(())
            }
            Err(e) => Err(e),
        }
    }

    /// Disconnects; plugs back in after `len` (or on request if `None`).
    fn unplug(&mut self, now: Instant, reason: &str, len: Option<Duration>) {
        if self.port.take().is_none() {
            return;
        }
        self.plug.unplug();
        self.framer = Decoder::new();
        self.decoder = Decoder::new();
        self.to_hand.clear();
        self.to_host.clear();
        self.plug_at = len.map(|d| now + d);
        (self.emit)(
            now,
            HandEvent::Unplugged {
                reason: reason.into(),
                for_ms: len.map(|d| d.as_millis() as u64),
            },
        );
    }

    /// The port failed: plug in again if the plug can, else end.
    fn port_failed(&mut self, now: Instant, why: String) -> io::Result<()> {
        if !self.plug.can_replug() {
            return Err(io::Error::new(io::ErrorKind::BrokenPipe, why));
        }
        self.unplug(
            now,
            &format!("port failed: {why}"),
            Some(REPLUG_AFTER_FAILURE),
        );
        Ok(())
    }

    fn faults_enabled(&self) -> bool {
        self.control.faults_enabled.load(Ordering::SeqCst)
    }

    /// Bytes from the host, through the injector when faults are set.
    fn ingest(&mut self, bytes: &[u8], now: Instant) {
        if !self.injector.is_active() {
            self.decoder.push(bytes);
            return;
        }
        self.framer.push(bytes);
        while self.port.is_some() {
            let Some(p) = self.framer.next_packet() else {
                break;
            };
            let frame = p.encode();
            let enabled = self.faults_enabled();
            match self.injector.fate(Toward::Hand, &p, now, enabled) {
                None => self.to_hand.push(now, Duration::ZERO, frame),
                Some(fate) => {
                    self.report_faults(now, Toward::Hand, &p, &fate.kinds());
                    if let Some(len) = fate.disconnect {
                        self.unplug(now, "injected disconnect", Some(len));
                    } else if !fate.drop {
                        let mut frame = frame;
                        fate.corrupt(&mut frame);
                        let delay = fate.delay.unwrap_or_default();
                        if fate.duplicate {
                            self.to_hand.push(now, delay, frame.clone());
                        }
                        self.to_hand.push(now, delay, frame);
                    }
                }
            }
        }
    }

    fn report_faults(
        &mut self,
        now: Instant,
        toward: Toward,
        p: &Packet,
        kinds: &[super::FaultKind],
    ) {
        for &fault in kinds {
            (self.emit)(
                now,
                HandEvent::Fault {
                    fault,
                    toward,
                    seq: p.seq,
                    cmd: p.cmd,
                },
            );
        }
    }

    /// Hands the frames that arrived to the state machine and answers them.
    fn deliver_due(&mut self, now: Instant) -> io::Result<()> {
        while let Some(bytes) = self.to_hand.pop_due(now) {
            self.decoder.push(&bytes);
        }
        while let Some(p) = self.decoder.next_packet() {
            let (ack, event) = lock(self.hand).on_packet(&p, now);
            // Logged before the ACK leaves: whoever sees the ACK finds the
            // event in the log.
            if let Some(e) = event {
                (self.emit)(now, e);
            }
            if let Some(ack) = ack {
                self.answer(ack.packet(), now)?;
            }
            if self.port.is_none() {
                break;
            }
        }
        Ok(())
    }

    fn answer(&mut self, ack: Packet, now: Instant) -> io::Result<()> {
        let frame = ack.encode();
        if !self.injector.is_active() {
            return self.write(&frame, now);
        }
        let enabled = self.faults_enabled();
        match self.injector.fate(Toward::Host, &ack, now, enabled) {
            None => self.to_host.push(now, Duration::ZERO, frame),
            Some(fate) => {
                self.report_faults(now, Toward::Host, &ack, &fate.kinds());
                if !fate.drop {
                    let mut frame = frame;
                    fate.corrupt(&mut frame);
                    let delay = fate.delay.unwrap_or_default();
                    if fate.duplicate {
                        self.to_host.push(now, delay, frame.clone());
                    }
                    self.to_host.push(now, delay, frame);
                }
            }
        }
        self.send_due(now)
    }

    fn send_due(&mut self, now: Instant) -> io::Result<()> {
        while let Some(bytes) = self.to_host.pop_due(now) {
            self.write(&bytes, now)?;
        }
        Ok(())
    }

    fn write(&mut self, bytes: &[u8], now: Instant) -> io::Result<()> {
        let Some(port) = self.port.as_mut() else {
            return Ok(()); // unplugged: the bytes are lost with the cable
        };
        if let Err(e) = port.write_all(bytes).and_then(|_| port.flush()) {
            self.port_failed(now, e.to_string())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_frame_holds_back_the_frames_behind_it() {
        let t = Instant::now();
        let ms = Duration::from_millis;
        let mut line = DelayLine::default();
        line.push(t, ms(100), vec![1]);
        line.push(t + ms(10), Duration::ZERO, vec![2]);
        line.push(t + ms(150), Duration::ZERO, vec![3]);
        assert_eq!(line.pop_due(t + ms(99)), None);
        assert_eq!(line.pop_due(t + ms(100)), Some(vec![1]));
        assert_eq!(line.pop_due(t + ms(100)), Some(vec![2]), "queued behind 1");
        assert_eq!(line.pop_due(t + ms(149)), None);
        assert_eq!(line.pop_due(t + ms(150)), Some(vec![3]));
        assert_eq!(line.pop_due(t + ms(10_000)), None);
    }
}
