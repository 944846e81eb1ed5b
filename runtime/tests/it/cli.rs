//! `hannes-run` as a user runs it: exit codes of failed approaches, the
//! simulated hand's `--pty` link on every way it stops, a stale link left by
//! a killed simulated hand, a closed stdout and errors under
//! `RUST_BACKTRACE=1`.

use crate::cli_common::*;
use grasp_test_support::program::assert_no_colour_codes;
use runtime::simhand::{FaultSpec, HandEvent, PtyHand};
use std::io::Read;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

#[test]
fn run_exits_3_with_a_reason_when_a_frame_cannot_be_read() {
    let dir = tempfile::tempdir().unwrap();
    let run = Approach::new(dir.path(), 8, Some(3));
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let out = hannes_run(&run.args(pty.path().to_str().unwrap()));
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
    let reason = last_line(&out.stderr);
    assert!(
        reason.starts_with("Error: ") && reason.contains("aborted") && reason.contains("frame"),
        "{reason}"
    );
    assert!(
        !pty.hand
            .events()
            .iter()
            .any(|e| matches!(e, HandEvent::Preshape { .. })),
        "an aborted approach sends nothing"
    );
}

#[test]
fn run_exits_4_with_a_reason_when_the_hand_cannot_be_reached() {
    let dir = tempfile::tempdir().unwrap();
    let run = Approach::new(dir.path(), 4, None);
    let missing = dir.path().join("no-hand-here");
    let out = hannes_run(&run.args(missing.to_str().unwrap()));
    assert_eq!(out.status.code(), Some(4), "{}", text(&out.stderr));
    let reason = last_line(&out.stderr);
    assert!(
        reason.starts_with("Error: ") && reason.contains("no-hand-here"),
        "{reason}"
    );
}

#[test]
fn run_exits_5_and_reports_a_decision_too_old_to_execute() {
    let dir = tempfile::tempdir().unwrap();
    let run = Approach::new(dir.path(), 4, None);
    // Every PRESHAPE is held 600 ms on its way: no decision can be
    // acknowledged within a 100 ms limit, and the hand refuses late copies.
    let faults: FaultSpec = "delay=1:600,on=preshape".parse().unwrap();
    let pty = PtyHand::plug_with_faults(&dir.path().join("hand"), faults, |_| {}).unwrap();
    let mut args = run.args(pty.path().to_str().unwrap());
    args.extend(["--max-decision-age-ms", "100", "--report"]);
    args.push(run.report.to_str().unwrap());
    let out = hannes_run(&args);
    assert_eq!(out.status.code(), Some(5), "{}", text(&out.stderr));
    let reason = last_line(&out.stderr);
    assert!(
        reason.starts_with("Error: approach 1: ") && reason.contains("100 ms age limit"),
        "{reason}"
    );
    let stderr = text(&out.stderr);
    assert!(stderr.contains("1 expired (stale decision)"), "{stderr}");
    let line: serde_json::Value =
        serde_json::from_str(std::fs::read_to_string(&run.report).unwrap().trim()).unwrap();
    assert_eq!(line["result"], "expired");
    assert_eq!(line["expired"]["command"], "PRESHAPE");
    assert_eq!(line["expired"]["limit_ms"], 100.0);
    assert!(line["preshape"].is_null() && line["closure"].is_null());
    assert!(
        !pty.hand
            .events()
            .iter()
            .any(|e| matches!(e, HandEvent::Preshape { .. })),
        "nothing executed: {:?}",
        pty.hand.events()
    );
}

#[test]
fn simulate_hand_removes_its_link_when_stopped_by_any_signal() {
    for signal in [libc::SIGTERM, libc::SIGINT, libc::SIGHUP] {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("hand.pty");
        let mut child = spawn_simulated_hand(&link);
        unsafe { libc::kill(child.id() as i32, signal) };
        let status = child.wait().unwrap();
        let mut stderr = String::new();
        child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut stderr)
            .unwrap();
        assert!(status.success(), "signal {signal}: {status:?} {stderr}");
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert!(left.is_empty(), "signal {signal} left {left:?}");
    }
}

