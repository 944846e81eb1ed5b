//! The holder's heartbeat: a thread that touches the lock file every
//! [`heartbeat_interval`] and notices a takeover, and the watch that
//! `--break-lock` keeps on a silent holder elsewhere.

use super::files::read_holder;
use super::holder::{Holder, Liveness};
use crate::dataset::error::Result;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::{Duration, SystemTime};

/// Testing hook: the heartbeat interval in milliseconds (default 10 s).
pub const HEARTBEAT_ENV: &str = "GRASP_GEN_LOCK_HEARTBEAT_MS";

/// Heartbeats a `--break-lock` waits for before taking a lock over.
pub(super) const SILENT_BEATS: u32 = 3;

pub fn heartbeat_interval() -> Duration {
    let ms = std::env::var(HEARTBEAT_ENV)
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        .filter(|ms| *ms > 0)
        .unwrap_or(10_000);
    Duration::from_millis(ms)
}

/// A held lock; released when dropped.
pub struct OutputLock {
    path: PathBuf,
    token: String,
    lost: Arc<AtomicBool>,
    stop_heartbeat: Option<Sender<()>>,
    heartbeat: Option<std::thread::JoinHandle<()>>,
}

impl OutputLock {
    /// Whether another process took the lock over (the run must stop).
    pub fn lost(&self) -> bool {
        self.lost.load(Ordering::SeqCst)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        drop(self.stop_heartbeat.take());
        if let Some(h) = self.heartbeat.take() {
            let _ = h.join();
        }
        if read_holder(&self.path).is_ok_and(|h| h.token == self.token) {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

pub(super) fn start_heartbeat(path: PathBuf, token: String) -> OutputLock {
    let lost = Arc::new(AtomicBool::new(false));
    let (tx, rx) = channel::<()>();
    let (p, t, l) = (path.clone(), token.clone(), lost.clone());
    let heartbeat = std::thread::spawn(move || loop {
        match rx.recv_timeout(heartbeat_interval()) {
            Err(RecvTimeoutError::Timeout) => {}
            _ => return,
        }
        if !read_holder(&p).is_ok_and(|h| h.token == t) {
            tracing::error!(
                "the lock {} is no longer this run's: stopping (another run took it over)",
                p.display()
            );
            l.store(true, Ordering::SeqCst);
            return;
        }
        let _ = std::fs::OpenOptions::new()
            .write(true)
            .open(&p)
            .and_then(|f| f.set_modified(SystemTime::now()));
    });
    OutputLock {
        path,
        token,
        lost,
        stop_heartbeat: Some(tx),
        heartbeat: Some(heartbeat),
    }
}

/// `--break-lock` on a holder elsewhere: dead if its heartbeat does not move
/// for [`SILENT_BEATS`] intervals, alive if it does.
pub(super) fn heartbeat_verdict(path: &Path, holder: &Holder) -> Result<Liveness> {
    let wait = heartbeat_interval() * SILENT_BEATS;
    tracing::warn!(
        "--break-lock: watching the heartbeat of {} for {:.0} s: {}",
        path.display(),
        wait.as_secs_f64(),
        holder.describe()
    );
    let before = modified(path);
    std::thread::sleep(wait);
    let after = modified(path);
    let same_holder = read_holder(path).is_ok_and(|h| h.token == holder.token);
    if !same_holder {
        return Ok(Liveness::Alive(
            "the lock changed hands while watching".into(),
        ));
    }
    if before.is_some() && before == after {
        Ok(Liveness::Dead(format!(
            "--break-lock: no heartbeat for {:.0} s",
            wait.as_secs_f64()
        )))
    } else {
        Ok(Liveness::Alive("its heartbeat is still moving".into()))
    }
}

fn modified(path: &Path) -> Option<SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

pub(super) fn heartbeat_age(path: &Path) -> Option<Duration> {
    SystemTime::now().duration_since(modified(path)?).ok()
}
