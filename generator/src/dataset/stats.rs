//! `grasp-gen dataset stats DIR`: frame counts and the measured render cost
//! per frame (worker wall-clock seconds from each record's `render.cost`),
//! per camera, so users can weigh render quality against accuracy.

use super::error::{DatasetError, Result};
use super::writer::visit_sequences;
use grasp_schema::dataset::{SequenceRecord, STUDIO_WORLD};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Frames and render seconds of one camera.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CameraCost {
    pub sequences: usize,
    pub frames: usize,
    pub seconds: f64,
    /// `seconds / frames`: mean render seconds per frame.
    pub seconds_per_frame: f64,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DatasetStats {
    pub sequences: usize,
    /// Wrist-camera frames (every sequence has them).
    pub frames: usize,
    /// Sequences whose record has no `render.cost` (older datasets).
    pub without_cost: usize,
    /// Object swap and appearance, once per sequence whatever the cameras.
    pub setup_seconds: f64,
    pub setup_seconds_per_frame: f64,
    /// Image-space camera effects (white balance, blur, noise, JPEG), part
    /// of the cameras' seconds, over all cameras.
    pub effects_seconds: f64,
    pub effects_seconds_per_frame: f64,
    /// CPU seconds of the workers (every thread), all cameras and setup.
    pub cpu_seconds: f64,
    pub cpu_seconds_per_frame: f64,
    /// Per camera folder (`Wrist_d435`, `Head_d435`).
    pub cameras: BTreeMap<String, CameraCost>,
    /// Sequences per render setting (`engine, samples, WxH`).
    pub settings: BTreeMap<String, usize>,
    /// Frames of the sequences with a cost (the setup's denominator).
    #[serde(skip)]
    setup_frames: usize,
}

impl DatasetStats {
    pub fn from_records<'a>(records: impl IntoIterator<Item = &'a SequenceRecord>) -> Self {
        let mut s = DatasetStats::default();
        for r in records {
            s.add(r);
        }
        s
    }

    /// Counts one more sequence (the per-frame means stay current).
    pub fn add(&mut self, r: &SequenceRecord) {
        let frames = r.frame_files.len();
        self.sequences += 1;
        self.frames += frames;
        *self.settings.entry(setting_label(r)).or_default() += 1;
        let Some(cost) = r.render_cost() else {
            self.without_cost += 1;
            return;
        };
        self.setup_seconds += cost.setup_seconds;
        self.effects_seconds += cost.effects_seconds;
        self.cpu_seconds += cost.cpu_seconds;
        self.setup_frames += frames;
        for (camera, seconds) in cost.camera_seconds {
            let c = self.cameras.entry(camera).or_default();
            c.sequences += 1;
            c.frames += frames;
            c.seconds += seconds;
            c.seconds_per_frame = per(c.seconds, c.frames);
        }
        self.setup_seconds_per_frame = per(self.setup_seconds, self.setup_frames);
        self.effects_seconds_per_frame = per(self.effects_seconds, self.setup_frames);
        self.cpu_seconds_per_frame = per(self.cpu_seconds, self.setup_frames);
    }

    pub fn render_text(&self) -> String {
        let mut out = format!(
            "{} sequences, {} frames per camera\n",
            self.sequences, self.frames
        );
        for (setting, n) in &self.settings {
            let _ = writeln!(out, "render setting {setting}: {n} sequences");
        }
        let _ = writeln!(
            out,
            "{:<12}{:>10}{:>10}{:>14}{:>16}",
            "camera", "sequences", "frames", "render s", "s per frame"
        );
        for (name, c) in &self.cameras {
            let _ = writeln!(
                out,
                "{name:<12}{:>10}{:>10}{:>14.2}{:>16.4}",
                c.sequences, c.frames, c.seconds, c.seconds_per_frame
            );
        }
        let _ = writeln!(
            out,
            "setup (object, materials, lights): {:.2} s in all, {:.4} s per frame",
            self.setup_seconds, self.setup_seconds_per_frame
        );
        if self.cpu_seconds > 0.0 {
            let _ = writeln!(
                out,
                "worker CPU time (every thread): {:.2} s in all, {:.4} s per frame",
                self.cpu_seconds, self.cpu_seconds_per_frame
            );
        }
        if self.effects_seconds > 0.0 {
            let _ = writeln!(
                out,
                "of the cameras' seconds, camera effects: {:.2} s in all, {:.4} s per frame",
                self.effects_seconds, self.effects_seconds_per_frame
            );
        }
        if self.without_cost > 0 {
            let _ = writeln!(
                out,
                "{} sequences carry no render cost (written before it was recorded)",
                self.without_cost
            );
        }
        out
    }
}

