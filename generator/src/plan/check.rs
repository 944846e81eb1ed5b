//! Every check of a config before planning, in one place so `plan`,
//! `render` and `dataset verify --config` agree. It lives in `plan` rather
//! than in `config`, which only reads and validates the sections: the
//! selection and size checks need the catalog and the planner's pair
//! selection, and `config` must not import the planner back.

use super::error::{PlanError, Result};
use super::{budget, selection};
use crate::catalog::Catalog;
use crate::config::GeneratorConfig;

/// Every check before planning: each section's values, the selection
/// against the catalog (unknown object ids and parts, with near matches)
/// and the size limits of [`crate::plan::budget`].
pub fn check(config: &GeneratorConfig, catalog: &Catalog) -> Result<()> {
    config.plan.validate().map_err(PlanError::PlanSection)?;
    config.appearance.validate()?;
    config.render.validate()?;
    config.check_world()?;
    selection::check_selection(&config.dataset, catalog)?;
    let pairs = selection::pair_count(&config.dataset, catalog);
    budget::check_size(&config.dataset, &config.plan, pairs)
}
