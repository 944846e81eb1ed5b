//! `hannes-run` as a user runs it: exit codes of failed approaches, the
//! simulated hand's `--pty` link on every way it stops, a stale link left by
//! a killed simulated hand, a closed stdout and errors under
//! `RUST_BACKTRACE=1`.

use grasp_test_support::program::{assert_no_colour_codes, Program};
use runtime::simhand::{FaultSpec, HandEvent, PtyHand};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_hannes-run");

/// A small stand-in checkpoint (random MobileNetV2 backbone, FC head, 32 px),
/// built once per test process.
fn checkpoint() -> &'static Path {
    static CKPT: OnceLock<PathBuf> = OnceLock::new();
    CKPT.get_or_init(|| {
        let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
        // Folders of earlier test processes that are gone.
        for entry in std::fs::read_dir(tmp).into_iter().flatten().flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            if let Some(pid) = name.strip_prefix("hannes-run-cli-checkpoint-") {
                if !Path::new("/proc").join(pid).exists() {
                    let _ = std::fs::remove_dir_all(entry.path());
                }
            }
        }
        let dir = tmp.join(format!("hannes-run-cli-checkpoint-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        trainer::stand_in::stand_in_checkpoint(
            &dir,
            32,
            grasp_model::backbone::Architecture::MobileNetV2,
        )
        .unwrap()
    })
}

/// A bare PNG sequence of `n` frames; frame `broken` (if any) is truncated.
fn sequence(dir: &Path, n: usize, broken: Option<usize>) -> PathBuf {
    let seq = dir.join("sequence");
    std::fs::create_dir_all(&seq).unwrap();
    for i in 0..n {
        let path = seq.join(format!("frame_{i:04}.png"));
        image::RgbImage::from_pixel(32, 32, image::Rgb([90, 120, 40]))
            .save(&path)
            .unwrap();
        if broken == Some(i) {
            let bytes = std::fs::read(&path).unwrap();
            std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        }
    }
    seq
}

/// A config whose link gives up quickly.
fn quick_link_config(dir: &Path) -> PathBuf {
    let path = dir.join("run.toml");
    std::fs::write(
        &path,
        "[link]\nack_timeout_ms = 50\nreconnect_interval_ms = 20\nreconnect_timeout_ms = 300\n",
    )
    .unwrap();
    path
}

