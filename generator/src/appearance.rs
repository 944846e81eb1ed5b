//! Domain randomization sampling. (Owned by the rendering work; to be filled in.)

use serde::{Deserialize, Serialize};

/// Ranges of the randomized appearance values.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AppearanceConfig {}
