//! Links to a simulated hand's pseudo-terminal, and who owns them.
//!
//! `simulate-hand --pty LINK` makes LINK a symlink to its `/dev/pts/N`. If
//! the simulated hand dies without removing it (SIGKILL, a crash), the link
//! stays, and once the kernel gives `/dev/pts/N` to another program, a host
//! opening LINK would talk to that program. So the hand records itself
//! beside the link, in `LINK.owner` (JSON: pid, the process's start time
//! and boot id, which tell a reused pid apart, and the link's target), and
//! the host ([`check_link`], called by every [`crate::transport::SerialConnector`])
//! opens a link to a pseudo-terminal only if its owner is alive and
//! still claims that target.

use serde::{Deserialize, Serialize};
use std::ffi::OsString;
use std::io;
use std::path::{Path, PathBuf};

/// Why a pseudo-terminal link was not made.
#[derive(Debug, thiserror::Error)]
pub enum PtyError {
    #[error("cannot create a pseudo-terminal pair")]
    Pair(#[source] serialport::Error),
    #[error("the pseudo-terminal has no slave name")]
    SlaveName,
    #[error("cannot open {}", path.display())]
    OpenSlave {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("cannot encode the owner record of {}", link.display())]
    EncodeOwner {
        link: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    #[error(transparent)]
    WriteOwner(#[from] grasp_support::atomic::WriteError),
    #[error("cannot create symlink {}", path.display())]
    Symlink {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("cannot move symlink into place at {}", path.display())]
    PlaceSymlink {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
}

/// Who made a link, as recorded in [`owner_path`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LinkOwner {
    pub pid: u32,
    /// Start time of the process, in clock ticks since boot
    /// (`/proc/PID/stat`, field 22).
    pub start_ticks: Option<u64>,
    pub boot_id: Option<String>,
    /// The pseudo-terminal the link points at.
    pub target: PathBuf,
}

impl LinkOwner {
    fn this_process(target: &Path) -> LinkOwner {
        let pid = std::process::id();
        LinkOwner {
            pid,
            start_ticks: process_stat(pid).ok().and_then(|s| s.start_ticks),
            boot_id: boot_id(),
            target: target.to_path_buf(),
        }
    }
}

/// `LINK.owner`.
pub fn owner_path(link: &Path) -> PathBuf {
    let mut name = OsString::from(link.as_os_str());
    name.push(".owner");
    PathBuf::from(name)
}

/// A pseudo-terminal's slave side linked at a path, with its owner record.
/// Dropping it removes both (if they are still this one's) and closes the
/// slave side.
#[derive(Debug)]
pub struct PtyLink {
    link: PathBuf,
    target: PathBuf,
    /// Keeps the slave side open so the master never sees a hang-up while
    /// the host is between connections. A plain handle takes no lock, so
    /// the host may still open the slave exclusively.
    _keep: std::fs::File,
}

impl PtyLink {
    /// A new pseudo-terminal pair whose slave side is reachable at `link`;
    /// returns its master side.
    pub fn create(link: &Path) -> Result<(serialport::TTYPort, PtyLink), PtyError> {
        use std::os::unix::fs::OpenOptionsExt;
        let (master, slave) = serialport::TTYPort::pair().map_err(PtyError::Pair)?;
        let target = serialport::SerialPort::name(&slave).ok_or(PtyError::SlaveName)?;
        let target = PathBuf::from(target);
        let keep = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOCTTY)
            .open(&target)
            .map_err(|source| PtyError::OpenSlave {
                path: target.clone(),
                source,
            })?;
        drop(slave);
        // The record first: a host never sees the link without it.
        let owner = LinkOwner::this_process(&target);
        let record = serde_json::to_vec_pretty(&owner).map_err(|source| PtyError::EncodeOwner {
            link: link.to_path_buf(),
            source,
        })?;
        grasp_support::atomic::write_atomic(&owner_path(link), &record)?;
        let made = PtyLink {
            link: link.to_path_buf(),
            target,
            _keep: keep,
        };
        replace_symlink(&made.target, link)?;
        Ok((master, made))
    }

    pub fn target(&self) -> &Path {
        &self.target
    }

    pub fn path(&self) -> &Path {
        &self.link
    }
}

impl Drop for PtyLink {
    fn drop(&mut self) {
        // Another hand may have taken the path over: leave its link alone.
        if std::fs::read_link(&self.link).is_ok_and(|t| t == self.target) {
            let _ = std::fs::remove_file(&self.link);
        }
        let record = owner_path(&self.link);
        let ours = read_owner(&record)
            .is_ok_and(|o| o.pid == std::process::id() && o.target == self.target);
        if ours {
            let _ = std::fs::remove_file(record);
        }
    }
}

/// A pseudo-terminal pair whose slave side is reachable at `link_path`.
/// Returns the master and the link (drop it to unplug).
pub fn pty_pair(link_path: &Path) -> Result<(serialport::TTYPort, PtyLink), PtyError> {
    PtyLink::create(link_path)
}

/// Points `link` at `target`, atomically (temp link + rename).
pub fn replace_symlink(target: &Path, link: &Path) -> Result<(), PtyError> {
    let tmp = grasp_support::atomic::temp_path(link);
    std::os::unix::fs::symlink(target, &tmp).map_err(|source| PtyError::Symlink {
        path: tmp.clone(),
        source,
    })?;
    std::fs::rename(&tmp, link).map_err(|source| PtyError::PlaceSymlink {
        path: link.to_path_buf(),
        source,
    })
}

fn read_owner(record: &Path) -> io::Result<LinkOwner> {
    let text = std::fs::read(record)?;
    serde_json::from_slice(&text).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{}: {e}", record.display()),
        )
    })
}