#[test]
fn run_refuses_a_link_left_by_a_killed_simulated_hand() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("hand.pty");
    let mut child = spawn_simulated_hand(&link);
    let old_target = std::fs::read_link(&link).unwrap();
    child.kill().unwrap(); // SIGKILL: nothing can clean up
    child.wait().unwrap();
    assert!(link.symlink_metadata().is_ok(), "the stale link stays");
    // Another hand gets a pseudo-terminal; the kernel hands out the lowest
    // free number, usually the killed hand's. If another test took that
    // one, point the link at the new hand ourselves: the same situation.
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    let name = serialport::SerialPort::name(&slave).unwrap();
    if Path::new(&name) != old_target {
        let tmp = dir.path().join("relink");
        std::os::unix::fs::symlink(&name, &tmp).unwrap();
        std::fs::rename(&tmp, &link).unwrap();
    }
    let other = runtime::simhand::RunningHand::spawn(Box::new(master), |_| {}).unwrap();

    let run = Approach::new(dir.path(), 4, None);
    let out = hannes_run(&run.args(link.to_str().unwrap()));
    assert_eq!(out.status.code(), Some(4), "{}", text(&out.stderr));
    let reason = last_line(&out.stderr);
    assert!(reason.contains("hand.pty"), "{reason}");
    assert!(reason.contains("no longer running"), "{reason}");
    assert!(other.events().is_empty(), "{:?}", other.events());
    drop(slave);
}

#[test]
fn replay_into_a_closed_pipe_ends_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let seq = sequence(dir.path(), 4, None);
    let ckpt = checkpoint().to_string_lossy().into_owned();
    program().assert_quiet_in_closed_pipe([
        "replay",
        "--checkpoint",
        &ckpt,
        "--source",
        seq.to_str().unwrap(),
    ]);
}

#[test]
fn user_errors_show_the_message_without_a_backtrace() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing-checkpoint");
    let reason = program().user_error([
        "replay".as_ref(),
        "--checkpoint".as_ref(),
        missing.as_os_str(),
        "--source".as_ref(),
        dir.path().as_os_str(),
    ]);
    assert!(reason.contains("missing-checkpoint"), "{reason}");
}

#[test]
fn logs_carry_no_colour_codes_when_stderr_is_not_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let device = dir.path().join("no-device-yet");
    // The simulated hand logs a warning while it waits for its device.
    let mut child = program()
        .command(["simulate-hand", "--port"])
        .arg(&device)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let mut seen = Vec::new();
    let mut buf = [0u8; 4096];
    let deadline = Instant::now() + Duration::from_secs(20);
    while !String::from_utf8_lossy(&seen).contains("WARN") && Instant::now() < deadline {
        match stderr.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => seen.extend_from_slice(&buf[..n]),
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    let text = String::from_utf8_lossy(&seen);
    assert!(
        text.contains("WARN") && text.contains("waiting for"),
        "{text}"
    );
    assert_no_colour_codes(&text);
}

#[test]
fn replay_exits_3_like_run_when_a_frame_cannot_be_read() {
    let dir = tempfile::tempdir().unwrap();
    let seq = sequence(dir.path(), 8, Some(3));
    let ckpt = checkpoint().to_string_lossy().into_owned();
    for json in [false, true] {
        let mut args = vec!["replay", "--checkpoint", &ckpt, "--source"];
        args.push(seq.to_str().unwrap());
        if json {
            args.push("--json");
        }
        let out = hannes_run(&args);
        assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
        let reason = last_line(&out.stderr);
        assert!(
            reason.starts_with("Error: aborted") && reason.contains("frame"),
            "{reason}"
        );
    }
}

/// `bench --pace` times frames at a camera's pace: ten frames at 20 fps
/// take at least nine periods (back to back the stand-in takes
/// milliseconds), the report says how they were paced, and a pace that is
/// no rate is refused by name.
#[test]
fn bench_paces_its_frames_at_a_camera_rate() {
    let bench = |extra: &[&str]| {
        let ckpt = checkpoint().to_str().unwrap();
        bench_inference(ckpt, "10", &[&["--size", "32"], extra].concat())
    };
    let started = Instant::now();
    let out = bench(&["--pace", "20"]);
    let took = started.elapsed();
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report = text(&out.stdout);
    assert!(report.contains("(10 frames, at 20 fps)"), "{report}");
    assert!(
        !report.contains("link") && !report.contains("approach"),
        "{report}"
    );
    assert!(took >= Duration::from_millis(450), "{took:?}: {report}");
    let out = bench(&["--pace=-3"]);
    assert!(!out.status.success());
    assert!(
        last_line(&out.stderr).contains("--pace"),
        "{}",
        text(&out.stderr)
    );
    let out = bench(&[]);
    assert!(text(&out.stdout).contains("(10 frames, back to back)"));
}

