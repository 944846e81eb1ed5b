//! `grasp-gen dataset verify`: checks a finished dataset. It counts sequences
//! per (object, part) pair and condition, finds missing, cut-short or
//! corrupt files (every PNG's chunks and CRCs, every EXR's chunks; a full
//! decode with `decode`), checks the manifest against the sequence folders,
//! checks the head camera's folder of every sequence whose plan has head
//! poses, and, given the plan source, checks that every configured sequence
//! (of the shard) is there and each record against a fresh re-plan and its
//! folder.

use super::error::{chain, DatasetError, Result};
use super::integrity::check_image;
use super::shard::Shard;
use super::writer::{
    manifest_entry, output_files, read_record, sequence_dirs, visit_sequences, WORK_DIR,
};
use super::{assign_folders, Assigned};
use crate::plan::PlanSource;
use crate::render::RenderConfig;
use grasp_schema::dataset::{
    head_sequence_dir, ManifestEntry, SequenceRecord, MANIFEST_FILE, SEQUENCE_FILE,
};
use grasp_schema::Condition;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::Path;

#[derive(Debug, Default)]
pub struct VerifyReport {
    pub sequences: usize,
    pub frames: usize,
    /// Head camera (`Head_d435`) sequences and frames checked.
    pub head_sequences: usize,
    pub head_frames: usize,
    /// Sequences per `object/part` pair and condition.
    pub counts: BTreeMap<String, BTreeMap<Condition, usize>>,
    /// Everything wrong, one line each, naming the file.
    pub problems: Vec<String>,
    /// Frames and measured render cost (see `dataset stats`).
    pub stats: super::stats::DatasetStats,
}

impl VerifyReport {
    pub fn ok(&self) -> bool {
        self.problems.is_empty()
    }

    /// The counts table and the problems, for the terminal.
    pub fn render_text(&self) -> String {
        let conditions: BTreeSet<Condition> = self
            .counts
            .values()
            .flat_map(|c| c.keys().copied())
            .collect();
        let mut s = format!("{:<40}", "object/part");
        for c in &conditions {
            let _ = write!(s, "{:>12}", c.name());
        }
        s.push('\n');
        for (pair, per) in &self.counts {
            let _ = write!(s, "{pair:<40}");
            for c in &conditions {
                let _ = write!(s, "{:>12}", per.get(c).copied().unwrap_or(0));
            }
            s.push('\n');
        }
        let _ = writeln!(
            s,
            "{} pairs, {} sequences, {} frames",
            self.counts.len(),
            self.sequences,
            self.frames
        );
        for (camera, c) in &self.stats.cameras {
            let _ = writeln!(
                s,
                "render cost {camera}: {:.4} s per frame over {} frames",
                c.seconds_per_frame, c.frames
            );
        }
        if self.head_sequences > 0 {
            let _ = writeln!(
                s,
                "head camera: {} sequences, {} frames",
                self.head_sequences, self.head_frames
            );
        }
        for p in &self.problems {
            let _ = writeln!(s, "PROBLEM: {p}");
        }
        s
    }
}

/// Missing sequences listed one by one before the rest are only counted.
const LISTED_MISSING: usize = 20;

/// Verifies the whole dataset at `root`. With `source`, every configured
/// sequence must be there, and every record must equal a fresh plan and sit
/// in the folder the key order gives it. `decode` decodes every image fully
/// (slower) on top of the integrity check of its file structure.
pub fn verify(root: &Path, source: Option<&dyn PlanSource>, decode: bool) -> Result<VerifyReport> {
    verify_shard(root, source, decode, Shard::ALL)
}

/// [`verify`] for the output of one `render --shard`: only the shard's
/// sequences are expected.
pub fn verify_shard(
    root: &Path,
    source: Option<&dyn PlanSource>,
    decode: bool,
    shard: Shard,
) -> Result<VerifyReport> {
    verify_against(root, source, None, decode, shard)
}

