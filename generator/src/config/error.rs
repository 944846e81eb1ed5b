//! Why a config is refused ([`ConfigError`]). Every section's check
//! returns it, so it lives apart from `config.rs`, which gathers the
//! sections, and imports nothing of the generator's own.

use std::path::PathBuf;

/// Why a config is refused. Every message names the field (`[section] key`
/// or `plan.section.key`) and, once the whole config is checked, the files.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The files (or `--set` values) do not load: a file that cannot be
    /// read, is not TOML, or a `--set` that does not parse. `config` names
    /// the files; the layer loader's error (which names the file or the
    /// `--set`) is the source.
    #[error("invalid config {config}")]
    Layers {
        config: String,
        #[source]
        source: Box<grasp_support::layers::LayersError>,
    },
    /// The merged table is not a config: an unknown key, a value of the
    /// wrong type.
    #[error("invalid config {config}")]
    Shape {
        config: String,
        #[source]
        source: Box<toml::de::Error>,
    },
    /// The config parses but one of its values is refused.
    #[error("invalid config {config}")]
    Check {
        config: String,
        #[source]
        source: Box<ConfigError>,
    },
    /// A field's value: "FIELD: REASON".
    #[error("{field}: {reason}")]
    Invalid { field: String, reason: String },
    /// A rule a field (with the others it names) must follow: "FIELD RULE",
    /// e.g. "plan.trajectory.fps must be positive, got 0".
    #[error("{field} {rule}")]
    Rule { field: String, rule: String },
    /// A folder a field names that cannot be read.
    #[error("{field}: cannot read {}", path.display())]
    Read {
        field: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A sequence length that gives too few or too many frames.
    #[error("a sequence of {duration_s} s at {fps} fps has {frames} frames; it needs 1 to 10^7")]
    FrameCount {
        duration_s: f64,
        fps: f64,
        frames: f64,
    },
}

pub type Result<T, E = ConfigError> = std::result::Result<T, E>;

impl ConfigError {
    pub(crate) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> Self {
        ConfigError::Invalid {
            field: field.into(),
            reason: reason.into(),
        }
    }

    pub(crate) fn rule(field: impl Into<String>, rule: impl Into<String>) -> Self {
        ConfigError::Rule {
            field: field.into(),
            rule: rule.into(),
        }
    }

    /// Refuses `value` unless it is one of `allowed`: "FIELD: unknown
    /// 'VALUE' (expected a, b or c)". Every named-value field checks so.
    pub(crate) fn check_one_of(
        field: impl Into<String>,
        value: &str,
        allowed: &[&str],
    ) -> Result<()> {
        if allowed.contains(&value) {
            return Ok(());
        }
        let expected = match allowed {
            [] => "nothing".to_string(),
            [only] => (*only).to_string(),
            [init @ .., last] => format!("{} or {last}", init.join(", ")),
        };
        Err(ConfigError::invalid(
            field,
            format!("unknown '{value}' (expected {expected})"),
        ))
    }

    /// The field the error is about, when it is about one.
    pub fn field(&self) -> Option<&str> {
        match self {
            ConfigError::Invalid { field, .. } | ConfigError::Rule { field, .. } => Some(field),
            ConfigError::Check { source, .. } => source.field(),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_one_of_names_the_field_the_value_and_the_choices() {
        assert!(ConfigError::check_one_of(
            "[render] denoiser",
            "none",
            &["openimagedenoise", "none"]
        )
        .is_ok());
        let e =
            ConfigError::check_one_of("[render] denoiser", "oidn", &["openimagedenoise", "none"])
                .unwrap_err();
        assert_eq!(e.field(), Some("[render] denoiser"));
        assert_eq!(
            e.to_string(),
            "[render] denoiser: unknown 'oidn' (expected openimagedenoise or none)"
        );
        let three = ConfigError::check_one_of("f", "x", &["a", "b", "c"]).unwrap_err();
        assert_eq!(three.to_string(), "f: unknown 'x' (expected a, b or c)");
        let one = ConfigError::check_one_of("f", "x", &["a"]).unwrap_err();
        assert_eq!(one.to_string(), "f: unknown 'x' (expected a)");
    }
}
