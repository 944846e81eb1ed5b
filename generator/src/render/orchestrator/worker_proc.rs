//! One worker process seen from the parent: started with its log file,
//! spoken to one JSON line at a time, killed or asked to quit.

use super::shared::Shared;
use crate::render::error::{RenderError, Result};
use crate::render::protocol::{Request, Response};
use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::{Arc, Mutex};

/// A live worker process.
pub(super) struct WorkerProc {
    child: Arc<Mutex<Child>>,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
    /// What the worker asked to be logged when it started.
    pub(super) note: Option<String>,
}

impl WorkerProc {
    pub(super) fn spawn(slot: usize, ctx: &Shared) -> Result<Self> {
        let log_path = ctx.worker_log(slot);
        if let Some(logs) = log_path.parent() {
            std::fs::create_dir_all(logs).map_err(|e| RenderError::io("cannot create", logs, e))?;
        }
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log_path)
            .map_err(|e| RenderError::io("cannot open", &log_path, e))?;
        let mut child = Command::new(&ctx.exe)
            .arg("worker")
            .envs(ctx.worker_env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(log)
            // Own process group: a terminal Ctrl-C reaches only the parent,
            // which then stops the workers itself.
            .process_group(0)
            .spawn()
            .map_err(|e| RenderError::io("cannot start worker", &ctx.exe, e))?;
        let stdin = child
            .stdin
            .take()
            .ok_or(RenderError::WorkerPipe("worker stdin"))?;
        let stdout = BufReader::new(
            child
                .stdout
                .take()
                .ok_or(RenderError::WorkerPipe("worker stdout"))?,
        );
        let mut proc = WorkerProc {
            child: Arc::new(Mutex::new(child)),
            stdin,
            stdout,
            note: None,
        };
        ctx.children.lock().unwrap_or_else(|e| e.into_inner())[slot] = Some(proc.child.clone());
        let init = Request::Init {
            geometry: ctx.geometry.clone(),
            settings: ctx.settings.clone(),
        };
        match proc.call(&init, &log_path)? {
            Response::Ready { note, .. } => Ok(WorkerProc { note, ..proc }),
            Response::Error { message, fatal, .. } => {
                Err(RenderError::WorkerStart { message, fatal })
            }
            other => Err(RenderError::UnexpectedAnswer {
                answer: format!("{other:?}"),
            }),
        }
    }

    pub(super) fn call(&mut self, request: &Request, log: &Path) -> Result<Response> {
        let mut line = serde_json::to_string(request).map_err(|source| RenderError::Json {
            what: "a worker request",
            source,
        })?;
        line.push('\n');
        let sent = self
            .stdin
            .write_all(line.as_bytes())
            .and_then(|_| self.stdin.flush());
        let mut answer = String::new();
        let read = sent.and_then(|_| self.stdout.read_line(&mut answer));
        match read {
            Ok(n) if n > 0 => {
                serde_json::from_str(&answer).map_err(|source| RenderError::InvalidAnswer {
                    answer: answer.trim().to_string(),
                    source,
                })
            }
            _ => {
                let status = self.kill();
                Err(RenderError::WorkerDied {
                    status,
                    log: log.to_path_buf(),
                })
            }
        }
    }

    fn kill(&mut self) -> String {
        let mut c = self.child.lock().unwrap_or_else(|e| e.into_inner());
        let _ = c.kill();
        c.wait()
            .map(|s| s.to_string())
            .unwrap_or_else(|e| e.to_string())
    }

    pub(super) fn quit(mut self) {
        let _ = self
            .stdin
            .write_all(b"{\"type\":\"quit\"}\n")
            .and_then(|_| self.stdin.flush());
        drop(self.stdin);
        let mut c = self.child.lock().unwrap_or_else(|e| e.into_inner());
        let _ = c.wait();
    }
}