/// [`verify_shard`] against a whole config (`dataset verify --config`):
/// also every record's render settings against the config's `[render]`
/// ([`crate::render::consistency`]), so a dataset resumed with another
/// `center_region` or sample count is reported.
pub fn verify_config(
    root: &Path,
    source: &dyn PlanSource,
    render: &RenderConfig,
    decode: bool,
    shard: Shard,
) -> Result<VerifyReport> {
    verify_against(root, Some(source), Some(render), decode, shard)
}

fn verify_against(
    root: &Path,
    source: Option<&dyn PlanSource>,
    render: Option<&RenderConfig>,
    decode: bool,
    shard: Shard,
) -> Result<VerifyReport> {
    let scan_error = |e| DatasetError::Scan {
        root: root.to_path_buf(),
        source: Box::new(e),
    };
    // Folder lists only: records are read and checked one at a time, so a
    // dataset of any size verifies in little memory.
    let dirs = sequence_dirs(root, false).map_err(scan_error)?;
    let head_dirs: BTreeSet<String> = sequence_dirs(root, true)
        .map_err(scan_error)?
        .into_iter()
        .collect();
    let mut report = VerifyReport::default();
    let mut listed = read_manifest(root, &mut report);
    let assigned = match source {
        Some(s) => Some(assign_folders(&s.keys()?)),
        None => None,
    };
    let expected_dirs: Option<BTreeMap<String, String>> = assigned.as_ref().map(|a| {
        a.iter()
            .map(|a| (a.planned.key.id(), a.rel_dir.clone()))
            .collect()
    });
    let mut ids = BTreeSet::new();
    let mut present = BTreeSet::new();
    let mut expected_heads = BTreeSet::new();
    let mut other_render = OtherRender::default();
    visit_sequences(root, false, |rel, record| {
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                report.problems.push(format!("{rel}: {}", chain(&e)));
                return Ok(());
            }
        };
        present.insert(rel.to_string());
        check_listed(rel, &record, listed.as_mut(), &mut report);
        if let Some(h) = check_head_folder(root, rel, &record, &head_dirs, decode, &mut report) {
            expected_heads.insert(h);
        }
        report.stats.add(&record);
        let plan = &record.plan;
        report.sequences += 1;
        report.frames += record.frame_files.len();
        *report
            .counts
            .entry(format!("{}/{}", plan.key.object, plan.key.part))
            .or_default()
            .entry(plan.key.condition)
            .or_default() += 1;
        if !ids.insert(plan.key.id()) {
            report
                .problems
                .push(format!("{rel}: sequence {} appears twice", plan.key.id()));
        }
        check_frames(root, rel, &record, decode, &mut report);
        let prefix = format!(
            "{}/{}/{}/",
            plan.category,
            plan.key.object,
            plan.preshape.authors_folder()
        );
        if !rel.starts_with(&prefix) {
            report.problems.push(format!(
                "{rel}: folder does not match its record ({prefix}...)"
            ));
        }
        if let (Some(source), Some(dirs)) = (source, &expected_dirs) {
            check_against_plan(source, dirs, rel, &record, &mut report);
        }
        if let Some(render) = render {
            other_render.check(render, rel, &record);
        }
        Ok(())
    })
    .map_err(scan_error)?;
    if let Some(listed) = listed {
        for rel in listed.keys().filter(|r| !present.contains(*r)) {
            report.problems.push(format!(
                "{MANIFEST_FILE} lists {rel}, which has no sequence.json"
            ));
        }
    }
    for rel in head_dirs.iter().filter(|r| !expected_heads.contains(*r)) {
        report.problems.push(format!(
            "{rel}: head camera folder without a finished wrist sequence (resume the run)"
        ));
    }
    other_render.report(&mut report);
    if let Some(assigned) = &assigned {
        check_complete(assigned, &present, shard, &mut report);
    }
    if dirs.is_empty() {
        report
            .problems
            .push(format!("{}: no finished sequence", root.display()));
    }
    for holder in super::lock::holders(&root.join(WORK_DIR)) {
        report.problems.push(format!(
            "{} is locked: {} (a run still writing, or killed: resume it with --resume)",
            root.display(),
            holder.describe()
        ));
    }
    let partial = root.join(WORK_DIR).join("partial");
    if std::fs::read_dir(&partial)
        .map(|mut d| d.next().is_some())
        .unwrap_or(false)
    {
        report.problems.push(format!(
            "{}: unfinished sequences remain (resume the run with --resume)",
            partial.display()
        ));
    }
    Ok(report)
}

