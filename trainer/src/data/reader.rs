//! Reads `ROOT/CATEGORY/OBJECT/PRESHAPE_FOLDER/CAMERA/rgbNNNNN/*.png`.
//!
//! A sequence folder with a `sequence.json` (the generator's) takes its
//! per-frame labels from it. Without one (the authors' real data) the labels
//! come from the pre-shape folder, with the last `no_grasp_tail_s` seconds
//! (0.5 s in the paper) labelled `no_grasp`. When `ROOT/manifest.jsonl` exists
//! the root is a generated dataset, and a sequence without `sequence.json` is
//! a missing-labels problem instead.

use super::{BadData, Dataset, LabelSource, Sequence};
use crate::error::DataError;
use grasp_model::input::{Crop, Lens};
use grasp_schema::dataset::{SequenceRecord, MANIFEST_FILE, SEQUENCE_FILE, WRIST_CAMERA_FOLDER};
use grasp_schema::taxonomy::{Class, Preshape};
use serde::{Deserialize, Serialize};
use std::fs;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReaderOptions {
    /// Camera folder to read (`Wrist_d435`, or `Head_d435` for egocentric).
    pub camera: String,
    /// Frame rate of the authors' real data (it has no metadata).
    pub real_fps: f64,
    /// Length of the final `no_grasp` segment of real data, in seconds.
    pub no_grasp_tail_s: f64,
    /// The centre crop the backbone sees (the model's input record): a
    /// fixed angle is cut through the lens each `sequence.json` records,
    /// else through `lens`.
    pub crop: Crop,
    /// Remove the sensor noise of the backbone's input square (non-local
    /// means at the level estimated in it) before the backbone.
    pub denoise: bool,
    /// The camera of data without `sequence.json` (the authors' layout, a
    /// user's recordings), which a fixed-angle crop needs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lens: Option<Lens>,
}

impl Default for ReaderOptions {
    fn default() -> Self {
        ReaderOptions {
            camera: WRIST_CAMERA_FOLDER.to_string(),
            real_fps: 30.0,
            no_grasp_tail_s: 0.5,
            crop: Crop::Whole,
            denoise: false,
            lens: None,
        }
    }
}

/// Each sequence folder `manifest.jsonl` lists for `camera` exists: one
/// that is gone is a problem (`bad`), not a silently smaller dataset.
fn check_manifest_folders(root: &Path, camera: &str, bad: &BadData) -> Result<(), DataError> {
    let manifest = root.join(MANIFEST_FILE);
    let Ok(text) = fs::read_to_string(&manifest) else {
        return bad.report(&manifest, "cannot be read");
    };
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let entry: Option<serde_json::Value> = serde_json::from_str(line).ok();
        let Some(path) = entry.as_ref().and_then(|e| e["path"].as_str()) else {
            bad.report(&manifest, format!("a line without a sequence path: {line}"))?;
            continue;
        };
        if !path.split('/').any(|c| c == camera) {
            continue;
        }
        let dir = root.join(path);
        if !dir.is_dir() {
            bad.report(
                &dir,
                format!("listed in {MANIFEST_FILE} but missing: the sequence is not read"),
            )?;
        }
    }
    Ok(())
}

impl ReaderOptions {
    /// `real_fps` finite and positive (at most 10000), `no_grasp_tail_s`
    /// finite and not negative: checked before any data is read.
    pub fn validate_numbers(&self) -> Result<(), crate::error::ConfigError> {
        let fps = self.real_fps;
        if !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0) {
            return Err(crate::error::ConfigError::invalid(
                "reader.real_fps",
                format!(
                    "reader.real_fps (--real-fps) must be a frame rate in (0, 10000], got {fps}"
                ),
            ));
        }
        let tail = self.no_grasp_tail_s;
        if !(tail.is_finite() && tail >= 0.0) {
            return Err(crate::error::ConfigError::invalid(
                "reader.no_grasp_tail_s",
                format!(
                    "reader.no_grasp_tail_s must be 0 or a positive number of seconds, got {tail}"
                ),
            ));
        }
        Ok(())
    }
}

