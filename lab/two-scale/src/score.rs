//! The three heads (narrow, wide, both scales) fitted per seed and scored
//! per world by the hand's decision and the vote.

use crate::fit::{fit, softmax, FitConfig, Fitted, Rows};
use crate::Split;
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

/// Which features a head reads.
#[derive(Debug, Clone, Copy)]
pub enum Input {
    /// The recipe's 18.3-degree crop (the control).
    Narrow,
    /// The wider crop alone.
    Wide,
    /// Both side by side.
    Both,
}

pub const INPUTS: [Input; 3] = [Input::Narrow, Input::Wide, Input::Both];

fn input(split: &Split, which: Input) -> Result<Tensor> {
    Ok(match which {
        Input::Narrow => split.narrow.clone(),
        Input::Wide => split.wide.clone(),
        Input::Both => Tensor::cat(&[&split.narrow, &split.wide], 1)?,
    })
}

pub struct Models {
    heads: Vec<(Input, Vec<Fitted>)>,
}

impl Models {
    pub fn fit(train: &Split, val: &Split, seeds: u64) -> Result<Models> {
        let labels = &train.frames.labels;
        let mut heads = Vec::new();
        for which in INPUTS {
            let rows = Rows {
                x: input(train, which)?,
                y: one_hot(labels, Class::COUNT)?,
                weight: balanced(labels),
            };
            let val_x = input(val, which)?;
            let loss = |m: &Fitted| frame_loss(&softmax(&m.logits(&val_x)?)?, &val.frames.labels);
            let mut fitted = Vec::new();
            for seed in 0..seeds {
                tracing::info!("{which:?} head, seed {seed}");
                fitted.push(fit(&rows, Class::COUNT, &FIT, seed, &loss)?);
            }
            heads.push((which, fitted));
        }
        Ok(Models { heads })
    }

    /// Each head's outcome on `set`, pooled over seeds.
    pub fn score(&self, set: &Split, data: &trainer::data::Dataset) -> Result<Vec<(Input, Tally)>> {
        let multi = data.multi_grasp_objects();
        let policy = grasp_policy::PolicyConfig::default();
        let mut out = Vec::new();
        for (which, models) in &self.heads {
            let x = input(set, *which)?;
            let mut tally = Tally::default();
            for m in models {
                let probs: Vec<Vec<f32>> = softmax(&m.logits(&x)?)?.to_vec2()?;
                for (si, seq) in data.sequences.iter().enumerate() {
                    let rows = &set.frames.seq_rows[si];
                    let v = VideoPrediction {
                        id: seq.id.clone(),
                        object: seq.object.clone(),
                        part: seq.part.clone(),
                        preshape: seq.preshape,
                        multi_grasp: multi.contains(&seq.object),
                        labels: (0..rows.len()).map(|i| seq.labels[i]).collect(),
                        probs: rows
                            .iter()
                            .map(|&r| std::array::from_fn(|k| probs[r][k]))
                            .collect(),
                        times_s: set.frames.seq_times[si].clone(),
                    };
                    tally.add(&v, &VideoOutcome::of(&v, &policy));
                }
            }
            out.push((*which, tally));
        }
        Ok(out)
    }
}

/// One-hot rows of frame classes.
fn one_hot(labels: &[u32], k: usize) -> Result<Tensor> {
    let mut v = vec![0f32; labels.len() * k];
    for (i, &l) in labels.iter().enumerate() {
        v[i * k + l as usize] = 1.0;
    }
    Ok(Tensor::from_vec(v, (labels.len(), k), &Device::Cpu)?)
}

/// Frame weights that give every class the same total.
fn balanced(labels: &[u32]) -> Vec<f32> {
    let mut count = [0usize; Class::COUNT];
    labels.iter().for_each(|&l| count[l as usize] += 1);
    labels
        .iter()
        .map(|&l| 1.0 / count[l as usize] as f32)
        .collect()
}

/// Class-balanced mean cross-entropy of frame probabilities.
fn frame_loss(probs: &Tensor, labels: &[u32]) -> Result<f64> {
    let p: Vec<Vec<f32>> = probs.to_vec2()?;
    let w = balanced(labels);
    let total: f32 = w.iter().sum();
    let loss: f64 = p
        .iter()
        .zip(labels)
        .zip(&w)
        .map(|((row, &l), &wi)| -f64::from(wi) * f64::from(row[l as usize].max(1e-7)).ln())
        .sum();
    Ok(loss / f64::from(total))
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

    fn cell(&self) -> String {
        format!(
            "{} / {} ({}, {}) {}",
            Self::pct(self.hand, self.videos),
            Self::pct(self.vote, self.videos),
            Self::pct(self.multi_hand, self.multi),
            Self::pct(self.multi_vote, self.multi),
            Self::pct(self.last_right, self.last_frames)
        )
    }

    fn hand_pct(&self) -> f64 {
        100.0 * self.hand as f64 / self.videos.max(1) as f64
    }

    fn vote_pct(&self) -> f64 {
        100.0 * self.vote as f64 / self.videos.max(1) as f64
    }
}

#[derive(Default)]
pub struct Table {
    rows: BTreeMap<String, Vec<(Input, Tally)>>,
}

impl Table {
    pub fn add(&mut self, name: &str, row: &[(Input, Tally)]) {
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
