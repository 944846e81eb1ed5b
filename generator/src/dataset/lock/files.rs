//! The lock files on disk: their folder, names (`shard-K-of-N.lock`) and
//! contents.

use super::holder::Holder;
use crate::dataset::error::{DatasetError, Result};
use crate::dataset::shard::Shard;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The lock folder of a dataset's work folder.
pub fn locks_dir(work_dir: &Path) -> PathBuf {
    work_dir.join("locks")
}

pub(super) fn lock_name(shard: Shard) -> String {
    format!("shard-{}-of-{}.lock", shard.index, shard.count)
}

pub(super) enum ReadError {
    Gone,
    Unreadable(String),
}

/// Reads a lock file, giving a writer that is still creating it a moment.
pub(super) fn read_holder_patiently(path: &Path) -> Result<Holder, ReadError> {
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
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io("cannot read", path, e))?;
    serde_json::from_slice(&bytes).map_err(|source| DatasetError::LockFile {
        path: path.to_path_buf(),
        source,
    })
}

/// The current holders of every lock of a work folder (for messages).
pub fn holders(work_dir: &Path) -> Vec<Holder> {
    lock_files(&locks_dir(work_dir))
        .unwrap_or_default()
        .iter()
        .filter_map(|p| read_holder(p).ok())
        .collect()
}

pub(super) fn lock_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| DatasetError::io("cannot read", dir, e))?
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
pub(super) fn shard_of(path: &Path) -> Option<Shard> {
    let name = path.file_name()?.to_str()?;
    let rest = name.strip_prefix("shard-")?.strip_suffix(".lock")?;
    let (k, n) = rest.split_once("-of-")?;
    format!("{k}/{n}").parse().ok()
}

/// `OUT` of `OUT/.grasp-gen/locks/X.lock`.
pub(super) fn folder_of(lock: &Path) -> PathBuf {
    lock.ancestors()
        .nth(3)
        .map(Path::to_path_buf)
        .unwrap_or_else(|| lock.to_path_buf())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lock_names_round_trip() {
        let s = Shard { index: 3, count: 8 };
        assert_eq!(shard_of(Path::new(&lock_name(s))), Some(s));
        assert_eq!(shard_of(Path::new("x.lock")), None);
    }
}
