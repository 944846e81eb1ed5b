//! What `report.html` shows of every frame: where the frames of each scored
//! video are (and the crop the model saw of them), and each run's answer
//! per frame. `eval` keeps it beside the report in memory; report.json does
//! not hold it (its per-frame answers would be most of the file).

use crate::data::{Dataset, Sequence};
use crate::eval::metrics::{frame_class, VideoPrediction};
use grasp_schema::taxonomy::Class;
use std::collections::{BTreeMap, BTreeSet};

/// One run's answer on one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMark {
    /// The frame: an index into its sequence's `frames`.
    pub frame: usize,
    /// Seconds since the start of the recording.
    pub time_s: f64,
    /// The frame's label.
    pub label: Class,
    /// The predicted class (argmax) and its probability.
    pub class: Class,
    pub confidence: f32,
}

/// The frames of the evaluated videos and every run's per-frame answers.
#[derive(Debug, Clone, Default)]
pub struct FrameRecord {
    /// The evaluated sequences by id (frame paths, crop, lens).
    sequences: BTreeMap<String, Sequence>,
    /// Per run (in the report's order), per video id, the frames it scored.
    runs: Vec<BTreeMap<String, Vec<FrameMark>>>,
}

impl FrameRecord {
    /// A record of `data`'s sequences, without runs yet.
    pub fn new(data: &Dataset) -> FrameRecord {
        let sequences = data
            .sequences
            .iter()
            .map(|s| (s.id.clone(), s.clone()))
            .collect();
        FrameRecord {
            sequences,
            runs: Vec::new(),
        }
    }

    /// Adds one run's predictions (the frames it scored of each video). A
    /// frame is found by its time stamp, which the prediction keeps from
    /// its sequence ([`Sequence::time_s`]).
    pub fn add_run(&mut self, predictions: &[VideoPrediction]) {
        let mut run = BTreeMap::new();
        for v in predictions {
            let Some(seq) = self.sequences.get(&v.id) else {
                continue;
            };
            let marks = (0..v.probs.len().min(v.labels.len()))
                .filter_map(|i| {
                    let t = v.time_s(i);
                    let class = frame_class(&v.probs[i]);
                    Some(FrameMark {
                        frame: frame_index(seq, t)?,
                        time_s: t,
                        label: v.labels[i],
                        class: Class::from_index(class)?,
                        confidence: v.probs[i][class],
                    })
                })
                .collect();
            run.insert(v.id.clone(), marks);
        }
        self.runs.push(run);
    }

    pub fn runs(&self) -> usize {
        self.runs.len()
    }

    pub fn sequence(&self, id: &str) -> Option<&Sequence> {
        self.sequences.get(id)
    }

    /// Run `run`'s marks on video `id`.
    pub fn marks(&self, run: usize, id: &str) -> &[FrameMark] {
        self.runs
            .get(run)
            .and_then(|r| r.get(id))
            .map(Vec::as_slice)
            .unwrap_or(&[])
    }

    /// The frames of video `id` that any run scored, in order.
    pub fn columns(&self, id: &str) -> Vec<usize> {
        let set: BTreeSet<usize> = (0..self.runs.len())
            .flat_map(|r| self.marks(r, id).iter().map(|m| m.frame))
            .collect();
        set.into_iter().collect()
    }
}

/// The index into `seq.frames` of the frame recorded at `time_s`.
fn frame_index(seq: &Sequence, time_s: f64) -> Option<usize> {
    if !(seq.fps.is_finite() && seq.fps > 0.0) {
        return None;
    }
    let recorded = (time_s * seq.fps).round() as i64;
    let i = usize::try_from(recorded - seq.first_frame as i64).ok()?;
    (i < seq.frames.len()).then_some(i)
}
