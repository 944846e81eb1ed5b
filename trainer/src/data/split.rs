//! Train/validation/test splits by sequence (never by frame), stratified by
//! object-part pair: each pair's sequences are shuffled with the split seed
//! and dealt out in proportion, so every pair with enough sequences appears
//! in every split.

use super::Dataset;
use crate::error::DataError;
use rand::seq::SliceRandom;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SplitConfig {
    pub val_fraction: f64,
    pub test_fraction: f64,
    /// Seed of the split, separate from the training seed so that runs with
    /// several seeds share one split.
    pub seed: u64,
}

impl SplitConfig {
    /// Both fractions finite in [0, 1), together under 1 (some sequences
    /// must be left to train on).
    pub fn validate(&self) -> Result<(), crate::error::ConfigError> {
        let invalid = |field, reason| Err(crate::error::ConfigError::invalid(field, reason));
        for (field, v) in [
            ("split.val_fraction", self.val_fraction),
            ("split.test_fraction", self.test_fraction),
        ] {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return invalid(
                    field,
                    format!("{field} must be in [0, 1), got {}", grasp_support::num(v)),
                );
            }
        }
        if self.val_fraction + self.test_fraction >= 1.0 {
            return invalid(
                "split.val_fraction",
                format!(
                    "split.val_fraction + split.test_fraction must be under 1, got {} + {}",
                    self.val_fraction, self.test_fraction
                ),
            );
        }
        Ok(())
    }
}

impl Default for SplitConfig {
    fn default() -> Self {
        SplitConfig {
            val_fraction: 0.15,
            test_fraction: 0.15,
            seed: 0,
        }
    }
}

/// Sequence ids of each split.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Split {
    pub train: Vec<String>,
    pub val: Vec<String>,
    pub test: Vec<String>,
}

impl Split {
    pub fn save(&self, path: &Path) -> Result<(), DataError> {
        let json = serde_json::to_string_pretty(self)?;
        Ok(grasp_support::atomic::write_atomic(path, json.as_bytes())?)
    }

