//! Reading a run's data and splitting it into train, validation and test.

use crate::data::split::{self, Split};
use crate::data::{self, BadData, Dataset};
use crate::error::DataError;
use crate::plan::DataPlan;
use std::path::Path;

/// The three splits of a run.
#[derive(Debug, Clone, Default)]
pub struct Splits {
    pub train: Dataset,
    pub val: Dataset,
    pub test: Dataset,
    pub split: Split,
}

/// Reads the data and splits it: separate validation/test roots when given,
/// otherwise a stratified split of the training root.
pub fn load_splits(plan: &DataPlan, bad: &BadData) -> Result<Splits, DataError> {
    let read = |root: &Path| -> Result<Dataset, DataError> {
        let d = data::read_dataset(root, &plan.reader, bad)?;
        if d.sequences.is_empty() {
            let root = root.to_path_buf();
            return Err(DataError::NoSequences { root });
        }
        Ok(d)
    };
    let all = read(&plan.train)?;
    let (train, val, test) = match (&plan.val, &plan.test) {
        (Some(v), t) => {
            let test = t.as_deref().map(read).transpose()?.unwrap_or_default();
            (all, read(v)?, test)
        }
        (None, t) => {
            let mut sc = plan.split.clone();
            let test = match t {
                Some(t) => {
                    sc.test_fraction = 0.0;
                    Some(read(t)?)
                }
                None => None,
            };
            let s = split::stratified_split(&all, &sc);
            let test = test.unwrap_or_else(|| split::select(&all, &s.test));
            (
                split::select(&all, &s.train),
                split::select(&all, &s.val),
                test,
            )
        }
    };
    let train = match plan.sequences_per_pair {
        Some(n) => {
            let capped = split::cap_per_pair(&train, n, plan.split.seed);
            tracing::info!(
                "at most {n} training sequence(s) per object-part pair: {} of {} kept",
                capped.sequences.len(),
                train.sequences.len()
            );
            capped
        }
        None => train,
    };
    refuse_test_worlds(&train, "training")?;
    refuse_test_worlds(&val, "validation")?;
    if val.sequences.is_empty() {
        return Err(DataError::EmptyValidation);
    }
    let ids = |d: &Dataset| d.sequences.iter().map(|s| s.id.clone()).collect();
    let split = Split {
        train: ids(&train),
        val: ids(&val),
        test: ids(&test),
    };
    Ok(Splits {
        train,
        val,
        test,
        split,
    })
}

/// A test world (another render world, a held-out reach) measures how a
/// model does where it was never trained or chosen: none of its sequences
/// may train it or pick its checkpoint.
fn refuse_test_worlds(data: &Dataset, split: &str) -> Result<(), DataError> {
    match data.sequences.iter().find(|s| s.test_world.is_some()) {
        Some(s) => Err(DataError::Invalid {
            path: data.root.clone(),
            reason: format!(
                "sequence {} belongs to a test world ({}); the {split} set may only hold \
                 training's own world (render it without configs/test-world-*.toml)",
                s.id,
                s.test_world.as_deref().unwrap_or_default()
            ),
        }),
        None => Ok(()),
    }
}
