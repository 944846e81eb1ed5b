//! Checks shared by the look's config sections: value ranges and the names
//! of the bundled world HDRIs.

use crate::config::error::{ConfigError, Result};

/// The world HDRIs shipped in the bpy wheel
/// (`bpy/5.0/datafiles/studiolights/world/*.exr`, CC0, Poly Haven).
pub const BUNDLED_HDRIS: [&str; 8] = [
    "city",
    "courtyard",
    "forest",
    "interior",
    "night",
    "studio",
    "sunrise",
    "sunset",
];

/// A `[lo, hi]` range check naming the field.
pub(crate) fn check_range(field: &str, [lo, hi]: [f64; 2], min: f64, max: f64) -> Result<()> {
    if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= min && hi <= max) {
        return Err(ConfigError::invalid(
            field,
            format!("need a range [min, max] within [{min}, {max}], got [{lo}, {hi}]"),
        ));
    }
    Ok(())
}

/// Checks a list of bundled HDRI names.
pub(crate) fn check_hdris(field: &str, hdris: &[String]) -> Result<()> {
    if hdris.is_empty() {
        return Err(ConfigError::invalid(field, "the list is empty"));
    }
    for h in hdris {
        if !BUNDLED_HDRIS.contains(&h.as_str()) {
            return Err(ConfigError::invalid(
                field,
                format!(
                    "'{h}' is not one of the bpy wheel's studio-light worlds ({})",
                    BUNDLED_HDRIS.join(", ")
                ),
            ));
        }
    }
    Ok(())
}
