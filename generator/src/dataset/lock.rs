//! The lock of an output folder: one file per shard in
//! `OUT/.grasp-gen/locks/`, so two runs never write the same sequences
//! while shards that split the work still share a folder.
//!
//! * A run of shard K/N takes `shard-K-of-N.lock`, created atomically (a
//!   hard link of a complete file, which also works on NFS), then looks at
//!   every other lock: shards K/N and K'/N' share a sequence exactly when
//!   K = K' mod gcd(N, N'), so `0/1` (a whole run, `dataset merge`) conflicts
//!   with every shard and `0/2`, `1/2` never conflict.
//! * The file names its holder: pid, host, start time, command, shard, and
//!   what tells a dead holder from a live one.
//! * A conflicting lock is stale, and removed with a message, when its
//!   holder ran on this machine (same host name, boot and pid namespace) and
//!   that process is gone (or the pid now belongs to a younger process), or
//!   when it was an earlier run of the same Slurm job (a requeued task runs
//!   with a higher `SLURM_RESTART_COUNT`). A holder on another machine is
//!   alive unless `--break-lock` is given and its heartbeat (the file's
//!   modification time, touched every [`heartbeat_interval`]) does not move
//!   for three intervals. A live holder is never overridden.
//! * The holder's heartbeat also checks that the file is still its own; a
//!   run whose lock was taken over stops instead of writing on.

use super::shard::Shard;
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Testing hook: the heartbeat interval in milliseconds (default 10 s).
pub const HEARTBEAT_ENV: &str = "GRASP_GEN_LOCK_HEARTBEAT_MS";

/// Heartbeats a `--break-lock` waits for before taking a lock over.
const SILENT_BEATS: u32 = 3;

pub fn heartbeat_interval() -> Duration {
    let ms = std::env::var(HEARTBEAT_ENV)
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        .filter(|ms| *ms > 0)
        .unwrap_or(10_000);
    Duration::from_millis(ms)
}

/// Who holds a lock, as written in the lock file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Holder {
    pub pid: u32,
    pub host: String,
    /// `/proc/sys/kernel/random/boot_id`: a different value means another
    /// machine (or a reboot) even under the same host name.
    pub boot_id: String,
    /// `/proc/self/ns/pid`: processes in another pid namespace (another
    /// container) cannot be seen, so they count as another machine.
    pub pid_namespace: String,
    /// Start time of the process in clock ticks since boot (`/proc/PID/stat`
    /// field 22), which tells a reused pid from the holder.
    pub process_start: Option<u64>,
    /// Seconds since 1970 (UTC).
    pub started_unix: u64,
    pub command: String,
    /// `render` or `merge`.
    pub purpose: String,
    /// The shard it writes, `K/N`.
    pub shard: String,
    /// Unique per acquisition, so a holder recognises its own file.
    pub token: String,
    #[serde(default)]
    pub slurm_job_id: Option<String>,
    #[serde(default)]
    pub slurm_restart_count: Option<u32>,
}

impl Holder {
    fn current(shard: Shard, purpose: &str) -> Holder {
        let pid = std::process::id();
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        Holder {
            pid,
            host: read_trimmed("/proc/sys/kernel/hostname")
                .or_else(|| std::env::var("HOSTNAME").ok())
                .unwrap_or_else(|| "unknown".into()),
            boot_id: read_trimmed("/proc/sys/kernel/random/boot_id").unwrap_or_default(),
            pid_namespace: std::fs::read_link("/proc/self/ns/pid")
                .map(|p| p.to_string_lossy().into_owned())
                .unwrap_or_default(),
            process_start: process_start(pid),
            started_unix: now.as_secs(),
            command: command_line(),
            purpose: purpose.to_string(),
            shard: shard.to_string(),
            token: format!("{pid}-{}-{}", now.as_nanos(), host_hash()),
            slurm_job_id: std::env::var("SLURM_JOB_ID").ok(),
            slurm_restart_count: std::env::var("SLURM_RESTART_COUNT")
                .ok()
                .and_then(|v| v.parse().ok())
                .or(std::env::var("SLURM_JOB_ID").ok().map(|_| 0)),
        }
    }

    fn same_machine(&self, other: &Holder) -> bool {
        self.host == other.host
            && self.boot_id == other.boot_id
            && self.pid_namespace == other.pid_namespace
    }