#[test]
fn run_with_a_stdin_closure_at_end_of_input_opens_the_hand_and_exits_3() {
    // Issue 60, case 3: stdin ends before the closure key: no "commanded".
    let dir = tempfile::tempdir().unwrap();
    let run = Approach::new(dir.path(), 4, None);
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let mut args = run.args(pty.path().to_str().unwrap());
    let closure = args.iter().position(|a| *a == "--closure").unwrap();
    args[closure + 1] = "stdin";
    args.extend(["--report", run.report.to_str().unwrap()]);
    let out = hannes_run(&args); // stdin is /dev/null
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    let reason = last_line(&out.stderr);
    assert!(
        reason.contains("ended before it fired") && reason.ends_with("hand opened"),
        "{reason}"
    );
    assert!(stderr.contains("0 commanded"), "{stderr}");
    let line: serde_json::Value =
        serde_json::from_str(std::fs::read_to_string(&run.report).unwrap().trim()).unwrap();
    assert_eq!(line["result"], "aborted");
    assert!(!line["reopened"].is_null());
    assert_eq!(line["hand"]["state"], "open");
    assert!(matches!(
        pty.hand.events().last(),
        Some(HandEvent::Open { .. })
    ));
}

#[test]
fn a_checkpoint_error_under_rust_backtrace_is_one_line() {
    // Issue 60, case 4: candle captured a 64-line backtrace into the error.
    let dir = tempfile::tempdir().unwrap();
    let ckpt = dir.path().join("ckpt");
    std::fs::create_dir_all(&ckpt).unwrap();
    for entry in std::fs::read_dir(checkpoint()).unwrap() {
        let entry = entry.unwrap();
        if entry.file_type().unwrap().is_file() {
            std::fs::copy(entry.path(), ckpt.join(entry.file_name())).unwrap();
        }
    }
    let best = ckpt.join("best.json");
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&best).unwrap()).unwrap();
    meta["head"]["feature_dim"] = 1000.into();
    std::fs::write(&best, meta.to_string()).unwrap();
    let seq = sequence(dir.path(), 3, None);
    let finished = program().run([
        "replay".as_ref(),
        "--checkpoint".as_ref(),
        ckpt.as_os_str(),
        "--source".as_ref(),
        seq.as_os_str(),
    ]);
    let reason = finished.assert_user_error();
    assert!(reason.contains("shape mismatch"), "{reason}");
    assert!(
        !finished.stderr.contains("candle_core::"),
        "{}",
        finished.stderr
    );
    assert_eq!(finished.stderr.lines().count(), 1, "{}", finished.stderr);
}

#[test]
fn a_window_of_1e30_seconds_is_refused_before_the_hand_is_told_anything() {
    // Issue 60, case 7: it panicked converting the window to a Duration,
    // after `run` had sent HELLO.
    let dir = tempfile::tempdir().unwrap();
    let run = Approach::new(dir.path(), 4, None);
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let mut args = run.args(pty.path().to_str().unwrap());
    args.extend(["--window", "1e30"]);
    let line = program().user_error(&args);
    assert!(line.contains("window_s"), "{line}");
    let seq = run.seq.to_str().unwrap();
    let ckpt = checkpoint().to_str().unwrap();
    let line = program().user_error([
        "replay",
        "--checkpoint",
        ckpt,
        "--source",
        seq,
        "--window",
        "1e30",
    ]);
    assert!(line.contains("window_s"), "{line}");
    assert!(pty.hand.events().is_empty(), "{:?}", pty.hand.events());
}

#[test]
fn lens_size_alone_says_what_is_missing() {
    // Issue 60, case 15: it said what the flag is, not what was missing.
    let dir = tempfile::tempdir().unwrap();
    let seq = sequence(dir.path(), 3, None);
    let ckpt = checkpoint().to_str().unwrap();
    let line = program().user_error([
        "replay",
        "--checkpoint",
        ckpt,
        "--source",
        seq.to_str().unwrap(),
        "--lens-size",
        "640x480",
    ]);
    assert!(
        line.contains("without") && line.contains("--focal-px"),
        "{line}"
    );
}

#[test]
fn a_baud_rate_of_0_is_a_usage_error() {
    // Issue 60's note: --baud 0 was accepted.
    let dir = tempfile::tempdir().unwrap();
    let run = Approach::new(dir.path(), 4, None);
    let mut args = run.args("/dev/null");
    args.extend(["--baud", "0"]);
    let out = hannes_run(&args);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("--baud"),
        "{}",
        text(&out.stderr)
    );
}