    pub fn load(path: &Path) -> Result<Split, DataError> {
        let text = std::fs::read_to_string(path).map_err(|source| DataError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| DataError::Parse {
            what: "split file",
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }
}

/// Splits `data` per object-part pair. Within a pair of `n` sequences, the
/// validation and test shares are `round(n * fraction)`, but a pair keeps at
/// least one training sequence, then one test, then one validation sequence
/// as `n` allows (training first: a pair never seen in training cannot be
/// learned).
pub fn stratified_split(data: &Dataset, cfg: &SplitConfig) -> Split {
    let mut strata: BTreeMap<String, Vec<&str>> = BTreeMap::new();
    for s in &data.sequences {
        strata.entry(s.stratum()).or_default().push(&s.id);
    }
    let mut rng = crate::rng::stream(cfg.seed, "split");
    let mut split = Split::default();
    for ids in strata.values_mut() {
        ids.shuffle(&mut rng);
        let (n_val, n_test) = shares(ids.len(), cfg);
        let (val, rest) = ids.split_at(n_val);
        let (test, train) = rest.split_at(n_test);
        split.val.extend(val.iter().map(|s| s.to_string()));
        split.test.extend(test.iter().map(|s| s.to_string()));
        split.train.extend(train.iter().map(|s| s.to_string()));
    }
    split
}

fn shares(n: usize, cfg: &SplitConfig) -> (usize, usize) {
    let round = |f: f64| (n as f64 * f).round() as usize;
    let mut n_test = round(cfg.test_fraction);
    let mut n_val = round(cfg.val_fraction);
    if cfg.test_fraction > 0.0 && n >= 2 {
        n_test = n_test.max(1);
    }
    if cfg.val_fraction > 0.0 && n >= 3 {
        n_val = n_val.max(1);
    }
    while n_val + n_test >= n && n_val + n_test > 0 {
        if n_val >= n_test && n_val > 0 {
            n_val -= 1;
        } else {
            n_test -= 1;
        }
    }
    (n_val, n_test)
}

/// At most `n` sequences of every object-part pair of `data`, the rest
/// dropped (training-set size studies). Each pair's sequences are shuffled
/// by a stream of `seed` and that pair alone, and the first `n` kept: the
/// choice is deterministic, and the subsets for growing `n` are nested, so
/// error against `n` varies with the amount of data only.
pub fn cap_per_pair(data: &Dataset, n: usize, seed: u64) -> Dataset {
    let mut strata: BTreeMap<String, Vec<&str>> = BTreeMap::new();
    for s in &data.sequences {
        strata.entry(s.stratum()).or_default().push(&s.id);
    }
    let mut keep = Vec::new();
    for (stratum, ids) in strata.iter_mut() {
        ids.sort_unstable();
        ids.shuffle(&mut crate::rng::stream(
            seed,
            &format!("per-pair/{stratum}"),
        ));
        keep.extend(ids.iter().take(n).map(|s| s.to_string()));
    }
    select(data, &keep)
}

/// The sequences of `data` named in `ids`, in dataset order.
pub fn select(data: &Dataset, ids: &[String]) -> Dataset {
    let wanted: std::collections::HashSet<&str> = ids.iter().map(String::as_str).collect();
    Dataset {
        root: data.root.clone(),
        sequences: data
            .sequences
            .iter()
            .filter(|s| wanted.contains(s.id.as_str()))
            .cloned()
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{LabelSource, Sequence};
    use grasp_schema::taxonomy::Preshape;

    fn dataset(pairs: &[(&str, usize)]) -> Dataset {
        let mut sequences = Vec::new();
        for (object, n) in pairs {
            for i in 0..*n {
                sequences.push(Sequence {
                    id: format!("{object}/{i:03}"),
                    dir: Default::default(),
                    category: "c".into(),
                    object: object.to_string(),
                    part: Some("p".into()),
                    preshape: Preshape::Power,
                    condition: "default".into(),
                    fps: 30.0,
                    frames: Vec::new(),
                    labels: Vec::new(),
                    label_source: LabelSource::SequenceJson,
                    crop: grasp_model::input::Crop::Whole,
                    lens: None,
                    lead_in: 0,
                    first_frame: 0,
                    rendered_region: None,
                    denoise: false,
                    test_world: None,
                    view: None,
                    probe: None,
                    style: None,
                });
            }
        }
        Dataset {
            root: Default::default(),
            sequences,
        }
    }

    fn ids(d: &Dataset) -> Vec<&str> {
        d.sequences.iter().map(|s| s.id.as_str()).collect()
    }

    #[test]
    fn cap_per_pair_is_deterministic_nested_and_per_pair() {
        let data = dataset(&[("a", 10), ("b", 3), ("c", 0)]);
        let two = cap_per_pair(&data, 2, 7);
        let five = cap_per_pair(&data, 5, 7);
        let count = |d: &Dataset, o: &str| d.sequences.iter().filter(|s| s.object == o).count();
        assert_eq!((count(&two, "a"), count(&two, "b")), (2, 2));
        // A pair with fewer sequences than the cap keeps them all.
        assert_eq!((count(&five, "a"), count(&five, "b")), (5, 3));
        assert_eq!(ids(&two), ids(&cap_per_pair(&data, 2, 7)));
        // Nested: the sequences kept at 2 are among those kept at 5.
        assert!(ids(&two).iter().all(|i| ids(&five).contains(i)));
        // Not simply the first ones, and another seed picks others.
        let other: Vec<Dataset> = (0..8).map(|s| cap_per_pair(&data, 2, s)).collect();
        assert!(other.iter().any(|d| ids(d) != ids(&two)));
        assert!(other.iter().any(|d| !ids(d).contains(&"a/000")));
        // A pair's choice does not depend on the other pairs.
        let alone = cap_per_pair(&dataset(&[("a", 10)]), 2, 7);
        let a_of_two: Vec<&str> = ids(&two)
            .into_iter()
            .filter(|i| i.starts_with('a'))
            .collect();
        assert_eq!(ids(&alone), a_of_two);
        assert_eq!(cap_per_pair(&data, 0, 7).sequences.len(), 0);
    }

    #[test]
    fn shares_keep_training_data() {
        let cfg = SplitConfig::default();
        assert_eq!(shares(1, &cfg), (0, 0));
        assert_eq!(shares(2, &cfg), (0, 1));
        assert_eq!(shares(3, &cfg), (1, 1));
        assert_eq!(shares(20, &cfg), (3, 3));
    }
}
