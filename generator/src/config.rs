//! The generator's config file (TOML), shared by `grasp-gen plan` and
//! `grasp-gen render`. Every section has defaults, so an empty file is a
//! valid config; `configs/default.toml` shows them all (a test checks it
//! against the built-in defaults).
//!
//! The sections' error, [`ConfigError`], lives in [`error`]: the sections
//! this file gathers import it from there, not from here.

pub mod error;

pub use error::{ConfigError, Result};

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The config flags of `plan`, `render` and `dataset verify`: files laid
/// over each other, then single values.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ConfigArgs {
    /// Generator config (TOML); defaults apply to missing keys. Repeat to
    /// lay files over each other, a later one winning key by key (a test
    /// set: --config configs/main.toml --config configs/test-look-b.toml).
    #[arg(long, value_name = "FILE")]
    pub config: Vec<PathBuf>,
    /// Overrides one config value after the files: a dotted KEY and a
    /// TOML value, e.g. --set dataset.seed=3 --set 'dataset.conditions=["fast"]'.
    #[arg(long, value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

impl ConfigArgs {
    /// The resolved config.
    pub fn load(&self) -> Result<GeneratorConfig> {
        GeneratorConfig::load_layers(&self.config, &self.set)
    }

    /// Whether any file or value was given.
    pub fn is_given(&self) -> bool {
        !self.config.is_empty() || !self.set.is_empty()
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GeneratorConfig {
    /// What to generate: seed, objects, conditions, sequences per pair.
    pub dataset: crate::plan::DatasetConfig,
    /// Scene, camera and trajectory parameters of the planner.
    pub plan: crate::plan::PlanConfig,
    /// Domain randomization ranges, and the `unseen_look` condition's own.
    pub appearance: crate::appearance::AppearanceConfig,
    /// Training's further randomisation levers, each switchable.
    pub randomize: crate::randomize::RandomizeConfig,
    /// Engine and output settings of the Blender workers.
    pub render: crate::render::RenderConfig,
}

/// The smallest side, in pixels, of the square `[render] center_region`
/// renders.
pub const MIN_CENTER_PX: f64 = 8.0;

impl GeneratorConfig {
    /// Reads a config file; errors name the file and the offending field.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_layers(&[path], &[])
    }

    /// Reads config files laid over each other (a later file wins key by
    /// key) with `--set KEY=VALUE` overrides on top
    /// ([`grasp_support::layers`]); no files give the defaults. Errors name
    /// the files and the offending field.
    pub fn load_layers<P: AsRef<Path>>(files: &[P], sets: &[String]) -> Result<Self> {
        let source = grasp_support::layers::describe(files, sets, "the default config");
        let table = grasp_support::layers::load(files, sets).map_err(|e| ConfigError::Layers {
            config: source.clone(),
            source: Box::new(e),
        })?;
        let config: GeneratorConfig =
            toml::Value::Table(table)
                .try_into()
                .map_err(|e| ConfigError::Shape {
                    config: source.clone(),
                    source: Box::new(e),
                })?;
        config.validate().map_err(|e| ConfigError::Check {
            config: source,
            source: Box::new(e),
        })?;
        Ok(config)
    }

    /// Checks every section, and that the `unseen_look` condition's values
    /// stay out of training's reach.
    pub fn validate(&self) -> Result<()> {
        self.plan.validate()?;
        self.appearance.validate()?;
        self.randomize.validate()?;
        self.render.validate()?;
        self.check_center_region()?;
        self.check_world()?;
        crate::randomize::check_unseen_disjoint(
            &self.appearance.unseen_look,
            &self.appearance,
            &self.randomize,
            &self.render.view_transform,
        )
    }

    /// `[render] center_region` leaves at least [`MIN_CENTER_PX`] pixels of
    /// the wrist camera's shorter side (Blender refuses a smaller border:
    /// "Image too small").
    pub fn check_center_region(&self) -> Result<()> {
        let [w, h] = self.plan.camera.resolution;
        let side = self.render.center_region * f64::from(w.min(h));
        if side < MIN_CENTER_PX {
            return Err(ConfigError::rule(
                "[render] center_region",
                format!(
                    "= {} renders a square of {side:.3} pixels of the {w}x{h} frames; \
                     it must span at least {MIN_CENTER_PX} pixels (at least {:.4} here)",
                    grasp_support::num(self.render.center_region),
                    MIN_CENTER_PX / f64::from(w.min(h))
                ),
            ));
        }
        Ok(())
    }

    /// What `[render] world` needs of the other sections: the foreign
    /// world draws the wrist camera only.
    pub fn check_world(&self) -> Result<()> {
        if self.render.world != crate::render::World::Studio && self.plan.head_camera.enabled {
            return Err(ConfigError::rule("[render] world", format!("= \"{}\" renders the wrist camera only; [plan.head_camera] enabled must be false", self.render.world.name())));
        }
        Ok(())
    }
}