/// The manifest's entries by path (`None` when it is missing, a problem).
fn read_manifest(
    root: &Path,
    report: &mut VerifyReport,
) -> Option<BTreeMap<String, ManifestEntry>> {
    let path = root.join(MANIFEST_FILE);
    let Ok(text) = std::fs::read_to_string(&path) else {
        report.problems.push(format!("{}: missing", path.display()));
        return None;
    };
    let mut listed = BTreeMap::new();
    for (n, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        match serde_json::from_str::<ManifestEntry>(line) {
            Ok(e) => {
                listed.insert(e.path.clone(), e);
            }
            Err(e) => report
                .problems
                .push(format!("{} line {}: {e}", path.display(), n + 1)),
        }
    }
    Some(listed)
}

/// The sequence's manifest line exists and agrees with its record.
fn check_listed(
    rel: &str,
    record: &SequenceRecord,
    listed: Option<&mut BTreeMap<String, ManifestEntry>>,
    report: &mut VerifyReport,
) {
    let Some(listed) = listed else {
        return;
    };
    match listed.get(rel) {
        None => report
            .problems
            .push(format!("{rel}: not listed in {MANIFEST_FILE}")),
        Some(e) if *e != manifest_entry(rel, record) => report.problems.push(format!(
            "{rel}: {MANIFEST_FILE} entry differs from sequence.json"
        )),
        Some(_) => {}
    }
}

/// A sequence with head poses has a head folder with the same record and
/// its frames; returns that folder (expected whether present or not).
fn check_head_folder(
    root: &Path,
    rel: &str,
    record: &SequenceRecord,
    head_dirs: &BTreeSet<String>,
    decode: bool,
    report: &mut VerifyReport,
) -> Option<String> {
    if !record.has_head_camera() {
        return None;
    }
    let Some(head_rel) = head_sequence_dir(rel) else {
        report.problems.push(format!(
            "{rel}: has head camera poses but is not a Wrist_d435 folder"
        ));
        return None;
    };
    if !head_dirs.contains(&head_rel) {
        report.problems.push(format!(
            "{head_rel}: missing (the plan of {rel} has head camera poses)"
        ));
        return Some(head_rel);
    }
    let head = match read_record(&root.join(&head_rel).join(SEQUENCE_FILE)) {
        Ok(h) => h,
        Err(e) => {
            report.problems.push(format!("{head_rel}: {}", chain(&e)));
            return Some(head_rel);
        }
    };
    if head.plan != record.plan || head.frame_files != record.frame_files {
        report.problems.push(format!(
            "{head_rel}: sequence.json differs from the wrist camera's {rel}"
        ));
    }
    report.head_sequences += 1;
    report.head_frames += head.frame_files.len();
    check_frames(root, &head_rel, &head, decode, report);
    Some(head_rel)
}

fn check_frames(
    root: &Path,
    rel: &str,
    record: &SequenceRecord,
    decode: bool,
    report: &mut VerifyReport,
) {
    if record.frame_files.len() != record.plan.frames.len() {
        report.problems.push(format!(
            "{rel}: {} frame files for {} planned frames",
            record.frame_files.len(),
            record.plan.frames.len()
        ));
    }
    let k = &record.plan.intrinsics;
    for name in output_files(record) {
        let path = root.join(rel).join(&name);
        match check_image(&path, decode) {
            Err(e) => report.problems.push(format!("{}: {e}", path.display())),
            Ok((w, h)) if (w, h) != (k.width, k.height) => report.problems.push(format!(
                "{}: {w}x{h} pixels, the intrinsics say {}x{}",
                path.display(),
                k.width,
                k.height
            )),
            Ok(_) => {}
        }
    }
}

