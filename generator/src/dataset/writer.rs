//! Writes sequences into the dataset. A sequence is rendered into a private
//! temporary folder, completed with its `sequence.json`, then renamed into
//! place: a killed run never leaves a half sequence, and a finished sequence
//! is exactly a folder holding `sequence.json`.
//!
//! With the egocentric camera on, the head view is rendered into a sibling
//! temporary folder and moved into `Head_d435` first; the wrist folder moves
//! last, so a sequence is finished only when both cameras are complete.

use super::error::{chain, DatasetError, Result};
use super::shard::Shard;
use crate::plan::PlannedKey;
use grasp_schema::dataset::{
    camera_dir, frame_file_name, head_sequence_dir, padding_for, part_file_name, sequence_dir_name,
    ManifestEntry, SequenceRecord, HEAD_CAMERA_FOLDER, MANIFEST_FILE, SEQUENCE_FILE,
    WRIST_CAMERA_FOLDER,
};
use grasp_support::atomic::write_atomic;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Working files of a run (partial sequences, mesh cache, worker logs).
pub const WORK_DIR: &str = ".grasp-gen";

/// A sequence with its final folder.
#[derive(Debug, Clone, PartialEq)]
pub struct Assigned {
    /// Position in the canonical key order (what shards split).
    pub position: usize,
    pub planned: PlannedKey,
    /// Folder relative to the root, `/`-separated.
    pub rel_dir: String,
}

/// Numbers sequences within their `OBJECT/PRESHAPE` folder by their position
/// in the canonical key order. The numbers depend only on the full key list,
/// never on shards or render order, so shards merge and resumed runs agree.
pub fn assign_folders(keys: &[PlannedKey]) -> Vec<Assigned> {
    let mut group_sizes: BTreeMap<(String, &str), u64> = BTreeMap::new();
    for k in keys {
        *group_sizes
            .entry((k.key.object.clone(), k.preshape.authors_folder()))
            .or_default() += 1;
    }
    let mut next: BTreeMap<(String, &str), u64> = BTreeMap::new();
    keys.iter()
        .enumerate()
        .map(|(position, k)| {
            let group = (k.key.object.clone(), k.preshape.authors_folder());
            let padding = padding_for(group_sizes[&group]);
            let n = next.entry(group).or_default();
            let dir = camera_dir(
                Path::new(""),
                &k.category,
                &k.key.object,
                k.preshape,
                WRIST_CAMERA_FOLDER,
            )
            .join(sequence_dir_name(*n, padding));
            *n += 1;
            Assigned {
                position,
                planned: k.clone(),
                rel_dir: to_slash(&dir),
            }
        })
        .collect()
}