/// Reads every sequence under `root`. Problems (unparseable or missing labels,
/// missing frames) go through `bad`; a root that cannot be listed is an error.
pub fn read_dataset(
    root: &Path,
    opts: &ReaderOptions,
    bad: &BadData,
) -> Result<Dataset, DataError> {
    opts.validate()?;
    let generated = root.join(MANIFEST_FILE).is_file();
    let narrow_lens = std::cell::Cell::new(0);
    let mut sequences = Vec::new();
    for category in subdirs(root)? {
        for object in subdirs(&category)? {
            for preshape_dir in subdirs(&object)? {
                let folder = file_name(&preshape_dir);
                let Some(preshape) = Preshape::from_authors_folder(&folder) else {
                    bad.report(
                        &preshape_dir,
                        format!(
                            "'{folder}' is not a pre-shape folder (expected one of: {})",
                            Preshape::ALL.map(|p| p.authors_folder()).join(", ")
                        ),
                    )?;
                    continue;
                };
                let camera = preshape_dir.join(&opts.camera);
                if !camera.is_dir() {
                    continue;
                }
                let ctx = FolderContext {
                    root,
                    narrow_lens: &narrow_lens,
                    category: file_name(&category),
                    object: file_name(&object),
                    preshape,
                    generated,
                };
                for dir in subdirs(&camera)? {
                    if !file_name(&dir).starts_with("rgb") {
                        continue;
                    }
                    if let Some(seq) = read_sequence(&dir, &ctx, opts, bad)? {
                        sequences.push(seq);
                    }
                }
            }
        }
    }
    if generated {
        check_manifest_folders(root, &opts.camera, bad)?;
    }
    if narrow_lens.get() > 0 {
        tracing::warn!(
            "{}: {} sequence(s) were rendered through a lens too narrow (or a centre too small) \
             for the crop of {}; they are cropped to all that was rendered, so the head \
             sees their parts larger than in training",
            root.display(),
            narrow_lens.get(),
            opts.crop.describe()
        );
    }
    Ok(Dataset {
        root: root.to_path_buf(),
        sequences,
    })
}

impl ReaderOptions {
    /// The input record's one validation of the crop (and of the lens).
    pub fn validate(&self) -> Result<(), grasp_model::input::InputError> {
        self.crop.validate()
    }

    /// The crop of a frame of `record`'s camera, rendered in its central
    /// `region`, through the lens it records: a fraction of the shorter
    /// side, and whether a lens too narrow for a fixed angle had it cut
    /// down to what was rendered (the head then sees the part a little
    /// larger than in training, instead of the black surround).
    fn crop_for(
        &self,
        lens: Option<&Lens>,
        record: &SequenceRecord,
        region: f64,
    ) -> Result<(Option<f64>, bool), grasp_model::input::InputError> {
        let k = &record.plan.intrinsics;
        let fraction = self.crop.fraction(lens, k.width, k.height)?;
        Ok(match (self.crop, fraction) {
            (Crop::AngleDeg(_), Some(f)) => (Some(f.min(region)), f > region + 1e-9),
            (_, f) => (f, false),
        })
    }

    /// The lens of a generated sequence: its `plan.intrinsics`. A fixed
    /// angle needs it valid; other crops do without.
    fn record_lens(&self, record: &SequenceRecord) -> Result<Option<Lens>, String> {
        match Lens::from_intrinsics(&record.plan.intrinsics) {
            Ok(lens) => Ok(Some(lens)),
            Err(e) if matches!(self.crop, Crop::AngleDeg(_)) => Err(e.to_string()),
            Err(_) => Ok(None),
        }
    }
}

struct FolderContext<'a> {
    root: &'a Path,
    /// Sequences whose lens was too narrow for the crop angle (cut down).
    narrow_lens: &'a std::cell::Cell<usize>,
    category: String,
    object: String,
    preshape: Preshape,
    generated: bool,
}

fn read_sequence(
    dir: &Path,
    ctx: &FolderContext,
    opts: &ReaderOptions,
    bad: &BadData,
) -> Result<Option<Sequence>, DataError> {
    let json = dir.join(SEQUENCE_FILE);
    let seq = if json.is_file() {
        match read_record(&json) {
            Ok(record) => match record.center_region() {
                Some(region) => {
                    let at_json = |reason: String| DataError::Invalid {
                        path: json.clone(),
                        reason,
                    };
                    let lens = opts.record_lens(&record).map_err(at_json)?;
                    let (crop, cut) = opts
                        .crop_for(lens.as_ref(), &record, region)
                        .map_err(|e| at_json(e.to_string()))?;
                    if cut {
                        ctx.narrow_lens.set(ctx.narrow_lens.get() + 1);
                    }
                    check_center_region(&json, region, crop)?;
                    from_record(dir, ctx, &record, region, lens, opts)
                }
                None => {
                    bad.report(&json, "render.center_region must be a fraction in (0, 1]")?;
                    return Ok(None);
                }
            },
            Err(reason) => {
                bad.report(&json, reason)?;
                return Ok(None);
            }
        }
    } else if ctx.generated {
        bad.report(
            &json,
            "missing labels: no sequence.json in a generated dataset",
        )?;
        return Ok(None);
    } else {
        from_folder(dir, ctx, opts)?
    };
    check_frames(seq, bad)
}

