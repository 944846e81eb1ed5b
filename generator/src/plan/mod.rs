//! Reach planning: turns (dataset seed, object, part, index, condition) into a
//! `SequencePlan`. (Owned by the planning work; to be filled in.)

use serde::{Deserialize, Serialize};

/// What to generate.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DatasetConfig {}

/// Scene, camera and trajectory parameters.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlanConfig {}
