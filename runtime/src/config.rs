//! `hannes-run` config file (TOML). Every field is optional; command-line
//! flags override the file. Example:
//!
//! ```toml
//! [policy]
//! window_s = 2.0
//! early_margin = 8
//! fallback = "power"      # omit the key to send nothing on low confidence
//! on_invalid = "abort"
//! max_decision_age_ms = 300   # older decisions are never executed
//!
//! [link]
//! ack_timeout_ms = 100
//! retries = 3
//! heartbeat_interval_ms = 200
//! watchdog_ms = 1000
//! ```

use crate::link::LinkConfig;
use crate::policy::PolicyConfig;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Why a config file was not used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Not TOML, an unknown field, a value of the wrong type.
    #[error("invalid config {}", path.display())]
    Parse {
        path: PathBuf,
        #[source]
        source: toml::de::Error,
    },
    /// Read, but a setting is outside its range.
    #[error("invalid config {}", path.display())]
    Invalid {
        path: PathBuf,
        #[source]
        source: InvalidSetting,
    },
}

/// The settings' error and check, from `grasp-policy` (the runtime's own
/// sections, such as `[link]`, import them from there).
pub use grasp_policy::setting::{ensure, InvalidSetting};

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RuntimeConfig {
    pub policy: PolicyConfig,
    pub link: LinkConfig,
}

impl RuntimeConfig {
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let path_buf = || path.to_path_buf();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path_buf(),
            source,
        })?;
        let cfg: RuntimeConfig = toml::from_str(&text).map_err(|source| ConfigError::Parse {
            path: path_buf(),
            source,
        })?;
        cfg.validate().map_err(|source| ConfigError::Invalid {
            path: path_buf(),
            source,
        })?;
        Ok(cfg)
    }

    pub fn validate(&self) -> Result<(), InvalidSetting> {
        self.policy.validate()?;
        self.link.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grasp_schema::taxonomy::Preshape;

    #[test]
    fn reads_partial_files_and_names_bad_fields() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("run.toml");
        std::fs::write(&p, "[policy]\nearly_margin = 5\nfallback = \"lateral\"\n").unwrap();
        let cfg = RuntimeConfig::load(&p).unwrap();
        assert_eq!(cfg.policy.early_margin, Some(5));
        assert_eq!(cfg.policy.fallback, Some(Preshape::Lateral));
        assert_eq!(cfg.link.retries, LinkConfig::default().retries);

        std::fs::write(&p, "[policy]\nwindow = 2\n").unwrap();
        let err = grasp_support::error_chain(&RuntimeConfig::load(&p).unwrap_err());
        assert!(err.contains("window") && err.contains("run.toml"), "{err}");

        std::fs::write(
            &p,
            "[link]\nheartbeat_interval_ms = 900\nwatchdog_ms = 1000\n",
        )
        .unwrap();
        let err = grasp_support::error_chain(&RuntimeConfig::load(&p).unwrap_err());
        assert!(err.contains("heartbeat_interval_ms"), "{err}");
    }
}
