//! `hannes-run simulate-hand`: the hand side of the protocol on a serial
//! device or a pseudo-terminal, one JSON line per event.

use crate::args::SimArgs;
use crate::setup::stop_flag;
use anyhow::{Context, Result};
use runtime::simhand::{DevicePort, HandEvent, Plug, PtyPlug, RunningHand};
use std::io::Write;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

pub(crate) fn simulate_hand(mut args: SimArgs) -> Result<()> {
    let stop = stop_flag()?;
    let started = Instant::now();
    let sink = move |e: &HandEvent| print_event(started, e);
    let faults = args.faults.take().unwrap_or_default();
    if faults.is_active() {
        eprintln!("injecting link faults: {faults}");
    }
    let (plug, ready) = plug(&args)?;
    let hand = RunningHand::start(plug, faults, sink)?;
    eprintln!("{ready}");
    while !stop.load(Ordering::Relaxed) && !hand.is_finished() {
        std::thread::sleep(Duration::from_millis(50));
    }
    // Stopping ends the serving thread, which unplugs: the link and its
    // owner record are removed.
    hand.stop().context("simulated hand failed")
}

/// The device side: a fresh pseudo-terminal (`--pty`) or a serial device
/// (`--port`), with the line that tells the user where to connect.
fn plug(args: &SimArgs) -> Result<(Box<dyn Plug>, String)> {
    Ok(match (&args.pty, &args.port) {
        (Some(link), _) => (
            Box::new(PtyPlug::new(link)?),
            format!(
                "simulated hand listening; connect the host to {}",
                link.display()
            ),
        ),
        (None, Some(port)) => (
            Box::new(DevicePort {
                path: port.clone(),
                baud: args.baud,
            }),
            format!("simulated hand serving {}", port.display()),
        ),
        (None, None) => unreachable!("clap requires --port or --pty"),
    })
}

fn print_event(started: Instant, e: &HandEvent) {
    let mut v = serde_json::to_value(e).unwrap_or_default();
    if let Some(obj) = v.as_object_mut() {
        obj.insert(
            "t_ms".into(),
            serde_json::json!(started.elapsed().as_millis() as u64),
        );
    }
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{v}");
    let _ = out.flush();
}