fn to_slash(p: &Path) -> String {
    p.components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

/// Frame file names of a sequence with `count` frames.
pub fn frame_files(count: usize) -> Vec<String> {
    let padding = padding_for(count as u64);
    (0..count as u64)
        .map(|i| frame_file_name(i, padding))
        .collect()
}

/// A dataset root being written.
#[derive(Debug, Clone)]
pub struct DatasetDir {
    pub root: PathBuf,
}

impl DatasetDir {
    pub fn create(root: &Path) -> Result<Self> {
        std::fs::create_dir_all(root.join(WORK_DIR).join("partial"))
            .map_err(|e| DatasetError::io("cannot create dataset folder", root, e))?;
        Ok(DatasetDir {
            root: root.to_path_buf(),
        })
    }

    pub fn work_dir(&self) -> PathBuf {
        self.root.join(WORK_DIR)
    }

    /// Whether the sequence's final folder is complete: its `sequence.json`
    /// exists and, when its plan has a head camera, so does the head
    /// folder's.
    pub fn is_finished(&self, rel_dir: &str) -> bool {
        let record = self.root.join(rel_dir).join(SEQUENCE_FILE);
        if !record.is_file() {
            return false;
        }
        let head = head_sequence_dir(rel_dir).map(|h| self.root.join(h).join(SEQUENCE_FILE));
        if head.as_ref().is_some_and(|h| h.is_file()) {
            return true;
        }
        // No head record: finished only if the plan has no head camera.
        read_record(&record).is_ok_and(|r| !r.has_head_camera())
    }

    /// The head camera's temporary folder of a partial sequence folder.
    pub fn partial_head_dir(partial: &Path) -> PathBuf {
        let mut name = partial.file_name().unwrap_or_default().to_os_string();
        name.push(".head");
        partial.with_file_name(name)
    }

    /// A fresh temporary folder for one attempt at a sequence.
    pub fn partial_dir(&self, position: usize, attempt: u32) -> Result<PathBuf> {
        let dir = self
            .work_dir()
            .join("partial")
            .join(format!("{position:08}-{attempt}-{}", std::process::id()));
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(|e| DatasetError::io("cannot clear", &dir, e))?;
        }
        std::fs::create_dir_all(&dir).map_err(|e| DatasetError::io("cannot create", &dir, e))?;
        Ok(dir)
    }

    /// Removes the partial sequences of `shard` left by a killed run (the
    /// caller holds its lock). Other shards writing into the same folder
    /// keep theirs: a partial folder's name starts with its position.
    pub fn clean_partials(&self, shard: Shard) -> Result<()> {
        let dir = self.work_dir().join("partial");
        std::fs::create_dir_all(&dir).map_err(|e| DatasetError::io("cannot create", &dir, e))?;
        let cannot_read = |e| DatasetError::io("cannot read", &dir, e);
        for entry in std::fs::read_dir(&dir).map_err(cannot_read)? {
            let path = entry.map_err(cannot_read)?.path();
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            let position = name.split('-').next().and_then(|p| p.parse::<usize>().ok());
            if shard == Shard::ALL || position.is_some_and(|p| shard.contains(p)) {
                let removed = if path.is_dir() {
                    std::fs::remove_dir_all(&path)
                } else {
                    std::fs::remove_file(&path)
                };
                removed.map_err(|e| DatasetError::io("cannot clear", &path, e))?;
            }
        }
        Ok(())
    }

    /// Whether a finished sequence's files are all there and whole (the
    /// integrity check of [`super::integrity`], no decoding): the reason
    /// when not. `--resume` re-renders such sequences.
    pub fn check_finished(&self, rel_dir: &str) -> std::result::Result<(), String> {
        let record_path = self.root.join(rel_dir).join(SEQUENCE_FILE);
        let record = read_record(&record_path).map_err(|e| chain(&e))?;
        let mut dirs = vec![rel_dir.to_string()];
        if record.has_head_camera() {
            let head = head_sequence_dir(rel_dir)
                .ok_or_else(|| format!("{rel_dir}: head camera poses outside Wrist_d435"))?;
            let head_record = self.root.join(&head).join(SEQUENCE_FILE);
            super::integrity::check_json(&head_record)
                .map_err(|e| format!("{}: {e}", head_record.display()))?;
            dirs.push(head);
        }
        for dir in dirs {
            for name in output_files(&record) {
                let path = self.root.join(&dir).join(&name);
                super::integrity::check_image(&path, false)
                    .map_err(|e| format!("{}: {e}", path.display()))?;
            }
        }
        Ok(())
    }

    /// Completes a rendered sequence: checks its frames, writes
    /// `sequence.json`, renames the folder into place and appends the
    /// manifest line.
    /// With a head camera, its folder [`Self::partial_head_dir`] is
    /// completed and moved first.
    pub fn finish(&self, partial: &Path, rel_dir: &str, record: &SequenceRecord) -> Result<()> {
        let json = serde_json::to_vec_pretty(record).map_err(|source| DatasetError::Serialise {
            what: "a sequence record",
            source,
        })?;
        if record.has_head_camera() {
            let head_rel =
                head_sequence_dir(rel_dir).ok_or_else(|| DatasetError::NoHeadFolder {
                    rel: rel_dir.to_string(),
                    reason: format!("no {WRIST_CAMERA_FOLDER} component for the head camera"),
                })?;
            let head_partial = Self::partial_head_dir(partial);
            check_frames(&head_partial, record)?;
            self.move_into_place(&head_partial, &head_rel, &json)?;
        }
        check_frames(partial, record)?;
        self.move_into_place(partial, rel_dir, &json)?;
        self.append_manifest(&manifest_entry(rel_dir, record))
    }

    /// Writes `sequence.json` into a completed folder and renames it into place.
    fn move_into_place(&self, partial: &Path, rel_dir: &str, json: &[u8]) -> Result<()> {
        std::fs::write(partial.join(SEQUENCE_FILE), json)
            .map_err(|e| DatasetError::io("cannot write", partial, e))?;
        let target = self.root.join(rel_dir);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent)
                .map_err(|e| DatasetError::io("cannot create", parent, e))?;
        }
        if target.exists() {
            // Unfinished leftovers only: finished sequences are skipped.
            std::fs::remove_dir_all(&target)
                .map_err(|e| DatasetError::io("cannot replace", &target, e))?;
        }
        std::fs::rename(partial, &target).map_err(|source| DatasetError::Move {
            from: partial.to_path_buf(),
            to: target.clone(),
            source,
        })
    }

    fn append_manifest(&self, entry: &ManifestEntry) -> Result<()> {
        let path = self.root.join(MANIFEST_FILE);
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(|e| DatasetError::io("cannot open", &path, e))?;
        let mut line = serde_json::to_string(entry).map_err(|source| DatasetError::Serialise {
            what: "a manifest entry",
            source,
        })?;
        line.push('\n');
        f.write_all(line.as_bytes())
            .map_err(|e| DatasetError::io("cannot append to", &path, e))
    }

    /// Rewrites `manifest.jsonl` from the finished sequence folders, sorted
    /// by path, so it is identical however the sequences were produced.
    pub fn rebuild_manifest(&self) -> Result<usize> {
        let mut text = String::new();
        let mut count = 0;
        visit_sequences(&self.root, false, |rel, record| {
            let entry = manifest_entry(rel, &record?);
            let line = serde_json::to_string(&entry).map_err(|source| DatasetError::Serialise {
                what: "a manifest entry",
                source,
            })?;
            text.push_str(&line);
            text.push('\n');
            count += 1;
            Ok(())
        })?;
        write_atomic(&self.root.join(MANIFEST_FILE), text.as_bytes())?;
        Ok(count)
    }
}

