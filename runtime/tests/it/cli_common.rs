//! What the `hannes-run` command-line tests share: a stand-in checkpoint,
//! bare PNG sequences, a quick link config, the program run in the
//! foreground or the background, and the simulated hand as a process.
#![allow(dead_code)] // each test binary uses a different part

use crate::common::eventually;
use grasp_test_support::Program;
use runtime::simhand::HandEvent;
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::sync::OnceLock;
use std::time::Duration;

pub const BIN: &str = env!("CARGO_BIN_EXE_hannes-run");

/// A small stand-in checkpoint (random MobileNetV2 backbone, FC head, 32 px),
/// built once per test process.
pub fn checkpoint() -> &'static Path {
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
pub fn sequence(dir: &Path, n: usize, broken: Option<usize>) -> PathBuf {
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

/// `hannes-run bench` timing `frames` frames after one warm-up frame,
/// without the link and approach parts, with `extra` arguments.
pub fn bench_inference(checkpoint: &str, frames: &str, extra: &[&str]) -> Output {
    let base = [
        "bench",
        "--checkpoint",
        checkpoint,
        "--frames",
        frames,
        "--warmup",
        "1",
        "--sends",
        "0",
        "--approaches",
        "0",
    ];
    hannes_run(&[&base[..], extra].concat())
}

/// A config whose link gives up quickly.
pub fn quick_link_config(dir: &Path) -> PathBuf {
    let path = dir.join("run.toml");
    std::fs::write(
        &path,
        "[link]\nack_timeout_ms = 50\nreconnect_interval_ms = 20\nreconnect_timeout_ms = 300\n",
    )
    .unwrap();
    path
}

pub fn hannes_run(args: &[&str]) -> Output {
    program()
        .command(args)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The last line of stderr: the one-line reason.
pub fn last_line(stderr: &[u8]) -> String {
    text(stderr).lines().last().unwrap_or_default().to_string()
}

/// What one `hannes-run run` approach of a test reads and writes in its
/// folder: the frames, a link config (quick to give up unless replaced),
/// the report and the stand-in checkpoint.
pub struct Approach {
    pub seq: PathBuf,
    pub config: PathBuf,
    pub report: PathBuf,
    ckpt: String,
}

impl Approach {
    /// `frames` frames in `dir` (frame `broken`, if any, truncated).
    pub fn new(dir: &Path, frames: usize, broken: Option<usize>) -> Approach {
        Approach {
            seq: sequence(dir, frames, broken),
            config: quick_link_config(dir),
            report: dir.join("report.jsonl"),
            ckpt: checkpoint().to_string_lossy().into_owned(),
        }
    }

    /// The same approach with another link config file.
    pub fn with_config(self, config: PathBuf) -> Approach {
        Approach { config, ..self }
    }

    /// `run` now, to the hand at `port`, without a closure, as fast as the
    /// frames load.
    pub fn args<'a>(&'a self, port: &'a str) -> Vec<&'a str> {
        vec![
            "run",
            "--checkpoint",
            &self.ckpt,
            "--source",
            self.seq.to_str().unwrap(),
            "--port",
            port,
            "--config",
            self.config.to_str().unwrap(),
            "--trigger",
            "now",
            "--closure",
            "none",
            "--as-fast",
        ]
    }
}

pub fn spawn_simulated_hand(link: &Path) -> std::process::Child {
    let child = program()
        .command(["simulate-hand", "--pty"])
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

pub fn program() -> Program {
    Program::new(BIN)
}

/// `hannes-run run` in the background, its stderr collected line by line
/// so a test can wait for a phase of the approach.
pub struct Running {
    child: std::process::Child,
    stderr: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Running {
    pub fn spawn(args: &[&str]) -> Running {
        let mut child = program()
            .command(args)
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

    pub fn stderr(&self) -> String {
        self.stderr.lock().unwrap().join("\n")
    }

    /// Waits (bounded) for a line of stderr that contains every one of
    /// `parts`.
    pub fn wait_for_line(&self, parts: &[&str]) {
        let seen = eventually(Duration::from_secs(60), || {
            let lines = self.stderr.lock().unwrap();
            lines.iter().any(|l| parts.iter().all(|p| l.contains(p)))
        });
        assert!(seen, "no line with {parts:?} in:\n{}", self.stderr());
    }

    pub fn signal(&self, signal: i32) {
        // SAFETY: a plain kill(2) of our own child.
        assert_eq!(unsafe { libc::kill(self.child.id() as i32, signal) }, 0);
    }

    /// Waits (bounded) for the exit; returns the code and stderr.
    pub fn finish(mut self) -> (Option<i32>, String) {
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
pub fn movements(events: &[HandEvent]) -> Vec<&'static str> {
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
pub fn set<'a>(args: &mut [&'a str], option: &str, value: &'a str) {
    let i = args.iter().position(|a| *a == option).expect(option);
    args[i + 1] = value;
}

pub fn report_line(path: &Path) -> serde_json::Value {
    serde_json::from_str(std::fs::read_to_string(path).unwrap().trim()).unwrap()
}
