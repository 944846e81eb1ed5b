//! The one way the toolkit writes a file: into a temporary sibling, synced,
//! then renamed over the destination, then the folder synced. A reader sees
//! the old file or the new one, never a part; a crash leaves at most a
//! hidden `.NAME.*.tmp` file beside it.
//!
//! Temporary names are unique per call (process id, a per-process counter
//! and a random number), so two writers of one folder, in one process or
//! several, never share one: `a.json` and `a.png` get different names, and
//! so do two writers of `a.json`, whose renames then simply race (the last
//! one wins, whole).

use std::hash::{BuildHasher, Hasher};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A failed atomic write, naming the file and the step.
#[derive(Debug, thiserror::Error)]
#[error("cannot {step} {}", path.display())]
pub struct WriteError {
    /// What was being done: "create the folder of", "write", "move into place".
    pub step: &'static str,
    pub path: PathBuf,
    #[source]
    pub source: std::io::Error,
}

impl WriteError {
    fn new(step: &'static str, path: &Path, source: std::io::Error) -> Self {
        WriteError {
            step,
            path: path.to_path_buf(),
            source,
        }
    }
}

/// A sibling of `path` that no other call, in this process or another,
/// returns: `.NAME.PID-COUNTER-RANDOM.tmp`.
pub fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let count = COUNTER.fetch_add(1, Ordering::Relaxed);
    // std's per-instance random hash keys: no dependency, different in every
    // process and every call.
    let random = std::collections::hash_map::RandomState::new()
        .build_hasher()
        .finish();
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(
        ".{name}.{}-{count}-{random:016x}.tmp",
        std::process::id()
    ))
}

/// Writes `bytes` to `path` atomically, creating its folder if needed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    write_atomic_with(path, |tmp| {
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(tmp)
            .map_err(|e| WriteError::new("write", path, e))?;
        file.write_all(bytes)
            .map_err(|e| WriteError::new("write", path, e))
    })
}

/// Writes `path` atomically through `write`, which creates the file at the
/// temporary path it is given (for libraries that save to a path: images,
/// safetensors). The temporary file is removed when `write` fails.
pub fn write_atomic_with<E: From<WriteError>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), E> {
    let dir = parent_dir(path);
    std::fs::create_dir_all(dir).map_err(|e| WriteError::new("create the folder of", path, e))?;
    let tmp = temp_path(path);
    let written = write(&tmp).and_then(|()| {
        sync_file(&tmp).map_err(|e| WriteError::new("write", path, e))?;
        std::fs::rename(&tmp, path).map_err(|e| WriteError::new("move into place", path, e))?;
        Ok(())
    });
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
        return written;
    }
    // The rename is durable once the folder's entry is on disk.
    sync_dir(dir);
    Ok(())
}

/// A file being written in place of `path`: [`AtomicFile::commit`] syncs it
/// and renames it into place; dropped before that, it is removed and `path`
/// is untouched. For output written piece by piece (JSON lines).
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    out: Option<std::io::BufWriter<std::fs::File>>,
}

impl AtomicFile {
    pub fn create(path: &Path) -> Result<AtomicFile, WriteError> {
        std::fs::create_dir_all(parent_dir(path))
            .map_err(|e| WriteError::new("create the folder of", path, e))?;
        let tmp = temp_path(path);
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| WriteError::new("write", path, e))?;
        Ok(AtomicFile {
            path: path.to_path_buf(),
            tmp,
            out: Some(std::io::BufWriter::new(file)),
        })
    }

    /// The destination.
    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn commit(mut self) -> Result<(), WriteError> {
        let out = self.out.take().expect("an AtomicFile is committed once");
        let committed = out
            .into_inner()
            .map_err(|e| e.into_error())
            .and_then(|f| f.sync_all())
            .map_err(|e| WriteError::new("write", &self.path, e))
            .and_then(|()| {
                std::fs::rename(&self.tmp, &self.path)
                    .map_err(|e| WriteError::new("move into place", &self.path, e))
            });
        if committed.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        } else {
            sync_dir(parent_dir(&self.path));
        }
        committed
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.out
            .as_mut()
            .expect("not committed while writing")
            .write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out
            .as_mut()
            .expect("not committed while writing")
            .flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.out.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

fn sync_file(path: &Path) -> std::io::Result<()> {
    std::fs::File::open(path)?.sync_all()
}

/// Best effort: some file systems cannot sync a folder, and the data itself
/// is already safe in the renamed file.
fn sync_dir(dir: &Path) {
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    }

    #[test]
    fn writers_of_one_folder_never_share_a_temp_name() {
        let dir = Path::new("/data/seq");
        // the race of `with_extension("tmp")`: a.json and a.png -> a.tmp
        assert_ne!(
            temp_path(&dir.join("a.json")),
            temp_path(&dir.join("a.png"))
        );
        let names: HashSet<PathBuf> = (0..1000).map(|_| temp_path(&dir.join("a.json"))).collect();
        assert_eq!(names.len(), 1000);
        let tmp = temp_path(&dir.join("a.json"));
        assert_eq!(
            tmp.parent(),
            Some(dir),
            "same folder, so the rename is atomic"
        );
        let name = tmp.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            name.starts_with(".a.json.") && name.ends_with(".tmp"),
            "{name}"
        );
    }

    #[test]
    fn concurrent_writers_of_a_json_and_a_png_each_leave_a_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let json = dir.path().join("a.json");
        let png = dir.path().join("a.png");
        std::thread::scope(|s| {
            for writer in 0..8u8 {
                let (json, png) = (&json, &png);
                s.spawn(move || {
                    for round in 0..50u8 {
                        write_atomic(json, &[writer; 4096]).unwrap();
                        write_atomic(png, &[round; 8192]).unwrap();
                    }
                });
            }
        });
        let a = std::fs::read(&json).unwrap();
        assert_eq!(a.len(), 4096);
        assert!(a.iter().all(|b| *b == a[0]), "bytes of two writers mixed");
        let b = std::fs::read(&png).unwrap();
        assert_eq!(b.len(), 8192);
        assert!(b.iter().all(|x| *x == b[0]), "bytes of two writers mixed");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/model.safetensors");
        write_atomic(&path, b"old").unwrap();
        let err = write_atomic_with(&path, |tmp| -> Result<(), WriteError> {
            std::fs::write(tmp, b"half").unwrap();
            Err(WriteError::new(
                "write",
                tmp,
                std::io::Error::other("disk full"),
            ))
        })
        .unwrap_err();
        assert!(err.to_string().contains("cannot write"), "{err}");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert!(leftovers(&dir.path().join("sub")).is_empty());
    }

    #[test]
    fn an_atomic_file_appears_only_when_committed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("plans.jsonl");
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(b"{}\n").unwrap();
        assert!(!path.exists());
        drop(f);
        assert!(!path.exists() && leftovers(dir.path()).is_empty());
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(b"{}\n").unwrap();
        f.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"{}\n");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn an_unwritable_folder_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("file");
        std::fs::write(&blocker, b"x").unwrap();
        let err = write_atomic(&blocker.join("out.json"), b"{}").unwrap_err();
        assert!(err.to_string().contains("out.json"), "{err}");
    }
}
