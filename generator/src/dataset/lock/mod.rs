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

mod files;
mod heartbeat;
mod holder;

pub use files::{holders, locks_dir, read_holder};
pub use heartbeat::{heartbeat_interval, OutputLock, HEARTBEAT_ENV};
pub use holder::{liveness, utc_time, Holder, Liveness};

use super::error::{DatasetError, Result};
use super::shard::Shard;
use files::{folder_of, lock_files, lock_name, read_holder_patiently, shard_of, ReadError};
use heartbeat::{heartbeat_age, heartbeat_verdict, start_heartbeat, SILENT_BEATS};
use holder::human_duration;
use std::path::Path;

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
    std::fs::create_dir_all(&dir).map_err(|e| DatasetError::io("cannot create", &dir, e))?;
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
        return Err(DatasetError::LockContended { lock: path });
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
    let json = serde_json::to_vec_pretty(me).map_err(|source| DatasetError::Serialise {
        what: "a lock holder",
        source,
    })?;
    let tmp = path.with_file_name(format!(".{}.tmp", me.token));
    std::fs::write(&tmp, &json).map_err(|e| DatasetError::io("cannot write", &tmp, e))?;
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
                    .map_err(|e| DatasetError::io("cannot write", path, e))?;
                Ok(true)
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
            Err(e) => Err(DatasetError::io("cannot create", path, e)),
        },
    }
}

/// Removes the conflicting lock at `path` if its holder is gone (or, with
/// `break_lock`, silent on another machine); otherwise fails naming it.
fn clear_conflict(path: &Path, me: &Holder, break_lock: bool) -> Result<()> {
    let holder = match read_holder_patiently(path) {
        Ok(h) => h,
        Err(ReadError::Gone) => return Ok(()),
        Err(ReadError::Unreadable(e)) => {
            return Err(DatasetError::LockUnreadable {
                folder: folder_of(path).to_path_buf(),
                lock: path.to_path_buf(),
                reason: e,
            })
        }
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
        Liveness::Alive(reason) => Err(DatasetError::InUse {
            folder: folder_of(path).to_path_buf(),
            holder: holder.describe(),
            reason,
            lock: path.to_path_buf(),
        }),
        Liveness::Unknown => Err(DatasetError::InUseElsewhere {
            folder: folder_of(path).to_path_buf(),
            holder: holder.describe(),
            age: heartbeat_age(path)
                .map(|d| human_duration(d.as_secs()))
                .unwrap_or_else(|| "?".into()),
            lock: path.to_path_buf(),
            beats: SILENT_BEATS,
            interval_s: heartbeat_interval().as_secs_f64(),
        }),
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
        Err(e) => return Err(DatasetError::io("cannot remove", path, e)),
    }
    if read_holder(&grave).is_ok_and(|h| h.token != token) {
        // Someone else's fresh lock: put it back.
        let _ = std::fs::hard_link(&grave, path);
    }
    let _ = std::fs::remove_file(&grave);
    Ok(())
}