    /// One line naming the holder, for messages.
    pub fn describe(&self) -> String {
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(self.started_unix);
        format!(
            "{} of shard {} by pid {} on host {}, started {} ({} ago){}, command: {}",
            self.purpose,
            self.shard,
            self.pid,
            self.host,
            utc_time(self.started_unix),
            human_duration(now.saturating_sub(self.started_unix)),
            self.slurm_job_id
                .as_ref()
                .map(|j| format!(", Slurm job {j}"))
                .unwrap_or_default(),
            self.command
        )
    }
}

/// Whether a lock's holder can still be running.
#[derive(Debug, Clone, PartialEq)]
pub enum Liveness {
    Alive(String),
    Dead(String),
    /// On another machine: cannot be checked from here.
    Unknown,
}

/// Judges `holder` from the point of view of `me`.
pub fn liveness(holder: &Holder, me: &Holder) -> Liveness {
    if let (Some(job), Some(mine)) = (&holder.slurm_job_id, &me.slurm_job_id) {
        let (theirs, ours) = (
            holder.slurm_restart_count.unwrap_or(0),
            me.slurm_restart_count.unwrap_or(0),
        );
        if job == mine && theirs < ours {
            return Liveness::Dead(format!(
                "an earlier run (restart {theirs}) of Slurm job {job}, which Slurm has requeued"
            ));
        }
    }
    if !holder.same_machine(me) {
        return Liveness::Unknown;
    }
    if holder.pid == me.pid && holder.process_start == me.process_start {
        return Liveness::Alive("this very process holds it".into());
    }
    match (process_start(holder.pid), holder.process_start) {
        (None, _) => Liveness::Dead(format!("no process {} on this machine", holder.pid)),
        (Some(now), Some(then)) if now != then => Liveness::Dead(format!(
            "pid {} now belongs to a younger process",
            holder.pid
        )),
        _ => Liveness::Alive(format!("process {} is running", holder.pid)),
    }
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

/// The lock folder of a dataset's work folder.
pub fn locks_dir(work_dir: &Path) -> PathBuf {
    work_dir.join("locks")
}

fn lock_name(shard: Shard) -> String {
    format!("shard-{}-of-{}.lock", shard.index, shard.count)
}

/// Takes the lock of `shard` in `work_dir`, or fails naming the holder of
/// a conflicting one. `break_lock` also takes over locks of holders on
/// other machines whose heartbeat has stopped.
pub fn acquire(
    work_dir: &Path,
    shard: Shard,
    purpose: &str,
    break_lock: bool,
) -> Result<OutputLock> {
    let dir = locks_dir(work_dir);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let me = Holder::current(shard, purpose);
    let path = dir.join(lock_name(shard));
    let mut created = false;
    for _ in 0..5 {
        if create_lock_file(&path, &me)? {
            created = true;
            break;
        }
        clear_conflict(&path, &me, break_lock)?;
    }
    if !created {
        bail!(
            "cannot take the lock {}: other processes keep creating it",
            path.display()
        );
    }
    let lock = start_heartbeat(path.clone(), me.token.clone());
    // Our file exists now: any later overlapping run sees it.
    for other in lock_files(&dir)? {
        if other == path {
            continue;
        }
        let Some(other_shard) = shard_of(&other) else {
            continue;
        };
        if other_shard.overlaps(&shard) {
            // On failure `lock` drops and removes our own file.
            clear_conflict(&other, &me, break_lock)?;
        }
    }
    Ok(lock)
}

/// Creates `path` holding `me` if it does not exist; false if it does.
fn create_lock_file(path: &Path, me: &Holder) -> Result<bool> {
    let json = serde_json::to_vec_pretty(me)?;
    let tmp = path.with_file_name(format!(".{}.tmp", me.token));
    std::fs::write(&tmp, &json).with_context(|| format!("cannot write {}", tmp.display()))?;
    let linked = std::fs::hard_link(&tmp, path);
    let _ = std::fs::remove_file(&tmp);
    match linked {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        // A file system without hard links: exclusive creation instead.
        Err(_) => match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
        {
            Ok(mut f) => {
                use std::io::Write;
                f.write_all(&json)
                    .and_then(|_| f.sync_all())
                    .with_context(|| format!("cannot write {}", path.display()))?;
                Ok(true)
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
            Err(e) => Err(e).with_context(|| format!("cannot create {}", path.display())),
        },
    }
}

/// Removes the conflicting lock at `path` if its holder is gone (or, with
/// `break_lock`, silent on another machine); otherwise fails naming it.
fn clear_conflict(path: &Path, me: &Holder, break_lock: bool) -> Result<()> {
    let holder = match read_holder_patiently(path) {
        Ok(h) => h,
        Err(ReadError::Gone) => return Ok(()),
        Err(ReadError::Unreadable(e)) => bail!(
            "{} is locked, but the lock file {} is unreadable ({e}); if no grasp-gen is \
             writing there, remove it",
            folder_of(path).display(),
            path.display()
        ),
    };
    let verdict = match liveness(&holder, me) {
        Liveness::Unknown if break_lock => heartbeat_verdict(path, &holder)?,
        other => other,
    };
    match verdict {
        Liveness::Dead(reason) => {
            tracing::warn!(
                "removing the stale lock {} ({reason}): {}",
                path.display(),
                holder.describe()
            );
            remove_if_token(path, &holder.token)
        }
        Liveness::Alive(reason) => bail!(
            "{} is in use: {}; {reason} (lock {}). Wait for it to finish or stop it first",
            folder_of(path).display(),
            holder.describe(),
            path.display()
        ),
        Liveness::Unknown => bail!(
            "{} is in use: {}; last heartbeat {} ago (lock {}). That host is not this \
             machine, so it cannot be checked from here. If that process is gone, run \
             again with --break-lock: it takes the lock over once the heartbeat has \
             stopped for {} intervals of {} s",
            folder_of(path).display(),
            holder.describe(),
            heartbeat_age(path)
                .map(|d| human_duration(d.as_secs()))
                .unwrap_or_else(|| "?".into()),
            path.display(),
            SILENT_BEATS,
            heartbeat_interval().as_secs_f64()
        ),
    }
}

/// `--break-lock` on a holder elsewhere: dead if its heartbeat does not move
/// for [`SILENT_BEATS`] intervals, alive if it does.
fn heartbeat_verdict(path: &Path, holder: &Holder) -> Result<Liveness> {
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

/// Removes `path` only if it still holds the lock with `token`: it is moved
/// aside first, so a lock created meanwhile by someone else survives.
fn remove_if_token(path: &Path, token: &str) -> Result<()> {
    let grave = path.with_file_name(format!(
        ".{}.broken-{}",
        path.file_name().unwrap_or_default().to_string_lossy(),
        std::process::id()
    ));
    match std::fs::rename(path, &grave) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e).with_context(|| format!("cannot remove {}", path.display())),
    }
    if read_holder(&grave).is_ok_and(|h| h.token != token) {
        // Someone else's fresh lock: put it back.
        let _ = std::fs::hard_link(&grave, path);
    }
    let _ = std::fs::remove_file(&grave);
    Ok(())
}

fn start_heartbeat(path: PathBuf, token: String) -> OutputLock {
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

enum ReadError {
    Gone,
    Unreadable(String),
}

/// Reads a lock file, giving a writer that is still creating it a moment.
fn read_holder_patiently(path: &Path) -> Result<Holder, ReadError> {
    let mut last = String::new();
    for _ in 0..10 {
        match std::fs::read(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(ReadError::Gone),
            Err(e) => last = e.to_string(),
            Ok(bytes) => match serde_json::from_slice(&bytes) {
                Ok(h) => return Ok(h),
                Err(e) => last = e.to_string(),
            },
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Err(ReadError::Unreadable(last))
}

pub fn read_holder(path: &Path) -> Result<Holder> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("invalid lock file {}", path.display()))
}

/// The current holders of every lock of a work folder (for messages).
pub fn holders(work_dir: &Path) -> Vec<Holder> {
    lock_files(&locks_dir(work_dir))
        .unwrap_or_default()
        .iter()
        .filter_map(|p| read_holder(p).ok())
        .collect()
}

fn lock_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let name = p.file_name().unwrap_or_default().to_string_lossy();
            name.ends_with(".lock") && !name.starts_with('.')
        })
        .collect();
    out.sort();
    Ok(out)
}

