//! The dense head's readouts beside the control, scored per world.

use crate::fit::{fit, softmax, FitConfig, Fitted, Rows};
use crate::masks::{K, NO_PART};
use crate::{balanced, frame_loss, one_hot, pooled, Split};
use anyhow::Result;
use candle_core::{Device, Tensor};
use grasp_schema::taxonomy::Class;
use std::collections::BTreeMap;
use trainer::eval::metrics::{VideoOutcome, VideoPrediction};

const FIT: FitConfig = FitConfig {
    lr: 5e-4,
    weight_decay: 5e-4,
    epochs: 60,
    patience: 8,
    batch_frames: 256,
};

/// How a frame is read from the dense head's cells.
#[derive(Debug, Clone, Copy)]
pub enum Readout {
    /// The pooled features through the control head.
    Control,
    /// The central cells' logits averaged.
    Centre,
    /// Each cell's pre-shape probabilities weighted by how surely it
    /// shows a part and how near the aim point (the centre) it is.
    Aim,
    /// Every cell's logits averaged.
    All,
    /// The pooled features through the head trained on frames and cells
    /// at once (the cells' part loss a regulariser; an FC head at run time).
    Joint,
}

pub const READOUTS: [Readout; 5] = [
    Readout::Control,
    Readout::Joint,
    Readout::Centre,
    Readout::Aim,
    Readout::All,
];

pub struct Models {
    dense: Vec<Fitted>,
    joint: Vec<Fitted>,
    control: Vec<Fitted>,
    grid: usize,
}

impl Models {
    pub fn fit(
        train: &Split,
        val: &Split,
        cell_y: Vec<f32>,
        ex: &crate::cells::CellExtractor,
        seeds: u64,
        cell_weight: f64,
        joint_only: bool,
    ) -> Result<Models> {
        let grid = ex.grid;
        let cells = ex.cells();
        let labels = &train.frames.labels;
        let weight = balanced(labels);
        let n = cell_y.len() / K;
        let dense_rows = Rows {
            x: train.cells.clone(),
            y: Tensor::from_vec(cell_y, (n, K), &Device::Cpu)?,
            weight: weight.clone(),
            per_frame: cells,
        };
        let control_rows = Rows {
            x: pooled(&train.cells, cells)?,
            y: one_hot(labels, Class::COUNT)?,
            weight,
            per_frame: 1,
        };
        let val_labels = val.frames.labels.clone();
        let mut out = Models {
            dense: vec![],
            joint: vec![],
            control: vec![],
            grid,
        };
        for seed in 0..seeds {
            let loss =
                |m: &Fitted| frame_loss(&read(m, &val.cells, Readout::Centre, grid)?, &val_labels);
            tracing::info!("dense head, seed {seed}");
            if !joint_only {
                out.dense
                    .push(fit(&dense_rows, None, K, &FIT, seed, &loss)?);
            }
            let loss =
                |m: &Fitted| frame_loss(&read(m, &val.cells, Readout::Control, grid)?, &val_labels);
            tracing::info!("control head, seed {seed}");
            out.control
                .push(fit(&control_rows, None, Class::COUNT, &FIT, seed, &loss)?);
            let loss =
                |m: &Fitted| frame_loss(&read(m, &val.cells, Readout::Joint, grid)?, &val_labels);
            tracing::info!("joint head, seed {seed}");
            let frames = crate::fit::FrameRows {
                x: control_rows.x.clone(),
                y: control_rows.y.clone(),
                cell_weight,
            };
            out.joint
                .push(fit(&dense_rows, Some(&frames), K, &FIT, seed, &loss)?);
        }
        Ok(out)
    }