fn hannes_run(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The last line of stderr: the one-line reason.
fn last_line(stderr: &[u8]) -> String {
    text(stderr).lines().last().unwrap_or_default().to_string()
}

fn run_args<'a>(ckpt: &'a str, seq: &'a str, port: &'a str, config: &'a str) -> Vec<&'a str> {
    vec![
        "run",
        "--checkpoint",
        ckpt,
        "--source",
        seq,
        "--port",
        port,
        "--config",
        config,
        "--trigger",
        "now",
        "--closure",
        "none",
        "--as-fast",
    ]
}

#[test]
fn run_exits_3_with_a_reason_when_a_frame_cannot_be_read() {
    let dir = tempfile::tempdir().unwrap();
    let seq = sequence(dir.path(), 8, Some(3));
    let config = quick_link_config(dir.path());
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let ckpt = checkpoint().to_string_lossy().into_owned();
    let out = hannes_run(&run_args(
        &ckpt,
        seq.to_str().unwrap(),
        pty.path().to_str().unwrap(),
        config.to_str().unwrap(),
    ));
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
    let seq = sequence(dir.path(), 4, None);
    let config = quick_link_config(dir.path());
    let missing = dir.path().join("no-hand-here");
    let ckpt = checkpoint().to_string_lossy().into_owned();
    let out = hannes_run(&run_args(
        &ckpt,
        seq.to_str().unwrap(),
        missing.to_str().unwrap(),
        config.to_str().unwrap(),
    ));
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
    let seq = sequence(dir.path(), 4, None);
    let config = quick_link_config(dir.path());
    // Every PRESHAPE is held 600 ms on its way: no decision can be
    // acknowledged within a 100 ms limit, and the hand refuses late copies.
    let faults: FaultSpec = "delay=1:600,on=preshape".parse().unwrap();
    let pty = PtyHand::plug_with_faults(&dir.path().join("hand"), faults, |_| {}).unwrap();
    let report = dir.path().join("report.jsonl");
    let ckpt = checkpoint().to_string_lossy().into_owned();
    let mut args = run_args(
        &ckpt,
        seq.to_str().unwrap(),
        pty.path().to_str().unwrap(),
        config.to_str().unwrap(),
    );
    args.extend(["--max-decision-age-ms", "100", "--report"]);
    args.push(report.to_str().unwrap());
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
        serde_json::from_str(std::fs::read_to_string(&report).unwrap().trim()).unwrap();
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

/// Polls `cond` for up to `limit` (a bound for a stuck test, not a timing
/// assertion).
fn eventually(limit: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let t = Instant::now();
    while t.elapsed() < limit {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    cond()
}

fn spawn_simulated_hand(link: &Path) -> std::process::Child {
    let child = Command::new(BIN)
        .args(["simulate-hand", "--pty"])
        .arg(link)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    assert!(
        eventually(Duration::from_secs(30), || link.symlink_metadata().is_ok()),
        "simulate-hand made no link"
    );
    child
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

    let seq = sequence(dir.path(), 4, None);
    let config = quick_link_config(dir.path());
    let ckpt = checkpoint().to_string_lossy().into_owned();
    let out = hannes_run(&run_args(
        &ckpt,
        seq.to_str().unwrap(),
        link.to_str().unwrap(),
        config.to_str().unwrap(),
    ));
    assert_eq!(out.status.code(), Some(4), "{}", text(&out.stderr));
    let reason = last_line(&out.stderr);
    assert!(reason.contains("hand.pty"), "{reason}");
    assert!(reason.contains("no longer running"), "{reason}");
    assert!(other.events().is_empty(), "{:?}", other.events());
    drop(slave);
}

fn program() -> Program {
    Program::new(BIN)
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
    let mut child = Command::new(BIN)
        .args(["simulate-hand", "--port"])
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

/// `hannes-run run` in the background, its stderr collected line by line
/// so a test can wait for a phase of the approach.
struct Running {
    child: std::process::Child,
    stderr: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Running {
    fn spawn(args: &[&str]) -> Running {
        let mut child = Command::new(BIN)
            .args(args)
            .env("RUST_BACKTRACE", "0")
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stderr = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let reader = {
            let (pipe, lines) = (child.stderr.take().unwrap(), stderr.clone());
            std::thread::spawn(move || {
                use std::io::BufRead;
                for line in std::io::BufReader::new(pipe).lines() {
                    let Ok(line) = line else { break };
                    lines.lock().unwrap().push(line);
                }
            })
        };
        Running {
            child,
            stderr,
            reader: Some(reader),
        }
    }

    fn stderr(&self) -> String {
        self.stderr.lock().unwrap().join("\n")
    }

    /// Waits (bounded) for a line of stderr that contains every one of
    /// `parts`.
    fn wait_for_line(&self, parts: &[&str]) {
        let seen = eventually(Duration::from_secs(60), || {
            let lines = self.stderr.lock().unwrap();
            lines.iter().any(|l| parts.iter().all(|p| l.contains(p)))
        });
        assert!(seen, "no line with {parts:?} in:\n{}", self.stderr());
    }

    fn signal(&self, signal: i32) {
        // SAFETY: a plain kill(2) of our own child.
        assert_eq!(unsafe { libc::kill(self.child.id() as i32, signal) }, 0);
    }

    /// Waits (bounded) for the exit; returns the code and stderr.
    fn finish(mut self) -> (Option<i32>, String) {
        let mut status = None;
        let exited = eventually(Duration::from_secs(60), || {
            status = self.child.try_wait().unwrap();
            status.is_some()
        });
        if !exited {
            let _ = self.child.kill();
            let _ = self.child.wait();
            panic!(
                "hannes-run did not exit after the signal:\n{}",
                self.stderr()
            );
        }
        self.reader.take().unwrap().join().unwrap();
        (status.unwrap().code(), self.stderr())
    }
}

/// The movements the hand executed, in order.
fn movements(events: &[HandEvent]) -> Vec<&'static str> {
    events
        .iter()
        .filter_map(|e| match e {
            HandEvent::Preshape { .. } => Some("preshape"),
            HandEvent::Close { .. } => Some("close"),
            HandEvent::Open { .. } => Some("open"),
            HandEvent::WatchdogOpen { .. } => Some("watchdog_open"),
            _ => None,
        })
        .collect()
}

/// Replaces the value of `option` in `args`.
fn set<'a>(args: &mut [&'a str], option: &str, value: &'a str) {
    let i = args.iter().position(|a| *a == option).expect(option);
    args[i + 1] = value;
}

fn report_line(path: &Path) -> serde_json::Value {
    serde_json::from_str(std::fs::read_to_string(path).unwrap().trim()).unwrap()
}

/// Before the fix the window ran to its end, the PRESHAPE was sent after
/// the signal and `run` exited 0.
#[test]
fn a_signal_during_the_window_sends_nothing_and_exits_with_its_code() {
    let dir = tempfile::tempdir().unwrap();
    // One frame a second, a 30 s window: the signal comes in the window.
    let seq = sequence(dir.path(), 40, None);
    let config = quick_link_config(dir.path());
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let report = dir.path().join("report.jsonl");
    let ckpt = checkpoint().to_string_lossy().into_owned();
    let mut args = run_args(
        &ckpt,
        seq.to_str().unwrap(),
        pty.path().to_str().unwrap(),
        config.to_str().unwrap(),
    );
    args.retain(|a| *a != "--as-fast");
    set(&mut args, "--closure", "delay:30");
    args.extend(["--fps", "1", "--window", "30"]);
    args.extend(["--report", report.to_str().unwrap()]);
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
    let line = report_line(&report);
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
    let seq = sequence(dir.path(), 4, None);
    // One attempt waits 1.5 s for its ACK; the hand holds every PRESHAPE
    // (and what follows it) 3 s: the first copy is in flight when the
    // signal comes, and a retransmission would follow 1.5 s after it.
    let config = dir.path().join("run.toml");
    std::fs::write(
        &config,
        "[link]\nack_timeout_ms = 1500\nretries = 5\nwatchdog_ms = 20000\n",
    )
    .unwrap();
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
    let report = dir.path().join("report.jsonl");
    let ckpt = checkpoint().to_string_lossy().into_owned();
    let mut args = run_args(
        &ckpt,
        seq.to_str().unwrap(),
        pty.path().to_str().unwrap(),
        config.to_str().unwrap(),
    );
    set(&mut args, "--closure", "delay:30");
    args.extend(["--max-decision-age-ms", "30000"]);
    args.extend(["--report", report.to_str().unwrap()]);
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
    let line = report_line(&report);
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
    let seq = sequence(dir.path(), 4, None);
    let config = quick_link_config(dir.path());
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let report = dir.path().join("report.jsonl");
    let ckpt = checkpoint().to_string_lossy().into_owned();
    let mut args = run_args(
        &ckpt,
        seq.to_str().unwrap(),
        pty.path().to_str().unwrap(),
        config.to_str().unwrap(),
    );
    set(&mut args, "--closure", "delay:30");
    args.extend(["--report", report.to_str().unwrap()]);
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
    let line = report_line(&report);
    assert_eq!(line["result"], "stopped");
    assert_eq!(line["stopped"]["signal"], "SIGINT");
    assert_eq!(line["stopped"]["phase"], "closure_delay");
    assert_eq!(line["preshape"]["command"], "PRESHAPE");
    assert_eq!(line["reopened"]["hand_state"], "open");
    assert!(line["closure"].is_null());
}

/// The stand-in checkpoint, copied with a fixed-angle crop of `angle_deg`.
fn angle_checkpoint(dir: &Path, angle_deg: f64) -> PathBuf {
    let ckpt = dir.join("angle-ckpt");
    std::fs::create_dir_all(&ckpt).unwrap();
    for entry in std::fs::read_dir(checkpoint()).unwrap().flatten() {
        std::fs::copy(entry.path(), ckpt.join(entry.file_name())).unwrap();
    }
    let json = ckpt.join("best.json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    meta["input"]["crop"] = serde_json::json!({ "angle_deg": angle_deg });
    std::fs::write(&json, serde_json::to_vec(&meta).unwrap()).unwrap();
    ckpt
}

/// A recording of `frames` whose sequence.json gives a square lens of
/// `focal` px at `lens_size` px.
fn recording(dir: &Path, frames: &[image::RgbImage], lens_size: u32, focal: f64) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut files = Vec::new();
    for (i, f) in frames.iter().enumerate() {
        let name = format!("{i:05}.png");
        f.save(dir.join(&name)).unwrap();
        files.push(name);
    }
    let record = serde_json::json!({
        "frame_files": files,
        "plan": {"fps": 10.0, "intrinsics": {
            "width": lens_size, "height": lens_size, "fx": focal, "fy": focal}},
    });
    std::fs::write(dir.join("sequence.json"), record.to_string()).unwrap();
    dir.to_path_buf()
}

/// Replay's per-frame rows without the timing column.
fn replay_rows(ckpt: &Path, seq: &Path) -> Vec<String> {
    let out = hannes_run(&[
        "replay",
        "--checkpoint",
        ckpt.to_str().unwrap(),
        "--source",
        seq.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    text(&out.stdout)
        .lines()
        .skip(1)
        .take_while(|l| !l.starts_with("decision"))
        .map(|l| {
            let mut words: Vec<&str> = l.split_whitespace().collect();
            words.pop(); // the timing
            words.join(" ")
        })
        .collect()
}

/// A recording scaled to half the size its sequence.json's intrinsics
/// were written for is cut at the checkpoint's angle through the lens
/// scaled with it: the same rows as the same frames with matching
/// intrinsics (it once got the full-size focal length, twice the crop and
/// a wrong pre-shape). Replay's JSON names the checkpoint, its input record
/// and the lens.
#[test]
fn a_recording_at_another_size_than_its_intrinsics_is_cut_at_the_same_angle() {
    let dir = tempfile::tempdir().unwrap();
    let focal = 32.0 / 21f64.to_radians().tan();
    let angle = grasp_schema::dataset::crop_angle_deg(0.5, focal, 64, 64);
    let ckpt = angle_checkpoint(dir.path(), angle);
    let frames: Vec<image::RgbImage> = (0..3)
        .map(|k| {
            image::RgbImage::from_fn(32, 32, |x, y| {
                let centre = (8..24).contains(&x) && (8..24).contains(&y);
                let v = if centre {
                    200 - 40 * k
                } else {
                    (x * 7 + y * 3) as u8
                };
                image::Rgb([v, (x * 8) as u8, (y * 8) as u8])
            })
        })
        .collect();
    let scaled = recording(&dir.path().join("scaled"), &frames, 64, focal);
    let matching = recording(&dir.path().join("matching"), &frames, 32, focal / 2.0);
    let rows = replay_rows(&ckpt, &scaled);
    assert_eq!(rows.len(), 3);
    assert_eq!(rows, replay_rows(&ckpt, &matching));

    let out = hannes_run(&[
        "replay",
        "--checkpoint",
        ckpt.to_str().unwrap(),
        "--source",
        scaled.to_str().unwrap(),
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let model = &json["model"];
    assert_eq!(model["checkpoint"], ckpt.to_str().unwrap());
    assert_eq!(model["input"]["crop"]["angle_deg"], angle);
    assert_eq!(model["lens"]["focal"]["width"], 64);
    assert_eq!(model["lens_from"], "sequence.json");
    assert!(json["decision"].is_object(), "{json}");

    // A focal length in millimetres is refused by name, not cut under a pixel.
    let out = hannes_run(&[
        "replay",
        "--checkpoint",
        ckpt.to_str().unwrap(),
        "--source",
        scaled.to_str().unwrap(),
        "--focal-px",
        "1.93",
        "--lens-size",
        "640x480",
    ]);
    assert!(!out.status.success());
    let reason = last_line(&out.stderr);
    assert!(
        reason.contains("focal_px") && reason.contains("field of view"),
        "{reason}"
    );
}