fn per(seconds: f64, frames: usize) -> f64 {
    if frames == 0 {
        0.0
    } else {
        seconds / frames as f64
    }
}

fn setting_label(r: &SequenceRecord) -> String {
    let k = &r.plan.intrinsics;
    let engine = r.render["engine"].as_str().unwrap_or("?");
    let samples = r.render["samples"].as_u64().unwrap_or(0);
    let mut label = format!("{engine}, {samples} samples, {}x{}", k.width, k.height);
    // A test world other than training's studio is named first.
    if let Some(world) = r.world().filter(|w| w != STUDIO_WORLD) {
        label = format!("{world} world, {label}");
    }
    match r.render_device() {
        Some(device) => format!("{label}, {device}"),
        None => label,
    }
}

/// Reads every finished sequence under `root`.
pub fn stats(root: &Path) -> Result<DatasetStats> {
    let mut s = DatasetStats::default();
    visit_sequences(root, false, |_, record| {
        s.add(&record?);
        Ok(())
    })
    .map_err(|e| DatasetError::Scan {
        root: root.to_path_buf(),
        source: Box::new(e),
    })?;
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use grasp_schema::dataset::RenderCost;

    fn record(frames: usize, cost: Option<(f64, f64, Option<f64>)>) -> SequenceRecord {
        let plan_json = serde_json::json!({
            "schema_version": 1, "dataset_seed": 1,
            "key": {"object": "o", "part": "p", "index": 0, "condition": "default"},
            "stream_seed": 1, "category": "c", "grasp_type": "large_diameter",
            "preshape": "power", "part_index": 0, "fps": 10.0, "duration_s": 1.0,
            "intrinsics": {"width": 32, "height": 32, "fx": 1.0, "fy": 1.0, "cx": 16.0,
                "cy": 16.0, "fov_x_deg": 1.0, "fov_y_deg": 1.0, "clip_near": 0.1, "clip_far": 9.0},
            "object": {"pose": {"position": [0.0, 0.0, 0.0], "rotation_wxyz": [1.0, 0.0, 0.0, 0.0]},
                "yaw_deg": 0.0, "upside_down": false, "on_table_border": false},
            "target": [0.0, 0.0, 0.0], "other_end": [0.0, 0.0, 0.0],
            "frames": [], "sampled": {}
        });
        let mut render = serde_json::json!({"engine": "workbench", "samples": 1});
        if let Some((setup, wrist, head)) = cost {
            let mut c = RenderCost {
                setup_seconds: setup,
                ..Default::default()
            };
            c.camera_seconds.insert("Wrist_d435".into(), wrist);
            if let Some(h) = head {
                c.camera_seconds.insert("Head_d435".into(), h);
            }
            render["cost"] = serde_json::to_value(c).unwrap();
        }
        SequenceRecord {
            plan: serde_json::from_value(plan_json).unwrap(),
            frame_files: (0..frames).map(|i| format!("{i:05}.png")).collect(),
            render,
            generator_version: "test".into(),
        }
    }

    #[test]
    fn seconds_per_frame_are_ratios_of_sums() {
        let rs = [
            record(10, Some((0.5, 2.0, Some(3.0)))),
            record(30, Some((1.5, 4.0, None))),
            record(5, None),
        ];
        let s = DatasetStats::from_records(&rs);
        assert_eq!((s.sequences, s.frames, s.without_cost), (3, 45, 1));
        let w = &s.cameras["Wrist_d435"];
        assert_eq!((w.sequences, w.frames), (2, 40));
        assert!((w.seconds_per_frame - 6.0 / 40.0).abs() < 1e-12);
        let h = &s.cameras["Head_d435"];
        assert_eq!((h.sequences, h.frames), (1, 10));
        assert!((h.seconds_per_frame - 0.3).abs() < 1e-12);
        assert!((s.setup_seconds_per_frame - 2.0 / 40.0).abs() < 1e-12);
        assert_eq!(s.settings["workbench, 1 samples, 32x32"], 3);
        assert!(s.render_text().contains("1 sequences carry no render cost"));
    }

    #[test]
    fn a_foreign_world_is_its_own_setting() {
        let mut foreign = record(4, None);
        foreign.render["world"] = "foreign".into();
        let mut studio = record(4, None);
        studio.render["world"] = "studio".into();
        let s = DatasetStats::from_records(&[foreign, studio, record(4, None)]);
        assert_eq!(s.settings["foreign world, workbench, 1 samples, 32x32"], 1);
        assert_eq!(s.settings["workbench, 1 samples, 32x32"], 2);
    }

    #[test]
    fn an_empty_dataset_has_zero_cost_not_nan() {
        let s = DatasetStats::from_records(&[]);
        assert_eq!(s.setup_seconds_per_frame, 0.0);
        assert!(s.cameras.is_empty());
    }
}