    /// Every readout's outcome on `set`, pooled over seeds.
    pub fn score(
        &self,
        set: &Split,
        data: &trainer::data::Dataset,
        _cells: usize,
    ) -> Result<Vec<(Readout, Tally)>> {
        let multi = data.multi_grasp_objects();
        let policy = grasp_policy::PolicyConfig::default();
        let mut out = Vec::new();
        for readout in READOUTS {
            let mut tally = Tally::default();
            let models = match readout {
                Readout::Control => &self.control,
                Readout::Joint => &self.joint,
                _ => &self.dense,
            };
            if models.is_empty() {
                continue;
            }
            for m in models {
                let probs: Vec<Vec<f32>> = read(m, &set.cells, readout, self.grid)?.to_vec2()?;
                for (si, seq) in data.sequences.iter().enumerate() {
                    let rows = &set.frames.seq_rows[si];
                    let valid: Vec<usize> = (0..seq.frames.len()).collect();
                    let v = VideoPrediction {
                        id: seq.id.clone(),
                        object: seq.object.clone(),
                        part: seq.part.clone(),
                        preshape: seq.preshape,
                        multi_grasp: multi.contains(&seq.object),
                        labels: rows
                            .iter()
                            .zip(&valid)
                            .map(|(_, &i)| seq.labels[i])
                            .collect(),
                        probs: rows
                            .iter()
                            .map(|&r| std::array::from_fn(|k| probs[r][k]))
                            .collect(),
                        times_s: set.frames.seq_times[si].clone(),
                    };
                    tally.add(&v, &VideoOutcome::of(&v, &policy));
                }
            }
            out.push((readout, tally));
        }
        Ok(out)
    }
}

/// Frame probabilities (frames, 5) of cells (frames x cells, dim).
fn read(m: &Fitted, cells: &Tensor, readout: Readout, grid: usize) -> Result<Tensor> {
    let per = grid * grid;
    if let Readout::Control | Readout::Joint = readout {
        let logits = m.logits(&pooled(cells, per)?)?;
        return softmax(&logits.narrow(1, 0, Class::COUNT)?);
    }
    let logits: Vec<f32> = m.logits(cells)?.flatten_all()?.to_vec1()?;
    let frames = logits.len() / (per * K);
    let mid = (grid as f64 - 1.0) / 2.0;
    let centre = |c: usize| {
        let (r, col) = ((c / grid) as f64 - mid, (c % grid) as f64 - mid);
        (
            r.abs() < 1.0,
            (-(r * r + col * col) / (2.0 * (grid as f64 / 4.0).powi(2))).exp(),
        )
    };
    let mut out = Vec::with_capacity(frames * Class::COUNT);
    for f in logits.chunks_exact(per * K) {
        let mut acc = [0f64; Class::COUNT];
        let mut total = 0.0;
        for (c, l) in f.chunks_exact(K).enumerate() {
            let (inner, gauss) = centre(c);
            let inner = inner && ((c % grid) as f64 - mid).abs() < 1.0;
            match readout {
                Readout::Centre | Readout::All if readout_takes(readout, inner) => {
                    acc.iter_mut().zip(l).for_each(|(a, &v)| *a += f64::from(v));
                    total += 1.0;
                }
                Readout::Aim => {
                    let p = softmax_row(l);
                    let w = (1.0 - p[NO_PART]) * gauss + 1e-9;
                    let s: f64 = p[..Class::COUNT].iter().sum::<f64>().max(1e-12);
                    acc.iter_mut().zip(&p).for_each(|(a, &v)| *a += w * v / s);
                    total += w;
                }
                _ => {}
            }
        }
        match readout {
            Readout::Aim => out.extend(acc.iter().map(|a| (a / total) as f32)),
            _ => {
                let mean: Vec<f64> = acc.iter().map(|a| a / total).collect();
                out.extend(softmax_row_f64(&mean).iter().map(|&v| v as f32));
            }
        }
    }
    Ok(Tensor::from_vec(out, (frames, Class::COUNT), &Device::Cpu)?)
}

fn readout_takes(readout: Readout, inner: bool) -> bool {
    matches!(readout, Readout::All) || inner
}