/// Frames rendered only in their centre (`[render] center_region`) are
/// black outside it, so a model must not look further out than that.
fn check_center_region(json: &Path, region: f64, crop: Option<f64>) -> Result<(), DataError> {
    match grasp_schema::dataset::crop_outside_region(region, crop) {
        Some(reason) => Err(DataError::Invalid {
            path: json.to_path_buf(),
            reason,
        }),
        None => Ok(()),
    }
}

/// A `sequence.json`, or why it is bad data (the reason a report gives
/// after the file's path).
fn read_record(path: &Path) -> Result<SequenceRecord, String> {
    let text = fs::read_to_string(path).map_err(|e| format!("cannot read: {e}"))?;
    let record: SequenceRecord =
        serde_json::from_str(&text).map_err(|e| format!("invalid sequence.json: {e}"))?;
    if record.frame_files.len() != record.plan.frames.len() {
        return Err(format!(
            "frame_files has {} entries but plan.frames has {}",
            record.frame_files.len(),
            record.plan.frames.len()
        ));
    }
    Ok(record)
}

fn from_record(
    dir: &Path,
    ctx: &FolderContext,
    record: &SequenceRecord,
    region: f64,
    lens: Option<Lens>,
    opts: &ReaderOptions,
) -> Sequence {
    let plan = &record.plan;
    Sequence {
        id: relative_id(ctx.root, dir),
        dir: dir.to_path_buf(),
        category: ctx.category.clone(),
        object: plan.key.object.clone(),
        part: Some(plan.key.part.clone()),
        preshape: plan.preshape,
        condition: plan.key.condition.name().to_string(),
        fps: plan.fps,
        frames: record.frame_files.iter().map(|f| dir.join(f)).collect(),
        labels: plan.labels(),
        label_source: LabelSource::SequenceJson,
        crop: opts.crop,
        lens,
        lead_in: plan.lead_in_frames(),
        first_frame: 0,
        rendered_region: (region < 1.0).then_some(region),
        denoise: opts.denoise,
        test_world: record.test_world(),
        view: None,
        probe: None,
        style: None,
    }
}

fn from_folder(
    dir: &Path,
    ctx: &FolderContext,
    opts: &ReaderOptions,
) -> Result<Sequence, DataError> {
    if let (Crop::AngleDeg(angle), None) = (opts.crop, opts.lens) {
        return Err(DataError::Invalid {
            path: dir.to_path_buf(),
            reason: format!(
                "the model crops a fixed angle of {angle} degrees, which needs the camera's \
                 focal length, and these frames have no sequence.json: give the camera's lens \
                 (--focal-px with --lens-size, --hfov-deg, or --lens-file)"
            ),
        });
    }
    let mut frames: Vec<PathBuf> = list(dir)?.filter(|p| is_image(p)).collect();
    frames.sort();
    Ok(Sequence {
        id: relative_id(ctx.root, dir),
        dir: dir.to_path_buf(),
        category: ctx.category.clone(),
        object: ctx.object.clone(),
        part: None,
        preshape: ctx.preshape,
        condition: "real".to_string(),
        fps: opts.real_fps,
        labels: folder_labels(frames.len(), ctx.preshape, opts),
        frames,
        label_source: LabelSource::PreshapeFolder,
        crop: opts.crop,
        lens: opts.lens,
        lead_in: 0,
        first_frame: 0,
        rendered_region: None,
        denoise: opts.denoise,
        test_world: None,
        view: None,
        probe: None,
        style: None,
    })
}

/// The authors' labelling: the pre-shape, then `no_grasp` for the last
/// `no_grasp_tail_s` seconds (rounded to whole frames).
pub fn folder_labels(n: usize, preshape: Preshape, opts: &ReaderOptions) -> Vec<Class> {
    let tail = ((opts.no_grasp_tail_s * opts.real_fps).round() as usize).min(n);
    (0..n)
        .map(|i| {
            if i >= n - tail {
                Class::NoGrasp
            } else {
                Class::from(preshape)
            }
        })
        .collect()
}