/// Every file of `record` in `dir` passes the integrity check (whole PNGs
/// and EXRs). When one does not, a probe write tells whether the disk is
/// full, and that OS error is what the failure reports.
fn check_frames(dir: &Path, record: &SequenceRecord) -> Result<()> {
    for name in output_files(record) {
        let f = dir.join(&name);
        if let Err(damage) = super::integrity::check_image(&f, false) {
            return Err(DatasetError::BadFrame {
                sequence: record.plan.key.id(),
                path: f,
                damage: damage.to_string(),
                full: super::storage::probe(dir),
            });
        }
    }
    Ok(())
}

/// The files a sequence folder must hold besides `sequence.json`: the
/// frames, the part label images when the record has part labels, and the
/// EXRs when the depth or instance pass was rendered.
pub fn output_files(record: &SequenceRecord) -> Vec<String> {
    let mut files = record.frame_files.clone();
    if record.part_labels().is_some() {
        files.extend(record.frame_files.iter().map(|f| part_file_name(f)));
    }
    if keeps_exr(record) {
        files.extend(record.frame_files.iter().map(|f| {
            Path::new(f)
                .with_extension("exr")
                .to_string_lossy()
                .into_owned()
        }));
    }
    files
}

/// Whether the record's passes leave an EXR next to each frame.
fn keeps_exr(record: &SequenceRecord) -> bool {
    record.render["passes"]
        .as_array()
        .is_some_and(|p| p.iter().any(|p| p == "depth" || p == "instance"))
}

pub fn manifest_entry(rel_dir: &str, record: &SequenceRecord) -> ManifestEntry {
    let plan = &record.plan;
    ManifestEntry {
        id: plan.key.id(),
        path: rel_dir.to_string(),
        object: plan.key.object.clone(),
        part: plan.key.part.clone(),
        grasp_type: plan.grasp_type,
        preshape: plan.preshape,
        condition: plan.key.condition,
        frames: plan.frames.len(),
    }
}

/// Every finished sequence under `root` (folders holding `sequence.json`,
/// outside the work folder and the head camera's folders), by relative
/// path. This holds every record in memory: commands that go through a
/// whole dataset use [`sequence_dirs`] and [`visit_sequences`] instead.
pub fn find_sequences(root: &Path) -> Result<BTreeMap<String, SequenceRecord>> {
    let mut out = BTreeMap::new();
    visit_sequences(root, false, |rel, record| {
        out.insert(rel.to_string(), record?);
        Ok(())
    })?;
    Ok(out)
}

/// The head camera's sequence folders under `root` (holding `sequence.json`).
pub fn find_head_sequences(root: &Path) -> Result<BTreeMap<String, SequenceRecord>> {
    let mut out = BTreeMap::new();
    visit_sequences(root, true, |rel, record| {
        out.insert(rel.to_string(), record?);
        Ok(())
    })?;
    Ok(out)
}

/// Calls `visit` with every sequence folder under `root` (wrist folders, or
/// the head camera's with `head`), in path order, and its record or the
/// error reading it. One record is in memory at a time.
pub fn visit_sequences(
    root: &Path,
    head: bool,
    mut visit: impl FnMut(&str, Result<SequenceRecord>) -> Result<()>,
) -> Result<()> {
    for rel in sequence_dirs(root, head)? {
        let record = read_record(&root.join(&rel).join(SEQUENCE_FILE));
        visit(&rel, record)?;
    }
    Ok(())
}