/// Render settings that differ from the config's, each with the first
/// folder and the number of sequences (one line per setting and value, not
/// per sequence: a resumed dataset may hold thousands).
#[derive(Default)]
struct OtherRender(BTreeMap<String, (String, usize)>);

impl OtherRender {
    fn check(&mut self, render: &RenderConfig, rel: &str, record: &SequenceRecord) {
        for change in crate::render::consistency::changed_settings(render, &record.render) {
            let entry = self
                .0
                .entry(change.to_string())
                .or_insert_with(|| (rel.to_string(), 0));
            entry.1 += 1;
        }
    }

    fn report(self, report: &mut VerifyReport) {
        for (change, (first, count)) in self.0 {
            report.problems.push(format!(
                "{first}: {change} ({count} sequence(s) so; a dataset must not mix render \
                 settings)"
            ));
        }
    }
}

/// Every configured sequence of `shard` is in the dataset; the missing ones
/// are named (the first [`LISTED_MISSING`], then counted).
fn check_complete(
    assigned: &[Assigned],
    present: &BTreeSet<String>,
    shard: Shard,
    report: &mut VerifyReport,
) {
    let in_shard: Vec<&Assigned> = assigned
        .iter()
        .filter(|a| shard.contains(a.position))
        .collect();
    let missing: Vec<String> = in_shard
        .iter()
        .filter(|a| !present.contains(&a.rel_dir))
        .map(|a| format!("{} ({})", a.rel_dir, a.planned.key.id()))
        .collect();
    if missing.is_empty() {
        return;
    }
    for m in missing.iter().take(LISTED_MISSING) {
        report.problems.push(format!("missing sequence {m}"));
    }
    report.problems.push(format!(
        "{} of the {} configured sequences{} {} missing{}; render with --resume to complete \
         the dataset",
        missing.len(),
        in_shard.len(),
        match shard == Shard::ALL {
            true => String::new(),
            false => format!(" of shard {shard}"),
        },
        if missing.len() == 1 { "is" } else { "are" },
        match missing.len() > LISTED_MISSING {
            true => format!(" ({} more not listed)", missing.len() - LISTED_MISSING),
            false => String::new(),
        }
    ));
}

fn check_against_plan(
    source: &dyn PlanSource,
    dirs: &BTreeMap<String, String>,
    rel: &str,
    record: &SequenceRecord,
    report: &mut VerifyReport,
) {
    let id = record.plan.key.id();
    match dirs.get(&id) {
        None => report.problems.push(format!(
            "{rel}: sequence {id} is not in the configured dataset"
        )),
        Some(d) if d != rel => report
            .problems
            .push(format!("{rel}: sequence {id} belongs in {d}")),
        Some(_) => {}
    }
    // Compare after the same JSON round trip the record went through (float
    // parsing may differ from the in-memory value in the last bit).
    let fresh = source
        .plan(&record.plan.key)
        .map_err(DatasetError::from)
        .and_then(|p| {
            let json = |source| DatasetError::Serialise {
                what: "the JSON round trip of a plan",
                source,
            };
            let text = serde_json::to_string(&p).map_err(json)?;
            serde_json::from_str::<grasp_schema::SequencePlan>(&text).map_err(json)
        });
    match fresh {
        Ok(fresh) if fresh == record.plan => {}
        Ok(_) => report.problems.push(format!(
            "{rel}: sequence.json differs from a fresh plan of {id} (other config or seed?)"
        )),
        Err(e) => report
            .problems
            .push(format!("{rel}: cannot re-plan {id}: {}", chain(&e))),
    }
}