/// Drops (or fails on) frames whose file is missing, and empty sequences.
fn check_frames(mut seq: Sequence, bad: &BadData) -> Result<Option<Sequence>, DataError> {
    let mut keep = Vec::with_capacity(seq.frames.len());
    for f in &seq.frames {
        let ok = f.is_file();
        if !ok {
            bad.report(f, "frame file is missing")?;
        }
        keep.push(ok);
    }
    if keep.iter().any(|k| !k) {
        seq.lead_in = keep.iter().take(seq.lead_in).filter(|k| **k).count();
        let mut k = keep.iter();
        seq.frames.retain(|_| *k.next().unwrap_or(&false));
        let mut k = keep.iter();
        seq.labels.retain(|_| *k.next().unwrap_or(&false));
    }
    if seq.frames.is_empty() {
        bad.report(&seq.dir, "sequence has no frames")?;
        return Ok(None);
    }
    Ok(Some(seq))
}

fn is_image(p: &Path) -> bool {
    matches!(
        p.extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref(),
        Some("png" | "jpg" | "jpeg")
    )
}

/// The visible sub-folders of `dir`, sorted. Hidden ones are bookkeeping,
/// never data: the generator's `.grasp-gen/` holds the partial sequences
/// of an unfinished render, its mesh cache, logs and locks.
fn subdirs(dir: &Path) -> Result<Vec<PathBuf>, DataError> {
    let mut out: Vec<PathBuf> = list(dir)?
        .filter(|p| p.is_dir() && !file_name(p).starts_with('.'))
        .collect();
    out.sort();
    Ok(out)
}

/// The entries of `dir` (unreadable entries left out).
fn list(dir: &Path) -> Result<impl Iterator<Item = PathBuf>, DataError> {
    let entries = fs::read_dir(dir).map_err(|source| DataError::List {
        path: dir.to_path_buf(),
        source,
    })?;
    Ok(entries.filter_map(|e| e.ok().map(|e| e.path())))
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn relative_id(root: &Path, dir: &Path) -> String {
    let rel = dir.strip_prefix(root).unwrap_or(dir);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::bad::OnBadData;
    use crate::data::synthetic::{write_synthetic, Layout, SyntheticSpec};

    #[test]
    fn a_root_that_cannot_be_listed_is_named() {
        let root = Path::new("no/such/dataset");
        let err = read_dataset(root, &ReaderOptions::default(), &BadData::default()).unwrap_err();
        assert!(
            matches!(&err, DataError::List { path, .. } if path == root),
            "{err:?}"
        );
        assert_eq!(err.to_string(), "cannot list no/such/dataset");
    }

    #[test]
    fn last_half_second_is_no_grasp() {
        let opts = ReaderOptions::default();
        let labels = folder_labels(90, Preshape::Pinch, &opts);
        assert_eq!(labels.iter().filter(|c| **c == Class::NoGrasp).count(), 15);
        assert_eq!(labels[74], Class::Pinch);
        assert_eq!(labels[75], Class::NoGrasp);
        assert_eq!(
            folder_labels(3, Preshape::Power, &opts),
            vec![Class::NoGrasp; 3]
        );
    }

    #[test]
    fn pooled_draws_keep_every_sequence_under_its_own_id() {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec::small(Layout::Generated);
        let bad = BadData::new(OnBadData::Fail);
        let read = |name: &str| {
            let root = dir.path().join(name);
            write_synthetic(&root, &spec).unwrap();
            read_dataset(&root, &ReaderOptions::default(), &bad).unwrap()
        };
        let (a, b) = (read("draw-a"), read("draw-b"));
        let n = a.sequences.len();
        assert!(n > 0);
        // Two draws of one spec share their relative ids.
        assert_eq!(a.sequences[0].id, b.sequences[0].id);

        let pooled = Dataset::pool(vec![a.clone(), b]);
        assert_eq!(pooled.sequences.len(), 2 * n);
        assert_eq!(pooled.root, a.root);
        let ids: std::collections::BTreeSet<&str> =
            pooled.sequences.iter().map(|s| s.id.as_str()).collect();
        assert_eq!(ids.len(), 2 * n, "ids collide");
        assert!(pooled.sequences[n].id.contains("draw-b"));

        // One draw is returned as it is.
        assert_eq!(Dataset::pool(vec![a.clone()]).sequences, a.sequences);
    }
}