/// The sequence folders under `root` (relative, `/`-separated, sorted):
/// folders holding `sequence.json`, outside hidden folders, in a head
/// camera folder or not as `head` says. Nothing is parsed.
pub fn sequence_dirs(root: &Path, head: bool) -> Result<Vec<String>> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    // Each folder once, by its real path: a symlink to a folder above it
    // (a loop) is not followed round and round.
    let mut seen = std::collections::HashSet::new();
    while let Some(dir) = stack.pop() {
        if !seen.insert(dir.canonicalize().unwrap_or_else(|_| dir.clone())) {
            tracing::warn!(
                "{}: a folder already listed (a symlink loop?): not read again",
                dir.display()
            );
            continue;
        }
        let cannot_read = |e| DatasetError::io("cannot read", &dir, e);
        let entries = std::fs::read_dir(&dir).map_err(cannot_read)?;
        for entry in entries {
            let path = entry.map_err(cannot_read)?.path();
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            if name.starts_with('.') {
                continue;
            }
            if path.is_dir() {
                stack.push(path);
            } else if name == SEQUENCE_FILE && in_head_folder(&path) == head {
                let rel = path
                    .parent()
                    .and_then(|p| p.strip_prefix(root).ok())
                    .map(to_slash)
                    .unwrap_or_default();
                out.push(rel);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// Whether a `sequence.json` lies in a `Head_d435/rgbNNNNN` folder.
fn in_head_folder(record: &Path) -> bool {
    record
        .parent()
        .and_then(Path::parent)
        .and_then(Path::file_name)
        .is_some_and(|n| n == HEAD_CAMERA_FOLDER)
}

pub fn read_record(path: &Path) -> Result<SequenceRecord> {
    let text =
        std::fs::read_to_string(path).map_err(|e| DatasetError::io("cannot read", path, e))?;
    serde_json::from_str(&text).map_err(|source| DatasetError::Record {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_symlink_loop_is_listed_once() {
        // Issue 60's note: `dataset verify` followed a loop 40 levels deep.
        let dir = tempfile::tempdir().unwrap();
        let seq = dir.path().join("can/010_can/power_no3/Wrist_d435/rgb00000");
        std::fs::create_dir_all(&seq).unwrap();
        std::fs::write(seq.join(SEQUENCE_FILE), "{}").unwrap();
        std::os::unix::fs::symlink(dir.path(), dir.path().join("can/loop")).unwrap();
        let found = sequence_dirs(dir.path(), false).unwrap();
        assert_eq!(found.len(), 1, "{found:?}");
    }

    use super::*;
    use grasp_schema::taxonomy::Preshape;
    use grasp_schema::{Condition, SequenceKey};

    fn key(object: &str, part: &str, index: u32, preshape: Preshape) -> PlannedKey {
        PlannedKey {
            key: SequenceKey {
                object: object.into(),
                part: part.into(),
                index,
                condition: Condition::Default,
            },
            category: "mug".into(),
            preshape,
        }
    }

    #[test]
    fn folders_are_numbered_per_object_and_preshape_in_key_order() {
        let keys = vec![
            key("025_mug", "handle", 0, Preshape::Pinch3),
            key("025_mug", "body", 0, Preshape::Power),
            key("025_mug", "handle", 1, Preshape::Pinch3),
            key("025_mug", "rim", 0, Preshape::Pinch3),
        ];
        let a = assign_folders(&keys);
        let dirs: Vec<&str> = a.iter().map(|a| a.rel_dir.as_str()).collect();
        assert_eq!(
            dirs,
            [
                "mug/025_mug/pinch_3/Wrist_d435/rgb00000",
                "mug/025_mug/power_no3/Wrist_d435/rgb00000",
                "mug/025_mug/pinch_3/Wrist_d435/rgb00001",
                "mug/025_mug/pinch_3/Wrist_d435/rgb00002",
            ]
        );
        // A subset (a shard) keeps the numbers of the full list.
        assert_eq!(a[3].position, 3);
    }

    #[test]
    fn numbers_widen_instead_of_overflowing() {
        let keys: Vec<_> = (0..100_001)
            .map(|i| key("o", "p", i, Preshape::Power))
            .collect();
        let a = assign_folders(&keys);
        assert!(a[0].rel_dir.ends_with("rgb000000"));
        assert!(a[100_000].rel_dir.ends_with("rgb100000"));
        assert_eq!(frame_files(3), ["00000.png", "00001.png", "00002.png"]);
        assert_eq!(frame_files(100_001)[100_000], "100000.png");
    }
}