/// The shard of a lock file name `shard-K-of-N.lock`.
fn shard_of(path: &Path) -> Option<Shard> {
    let name = path.file_name()?.to_str()?;
    let rest = name.strip_prefix("shard-")?.strip_suffix(".lock")?;
    let (k, n) = rest.split_once("-of-")?;
    format!("{k}/{n}").parse().ok()
}

/// `OUT` of `OUT/.grasp-gen/locks/X.lock`.
fn folder_of(lock: &Path) -> PathBuf {
    lock.ancestors()
        .nth(3)
        .map(Path::to_path_buf)
        .unwrap_or_else(|| lock.to_path_buf())
}

fn modified(path: &Path) -> Option<SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

fn heartbeat_age(path: &Path) -> Option<Duration> {
    SystemTime::now().duration_since(modified(path)?).ok()
}

fn read_trimmed(path: &str) -> Option<String> {
    std::fs::read_to_string(path)
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
}

/// Start time of process `pid` in clock ticks since boot, if it exists.
fn process_start(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) may hold spaces: count after its ')'.
    let after = &stat[stat.rfind(')')? + 1..];
    after.split_whitespace().nth(19)?.parse().ok()
}

fn host_hash() -> u64 {
    read_trimmed("/proc/sys/kernel/random/boot_id")
        .unwrap_or_default()
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        })
}

