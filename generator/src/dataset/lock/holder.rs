//! Who holds a lock and whether that process can still be running: the
//! holder's identity (pid, host, boot, pid namespace, Slurm job) and the
//! `/proc` facts that tell a live holder from a dead one.

use crate::dataset::shard::Shard;
use serde::{Deserialize, Serialize};
use std::time::{SystemTime, UNIX_EPOCH};

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
    pub(super) fn current(shard: Shard, purpose: &str) -> Holder {
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

    pub(super) fn same_machine(&self, other: &Holder) -> bool {
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

pub(super) fn human_duration(secs: u64) -> String {
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
}