/// Refuses a link that may lead to the wrong device: a symlink to a
/// pseudo-terminal whose recorded owner is gone, whose record names another
/// target, or that has no record at all. Anything else (a device node, a
/// udev link to a real adapter, a missing path) passes; opening it tells
/// the rest.
pub fn check_link(path: &Path) -> io::Result<()> {
    let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
    if !is_link {
        return Ok(());
    }
    let target = std::fs::read_link(path)?;
    let target = match target.is_absolute() {
        true => target,
        false => path.parent().unwrap_or(Path::new(".")).join(target),
    };
    let refuse = |why: String| {
        Err(io::Error::new(
            io::ErrorKind::PermissionDenied,
            format!("refusing {}: {why}", path.display()),
        ))
    };
    let record = owner_path(path);
    let owner = match read_owner(&record) {
        Ok(owner) => owner,
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            if target.starts_with("/dev/pts") {
                return refuse(format!(
                    "it points at the pseudo-terminal {} but no simulated hand claims it \
                     ({} is missing); open {0} itself if you made this link",
                    target.display(),
                    record.display()
                ));
            }
            return Ok(());
        }
        Err(e) => return refuse(format!("cannot read its owner record: {e}")),
    };
    if owner.target != target {
        return refuse(format!(
            "it points at {} but simulate-hand (pid {}) made it for {}",
            target.display(),
            owner.pid,
            owner.target.display()
        ));
    }
    if !is_alive(&owner) {
        return refuse(format!(
            "it was made by simulate-hand (pid {}), which is no longer running; {} may now \
             belong to another program (remove the stale link, or restart simulate-hand)",
            owner.pid,
            target.display()
        ));
    }
    Ok(())
}

/// Whether the process that wrote `owner` still runs (and is the same
/// process, not a reused pid).
fn is_alive(owner: &LinkOwner) -> bool {
    if owner.boot_id.is_some() && boot_id().is_some() && owner.boot_id != boot_id() {
        return false; // recorded before a reboot
    }
    match process_stat(owner.pid) {
        Ok(stat) => {
            let zombie = matches!(stat.state, 'Z' | 'X' | 'x');
            let same = owner.start_ticks.is_none() || owner.start_ticks == stat.start_ticks;
            !zombie && same
        }
        Err(e) if e.kind() == io::ErrorKind::NotFound => false,
        Err(_) => {
            // No /proc: ask the kernel whether the pid exists.
            // SAFETY: signal 0 only checks for existence.
            let r = unsafe { libc::kill(owner.pid as libc::pid_t, 0) };
            r == 0 || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
        }
    }
}

struct ProcStat {
    state: char,
    start_ticks: Option<u64>,
}

fn process_stat(pid: u32) -> io::Result<ProcStat> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat"))?;
    // The command name (field 2) is in parentheses and may hold spaces.
    let rest = text
        .rsplit_once(')')
        .map(|(_, r)| r)
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidData, "unreadable /proc stat"))?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    Ok(ProcStat {
        state: fields.first().and_then(|s| s.chars().next()).unwrap_or('?'),
        // Field 22 overall; fields after the name start at field 3.
        start_ticks: fields.get(19).and_then(|s| s.parse().ok()),
    })
}

fn boot_id() -> Option<String> {
    std::fs::read_to_string("/proc/sys/kernel/random/boot_id")
        .ok()
        .map(|s| s.trim().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_live_link_passes_and_is_removed_with_its_record() {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("hand");
        let (_master, made) = PtyLink::create(&link).unwrap();
        check_link(&link).unwrap();
        let owner = read_owner(&owner_path(&link)).unwrap();
        assert_eq!(owner.pid, std::process::id());
        assert_eq!(owner.target, made.target());
        assert!(owner.start_ticks.is_some());
        drop(made);
        assert!(link.symlink_metadata().is_err());
        assert!(!owner_path(&link).exists());
    }

    #[test]
    fn a_link_whose_owner_is_gone_or_unknown_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("hand");
        let (_master, made) = PtyLink::create(&link).unwrap();
        // The same pid but another start: the pid was reused.
        let mut owner = read_owner(&owner_path(&link)).unwrap();
        owner.start_ticks = owner.start_ticks.map(|t| t + 1);
        std::fs::write(owner_path(&link), serde_json::to_vec(&owner).unwrap()).unwrap();
        let e = check_link(&link).unwrap_err().to_string();
        assert!(e.contains("no longer running"), "{e}");
        // No record at all.
        std::fs::remove_file(owner_path(&link)).unwrap();
        let e = check_link(&link).unwrap_err().to_string();
        assert!(e.contains("no simulated hand claims it"), "{e}");
        // A record for another target.
        owner = LinkOwner::this_process(Path::new("/dev/pts/999999"));
        std::fs::write(owner_path(&link), serde_json::to_vec(&owner).unwrap()).unwrap();
        let e = check_link(&link).unwrap_err().to_string();
        assert!(e.contains("made it for /dev/pts/999999"), "{e}");
        drop(made);
    }

    #[test]
    fn links_to_anything_but_a_pseudo_terminal_pass_unchecked() {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("by-id");
        std::os::unix::fs::symlink("/dev/null", &link).unwrap();
        check_link(&link).unwrap();
        check_link(&dir.path().join("missing")).unwrap();
        check_link(Path::new("/dev/null")).unwrap();
    }
}