fn command_line() -> String {
    std::env::args()
        .map(|a| {
            if a.is_empty() || a.contains(char::is_whitespace) {
                format!("'{a}'")
            } else {
                a
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// `YYYY-MM-DD HH:MM:SS UTC` of a Unix time (civil-from-days, closed form).
pub fn utc_time(unix: u64) -> String {
    let days = (unix / 86_400) as i64;
    let secs = unix % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02}:{:02} UTC",
        secs / 3600,
        secs / 60 % 60,
        secs % 60
    )
}

fn human_duration(secs: u64) -> String {
    match secs {
        s if s < 120 => format!("{s} s"),
        s if s < 7200 => format!("{} min", s / 60),
        s if s < 172_800 => format!("{:.1} h", s as f64 / 3600.0),
        s => format!("{} days", s / 86_400),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn holder(host: &str, pid: u32) -> Holder {
        let mut h = Holder::current(Shard::ALL, "render");
        h.host = host.into();
        h.pid = pid;
        h.token = format!("t{pid}");
        h
    }

    #[test]
    fn utc_time_is_the_civil_date() {
        assert_eq!(utc_time(0), "1970-01-01 00:00:00 UTC");
        assert_eq!(utc_time(951_782_400), "2000-02-29 00:00:00 UTC");
        assert_eq!(utc_time(1_700_000_000), "2023-11-14 22:13:20 UTC");
    }

    #[test]
    fn a_dead_pid_on_this_machine_is_stale_a_live_one_is_not() {
        let me = Holder::current(Shard::ALL, "render");
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let dead_pid = child.id();
        child.wait().unwrap();
        let dead = holder(&me.host, dead_pid);
        assert!(matches!(liveness(&dead, &me), Liveness::Dead(_)));
        // The parent of this test process is alive, with its own start time.
        let ppid = std::os::unix::process::parent_id();
        let mut live = holder(&me.host, ppid);
        live.process_start = process_start(ppid);
        assert!(matches!(liveness(&live, &me), Liveness::Alive(_)));
        // The same pid with another start time is a reused pid.
        live.process_start = live.process_start.map(|t| t + 1);
        assert!(matches!(liveness(&live, &me), Liveness::Dead(_)));
        // This process itself (another of its runs) is alive.
        let me_again = Holder {
            token: "another".into(),
            ..me.clone()
        };
        assert!(matches!(liveness(&me_again, &me), Liveness::Alive(_)));
        // Another machine cannot be judged from here.
        let far = holder("some-other-host", ppid);
        assert_eq!(liveness(&far, &me), Liveness::Unknown);
    }

    #[test]
    fn an_earlier_run_of_the_same_slurm_job_is_stale() {
        let mut me = Holder::current(Shard::ALL, "render");
        me.slurm_job_id = Some("42".into());
        me.slurm_restart_count = Some(1);
        let mut before = holder("node-a", 1);
        before.slurm_job_id = Some("42".into());
        before.slurm_restart_count = Some(0);
        assert!(matches!(liveness(&before, &me), Liveness::Dead(_)));
        before.slurm_job_id = Some("43".into());
        assert_eq!(liveness(&before, &me), Liveness::Unknown);
    }

    #[test]
    fn lock_names_round_trip() {
        let s = Shard { index: 3, count: 8 };
        assert_eq!(shard_of(Path::new(&lock_name(s))), Some(s));
        assert_eq!(shard_of(Path::new("x.lock")), None);
    }
}