fn softmax_row(l: &[f32]) -> Vec<f64> {
    softmax_row_f64(&l.iter().map(|&v| f64::from(v)).collect::<Vec<_>>())
}

fn softmax_row_f64(l: &[f64]) -> Vec<f64> {
    let max = l.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = l.iter().map(|v| (v - max).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|v| v / s).collect()
}

/// Videos right by the hand and by the vote, multi-grasp apart, and the
/// pre-shape frames of the last second before contact.
#[derive(Debug, Default, Clone)]
pub struct Tally {
    videos: usize,
    hand: usize,
    vote: usize,
    multi: usize,
    multi_vote: usize,
    multi_hand: usize,
    last_frames: usize,
    last_right: usize,
}

impl Tally {
    fn add(&mut self, v: &VideoPrediction, o: &VideoOutcome) {
        self.videos += 1;
        let hand = o.hand.as_ref().is_some_and(|h| h.is_right(o.truth));
        self.hand += usize::from(hand);
        self.vote += usize::from(o.vote == o.truth);
        if v.multi_grasp {
            self.multi += 1;
            self.multi_vote += usize::from(o.vote == o.truth);
            self.multi_hand += usize::from(hand);
        }
        let grasp: Vec<usize> = (0..v.labels.len())
            .filter(|&i| v.labels[i] != Class::NoGrasp)
            .collect();
        if let Some(&last) = grasp.last() {
            let end = v.time_s(last);
            let truth = Class::from(v.preshape).index();
            for &i in grasp.iter().filter(|&&i| v.time_s(i) >= end - 1.0) {
                self.last_frames += 1;
                self.last_right +=
                    usize::from(trainer::eval::metrics::frame_class(&v.probs[i]) == truth);
            }
        }
    }

    fn pct(a: usize, b: usize) -> String {
        if b == 0 {
            "-".into()
        } else {
            format!("{:.1}", 100.0 * a as f64 / b as f64)
        }
    }

    pub fn cell(&self) -> String {
        format!(
            "{} / {} ({}, {}) {}",
            Self::pct(self.hand, self.videos),
            Self::pct(self.vote, self.videos),
            Self::pct(self.multi_hand, self.multi),
            Self::pct(self.multi_vote, self.multi),
            Self::pct(self.last_right, self.last_frames)
        )
    }

    pub fn hand_pct(&self) -> f64 {
        100.0 * self.hand as f64 / self.videos.max(1) as f64
    }

    pub fn vote_pct(&self) -> f64 {
        100.0 * self.vote as f64 / self.videos.max(1) as f64
    }
}

#[derive(Default)]
pub struct Table {
    rows: BTreeMap<String, Vec<(Readout, Tally)>>,
}

impl Table {
    pub fn add(&mut self, name: &str, row: &[(Readout, Tally)]) {
        self.rows.insert(name.to_string(), row.to_vec());
    }

    pub fn markdown(&self) -> String {
        let mut s = String::from(
            "Per world: hand / vote (multi-grasp hand, vote) last-second pre-shape frames, %, 3 seeds pooled\n\n| world |",
        );
        let Some(first) = self.rows.values().next() else {
            return s;
        };
        for (r, _) in first {
            s += &format!(" {r:?} |");
        }
        s += "\n|---|";
        s += &"---|".repeat(first.len());
        s += "\n";
        let mut worst = vec![(f64::INFINITY, f64::INFINITY); first.len()];
        for (name, row) in &self.rows {
            s += &format!("| {name} |");
            for (i, (_, t)) in row.iter().enumerate() {
                s += &format!(" {} |", t.cell());
                worst[i].0 = worst[i].0.min(t.hand_pct());
                worst[i].1 = worst[i].1.min(t.vote_pct());
            }
            s += "\n";
        }
        s += "| **worst** |";
        for (h, v) in worst {
            s += &format!(" **{h:.1} / {v:.1}** |");
        }
        s + "\n"
    }
}
