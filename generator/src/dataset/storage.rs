//! Telling a full disk from a bad frame. Blender reports "Saved" even when
//! the write failed for want of space, leaving a missing, empty or cut-short
//! file; so when a frame fails its check, a probe write into the same folder
//! asks the operating system directly and its error is reported instead.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Bytes the probe writes: more than a frame at the sizes rendered here, so
/// a disk too full for the next frame fails it.
const PROBE_BYTES: usize = 1 << 20;

/// The folder's file system refuses writes for want of space or quota.
#[derive(Debug, thiserror::Error)]
#[error("writing to {} fails", dir.display())]
pub struct StorageFull {
    pub dir: PathBuf,
    #[source]
    pub source: std::io::Error,
}

/// ENOSPC or EDQUOT.
pub fn is_full(e: &std::io::Error) -> bool {
    matches!(e.raw_os_error(), Some(28 | 122))
}

/// Writes and removes a probe file in `dir`; the error if the file system is
/// full (other errors are not this module's business).
pub fn probe(dir: &Path) -> Option<StorageFull> {
    let path = dir.join(format!(".space-probe-{}", std::process::id()));
    let result = std::fs::File::create(&path).and_then(|mut f| {
        f.write_all(&vec![0u8; PROBE_BYTES])?;
        f.sync_all()
    });
    let _ = std::fs::remove_file(&path);
    match result {
        Err(e) if is_full(&e) => Some(StorageFull {
            dir: dir.to_path_buf(),
            source: e,
        }),
        _ => None,
    }
}

/// Whether an error, anywhere in its chain, is a full file system.
pub fn is_storage_full(e: &(dyn std::error::Error + 'static)) -> bool {
    std::iter::successors(Some(e), |c| c.source())
        .any(|c| c.is::<StorageFull>() || c.downcast_ref::<std::io::Error>().is_some_and(is_full))
}
