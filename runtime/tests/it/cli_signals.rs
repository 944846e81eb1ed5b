//! `hannes-run run` stopped by a signal at each phase of an approach: the
//! window, the pre-shape in flight, the closure delay. The hand is left
//! open and nothing more is sent.

use crate::cli_common::*;
use crate::common::eventually;
use runtime::simhand::{FaultSpec, HandEvent, PtyHand};
use std::time::Duration;

/// Before the fix the window ran to its end, the PRESHAPE was sent after
/// the signal and `run` exited 0.
#[test]
fn a_signal_during_the_window_sends_nothing_and_exits_with_its_code() {
    let dir = tempfile::tempdir().unwrap();
    // One frame a second, a 30 s window: the signal comes in the window.
    let approach = Approach::new(dir.path(), 40, None);
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let mut args = approach.args(pty.path().to_str().unwrap());
    args.retain(|a| *a != "--as-fast");
    set(&mut args, "--closure", "delay:30");
    args.extend(["--fps", "1", "--window", "30"]);
    args.extend(["--report", approach.report.to_str().unwrap()]);
    let run = Running::spawn(&args);
    run.wait_for_line(&["approach 1: triggered"]);
    run.signal(libc::SIGTERM);
    let (code, stderr) = run.finish();
    assert_eq!(code, Some(143), "{stderr}");
    assert_eq!(
        last_line(stderr.as_bytes()),
        "Error: approach 1: stopped by SIGTERM during the approach window: \
         nothing was sent to the hand"
    );
    assert!(stderr.contains("1 stopped"), "{stderr}");
    let events = pty.hand.events();
    assert!(movements(&events).is_empty(), "{events:?}");
    let line = report_line(&approach.report);
    assert_eq!(line["result"], "stopped");
    assert_eq!(line["stopped"]["signal"], "SIGTERM");
    assert_eq!(line["stopped"]["phase"], "window");
    assert_eq!(line["window"]["decision"]["outcome"]["how"], "stopped");
    assert!(line["preshape"].is_null() && line["reopened"].is_null());
}

/// Before the fix a signal while the PRESHAPE waited for its ACK changed
/// nothing: it was retransmitted, the closure followed, and `run` exited 0.
#[test]
fn a_signal_while_the_preshape_is_in_flight_stops_retransmissions_and_opens_the_hand() {
    let dir = tempfile::tempdir().unwrap();
    // One attempt waits 1.5 s for its ACK; the hand holds every PRESHAPE
    // (and what follows it) 3 s: the first copy is in flight when the
    // signal comes, and a retransmission would follow 1.5 s after it.
    let config = dir.path().join("slow-link.toml");
    std::fs::write(
        &config,
        "[link]\nack_timeout_ms = 1500\nretries = 5\nwatchdog_ms = 20000\n",
    )
    .unwrap();
    let approach = Approach::new(dir.path(), 4, None).with_config(config);
    let faults: FaultSpec = "delay=1:3000,on=preshape".parse().unwrap();
    let received = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let pty = {
        let received = received.clone();
        PtyHand::plug_with_faults(&dir.path().join("hand"), faults, move |e| {
            if let HandEvent::Fault {
                toward: runtime::simhand::Toward::Hand,
                cmd: 0x10,
                ..
            } = e
            {
                received.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            }
        })
        .unwrap()
    };
    let mut args = approach.args(pty.path().to_str().unwrap());
    set(&mut args, "--closure", "delay:30");
    args.extend(["--max-decision-age-ms", "30000"]);
    args.extend(["--report", approach.report.to_str().unwrap()]);
    let run = Running::spawn(&args);
    let arrived = eventually(Duration::from_secs(60), || {
        received.load(std::sync::atomic::Ordering::SeqCst) > 0
    });
    assert!(arrived, "no PRESHAPE reached the hand:\n{}", run.stderr());
    // Copies so far (1 unless this test stalled past an ACK timeout).
    let before_signal = received.load(std::sync::atomic::Ordering::SeqCst);
    run.signal(libc::SIGHUP);
    let (code, stderr) = run.finish();
    assert_eq!(code, Some(129), "{stderr}");
    assert_eq!(
        last_line(stderr.as_bytes()),
        "Error: approach 1: stopped by SIGHUP while the pre-shape was being sent: hand opened"
    );
    assert_eq!(
        received.load(std::sync::atomic::Ordering::SeqCst),
        before_signal,
        "a PRESHAPE was sent after the signal: {:?}",
        pty.hand.events()
    );
    // The copy in flight was executed when the hand let it through; the
    // OPEN sent after the signal came behind it.
    assert_eq!(movements(&pty.hand.events()), vec!["preshape", "open"]);
    let line = report_line(&approach.report);
    assert_eq!(line["result"], "stopped");
    assert_eq!(line["stopped"]["phase"], "preshape");
    assert_eq!(line["stopped"]["may_have_moved"], true);
    assert_eq!(line["reopened"]["command"], "OPEN");
    assert!(line["closure"].is_null());
}

/// Before the fix Ctrl-C in the closure delay ended `run` at once with
/// code 0, the hand left pre-shaped and the report saying "commanded".
#[test]
fn ctrl_c_during_the_closure_delay_opens_the_hand_and_exits_130() {
    let dir = tempfile::tempdir().unwrap();
    let approach = Approach::new(dir.path(), 4, None);
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let mut args = approach.args(pty.path().to_str().unwrap());
    set(&mut args, "--closure", "delay:30");
    args.extend(["--report", approach.report.to_str().unwrap()]);
    let run = Running::spawn(&args);
    run.wait_for_line(&["acknowledged", "PRESHAPE"]);
    run.signal(libc::SIGINT);
    let (code, stderr) = run.finish();
    assert_eq!(code, Some(130), "{stderr}");
    assert_eq!(
        last_line(stderr.as_bytes()),
        "Error: approach 1: stopped by SIGINT while waiting for the closure: hand opened"
    );
    assert_eq!(movements(&pty.hand.events()), vec!["preshape", "open"]);
    let line = report_line(&approach.report);
    assert_eq!(line["result"], "stopped");
    assert_eq!(line["stopped"]["signal"], "SIGINT");
    assert_eq!(line["stopped"]["phase"], "closure_delay");
    assert_eq!(line["preshape"]["command"], "PRESHAPE");
    assert_eq!(line["reopened"]["hand_state"], "open");
    assert!(line["closure"].is_null());
}
