//! Rendering orchestration with headless Blender workers.
//!
//! `grasp-gen render` plans sequences in this process and hands them to N
//! worker processes (`grasp-gen worker`, the same binary), each embedding
//! Python with `bpy` imported once and the scene built once. Parent and
//! workers talk JSON lines over pipes ([`protocol`]); finished sequences are
//! moved into the dataset atomically ([`crate::dataset::writer`]).

pub mod consistency;
pub mod device;
pub mod effects;
pub mod engine;
pub mod error;
pub mod orchestrator;
pub mod parts;
pub mod planner_source;
pub mod protocol;
pub mod scene;
pub mod source;
pub mod worker;

use crate::config::error::{ConfigError, Result};
use grasp_schema::dataset::{CENTER_REGION_KEY, WORLD_KEY};
use serde::{Deserialize, Serialize};

pub use crate::dataset::shard::Shard;
pub use device::Device;
pub use engine::Engine;
pub use error::RenderError;
pub use orchestrator::{render, RenderOptions, RenderSummary};
pub use scene::SceneGeometry;
pub use source::RenderSource;

/// Which scene builder and render path draws the frames (`[render] world`).
/// Only pixels depend on it: plans, labels and every random draw of the
/// planner are the same in every world.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum World {
    /// Training's scene (`blender_scripts/worker.py`): the room, looks and
    /// levers every training set is drawn from.
    #[default]
    Studio,
    /// A foreign test world (`blender_scripts/foreign/`): its own room,
    /// table, materials, lights, camera model and Cycles integrator, which
    /// no training set may draw from. It ignores the plan's appearance.
    Foreign,
}

impl World {
    /// The name in configs and records.
    pub fn name(self) -> &'static str {
        match self {
            World::Studio => "studio",
            World::Foreign => "foreign",
        }
    }

    /// The Python module whose `Worker` builds this world's scene.
    pub fn worker_module(self) -> &'static str {
        match self {
            World::Studio => "blender_scripts.worker",
            World::Foreign => "blender_scripts.foreign.worker",
        }
    }

    /// Whether a training set may be drawn from it: only the studio. The
    /// world is recorded in every `sequence.json` (`render.world`,
    /// [`grasp_schema::dataset::WORLD_KEY`]) so a trainer can refuse the others.
    pub fn trainable(self) -> bool {
        self == World::Studio
    }
}

/// Image passes a sequence can carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Pass {
    Rgb,
    /// Camera distance, in a multilayer EXR next to each PNG.
    Depth,
    /// Object index (1 object, 2 hand, 3 table), in the same EXR.
    Instance,
    /// Which grasp part of the object each pixel shows, as `partNNNNN.png`
    /// (computed in Rust from the depth; see [`parts`]).
    Part,
}

/// Cycles light bounces.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Bounces {
    pub total: u32,
    pub diffuse: u32,
    pub glossy: u32,
    pub transmission: u32,
    pub transparent: u32,
}

impl Default for Bounces {
    fn default() -> Self {
        Bounces {
            total: 3,
            diffuse: 2,
            glossy: 1,
            transmission: 1,
            transparent: 2,
        }
    }
}

/// Engine and output settings (`[render]` in the config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderConfig {
    /// The scene builder and render path: `studio` (training's, the
    /// default) or `foreign` (a test world training never draws from).
    pub world: World,
    pub engine: Engine,
    /// Where Cycles renders: `auto` (a GPU backend Blender reports, else the
    /// CPU), `cpu`, or one GPU backend. It changes how pixels are computed,
    /// never the plans, labels or random draws.
    pub device: Device,
    /// Samples per pixel (Cycles, EEVEE); Workbench uses 8x anti-aliasing at
    /// 8 or more, none below.
    pub samples: u32,
    /// `openimagedenoise` or `none` (Cycles).
    pub denoiser: String,
    /// OpenImageDenoise prefilter of the albedo and normal guides: `none`,
    /// `fast` or `accurate`.
    pub denoising_prefilter: String,
    /// OpenImageDenoise's network: `high` (Blender's default), `balanced`
    /// or `fast`, each faster and a little blurrier than the one before.
    pub denoising_quality: String,
    /// Cycles adaptive-sampling noise threshold; 0 disables it.
    pub adaptive_threshold: f64,
    pub bounces: Bounces,
    /// Clamp of indirect light, which removes fireflies at few samples.
    pub clamp_indirect: f64,
    pub passes: Vec<Pass>,
    /// `part` pass: a point this far outside a part's box still gets its
    /// label, metres (boxes are annotated on the surface, not around it).
    pub part_tolerance_m: f64,
    /// Blender view transform: `AgX` (filmic, the default) or `Standard`.
    pub view_transform: String,
    /// Render threads per worker; 0 lets Blender use every core.
    pub threads: u32,
    /// Render all frames of a sequence in one animation call (keeps Cycles'
    /// scene in memory between frames) instead of one call per frame.
    pub one_call: bool,
    /// PNG compression, 0 to 100.
    pub png_compression: u32,
    /// Side of the centred square that is rendered, as a fraction of the
    /// image's shorter side; outside it frames stay black. 1 renders the
    /// whole frame. A model that sees only the centre (`grasp-train
    /// --center-crop`) needs no more, and Cycles' cost scales with pixels.
    pub center_region: f64,
    /// Worker processes (the `--workers` flag overrides it).
    pub workers: usize,
    /// A worker is restarted after this many sequences (Blender's memory
    /// grows in long runs).
    pub recycle_every: usize,
    /// Attempts after the first for a sequence whose worker failed.
    pub max_retries: u32,
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            world: World::Studio,
            engine: Engine::Cycles,
            device: Device::Auto,
            samples: 4,
            denoiser: "openimagedenoise".into(),
            denoising_prefilter: "fast".into(),
            denoising_quality: "high".into(),
            adaptive_threshold: 0.0,
            bounces: Bounces::default(),
            clamp_indirect: 3.0,
            passes: vec![Pass::Rgb],
            part_tolerance_m: 0.005,
            view_transform: "AgX".into(),
            threads: 0,
            one_call: true,
            png_compression: 15,
            center_region: 1.0,
            workers: 1,
            recycle_every: 50,
            max_retries: 2,
        }
    }
}

impl RenderConfig {
    /// Checks values; errors name the `[render]` field.
    pub fn validate(&self) -> Result<()> {
        if self.samples == 0 {
            return Err(ConfigError::invalid(
                "[render] samples",
                "must be at least 1",
            ));
        }
        if self.device.is_gpu() && self.engine != Engine::Cycles {
            return Err(ConfigError::rule("[render] device", format!("= \"{}\" chooses a Cycles device, but engine is {:?}, which draws through Blender's GPU module (use device = \"auto\")", self.device.name(), format!("{:?}", self.engine).to_lowercase())));
        }
        ConfigError::check_one_of(
            "[render] denoiser",
            &self.denoiser,
            &["openimagedenoise", "none"],
        )?;
        ConfigError::check_one_of(
            "[render] denoising_prefilter",
            &self.denoising_prefilter,
            &["none", "fast", "accurate"],
        )?;
        ConfigError::check_one_of(
            "[render] denoising_quality",
            &self.denoising_quality,
            &["high", "balanced", "fast"],
        )?;
        ConfigError::check_one_of(
            "[render] view_transform",
            &self.view_transform,
            &crate::look::unseen_config::VIEW_TRANSFORMS,
        )?;
        if !self.passes.contains(&Pass::Rgb) {
            return Err(ConfigError::invalid(
                "[render] passes",
                "must include \"rgb\"",
            ));
        }
        if self.png_compression > 100 {
            return Err(ConfigError::invalid(
                "[render] png_compression",
                "must be 0 to 100",
            ));
        }
        if !(self.center_region > 0.0 && self.center_region <= 1.0) {
            return Err(ConfigError::invalid(
                "[render] center_region",
                format!(
                    "must be in (0, 1], got {}",
                    grasp_support::num(self.center_region)
                ),
            ));
        }
        if self.center_region < 1.0 && self.passes != [Pass::Rgb] {
            return Err(ConfigError::rule("[render] center_region", format!("{} renders only part of each frame; the depth, instance and part passes need whole frames (use passes = [\"rgb\"] or center_region = 1)", self.center_region)));
        }
        if self.world == World::Foreign {
            if self.engine != Engine::Cycles {
                return Err(ConfigError::rule("[render] world", format!("= \"foreign\" renders with its own Cycles integrator; engine must be \"cycles\", got \"{}\"", format!("{:?}", self.engine).to_lowercase())));
            }
            if self.passes != [Pass::Rgb] {
                return Err(ConfigError::rule("[render] world", "= \"foreign\" distorts its frames through a lens model, so depth, instance and part images would not match them; use passes = [\"rgb\"]"));
            }
        }
        if self.workers == 0 || self.recycle_every == 0 {
            return Err(ConfigError::rule(
                "[render] workers",
                "and recycle_every must be at least 1",
            ));
        }
        if !(self.part_tolerance_m >= 0.0 && self.part_tolerance_m < 0.1) {
            return Err(ConfigError::invalid(
                "[render] part_tolerance_m",
                format!("must be in [0, 0.1) metres, got {}", self.part_tolerance_m),
            ));
        }
        if !(self.adaptive_threshold >= 0.0 && self.clamp_indirect >= 0.0) {
            return Err(ConfigError::rule(
                "[render] adaptive_threshold",
                "and clamp_indirect must be >= 0",
            ));
        }
        Ok(())
    }

    /// The settings the Blender side reads (`blender_scripts/render.py`);
    /// also recorded in every `sequence.json`. Orchestration-only fields
    /// (workers, recycling, retries) are left out: they do not change pixels.
    pub fn blender_settings(&self) -> serde_json::Value {
        let prefilter = self.denoising_prefilter.to_ascii_uppercase();
        let mut settings = serde_json::json!({
            WORLD_KEY: self.world,
            "engine": self.engine,
            "device": self.device,
            "samples": self.samples,
            "denoiser": self.denoiser,
            "denoising_prefilter": prefilter,
            "adaptive_threshold": self.adaptive_threshold,
            "bounces": self.bounces,
            "clamp_indirect": self.clamp_indirect,
            "passes": self.passes,
            "part_tolerance_m": self.part_tolerance_m,
            "view_transform": self.view_transform,
            "threads": self.threads,
            "one_call": self.one_call,
            "png_compression": self.png_compression,
            "blender": "5.0",
        });
        // Recorded only when it crops, so records of whole frames written
        // before the field existed compare equal.
        if self.center_region < 1.0 {
            settings[CENTER_REGION_KEY] = self.center_region.into();
        }
        // Recorded only when not Blender's default, likewise.
        if self.denoising_quality != "high" {
            settings["denoising_quality"] = self.denoising_quality.to_ascii_uppercase().into();
        }
        settings
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_cycles_rgb() {
        let c = RenderConfig::default();
        c.validate().unwrap();
        let s = c.blender_settings();
        assert_eq!(s["engine"], "cycles");
        assert_eq!(s["passes"], serde_json::json!(["rgb"]));
        assert_eq!(s["denoising_prefilter"], "FAST");
        assert!(s.get("denoising_quality").is_none());
    }

    #[test]
    fn denoising_quality_is_checked_and_recorded_upper_case() {
        let fast = RenderConfig {
            denoising_quality: "fast".into(),
            ..RenderConfig::default()
        };
        fast.validate().unwrap();
        assert_eq!(fast.blender_settings()["denoising_quality"], "FAST");
        let bad = RenderConfig {
            denoising_quality: "best".into(),
            ..RenderConfig::default()
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(
            err.contains("denoising_quality") && err.contains("best"),
            "{err}"
        );
    }

    #[test]
    fn center_region_is_recorded_only_when_it_crops() {
        let whole = RenderConfig::default();
        assert!(whole.blender_settings().get(CENTER_REGION_KEY).is_none());
        let part = RenderConfig {
            center_region: 0.5,
            ..Default::default()
        };
        part.validate().unwrap();
        assert_eq!(part.blender_settings()[CENTER_REGION_KEY], 0.5);
        for bad in [0.0, 1.5, f64::NAN] {
            let c = RenderConfig {
                center_region: bad,
                ..Default::default()
            };
            let e = format!("{:#}", c.validate().unwrap_err());
            assert!(e.contains("[render] center_region"), "{e}");
        }
        let with_depth = RenderConfig {
            passes: vec![Pass::Rgb, Pass::Depth],
            ..part
        };
        let e = format!("{:#}", with_depth.validate().unwrap_err());
        assert!(e.contains("need whole frames"), "{e}");
    }

    #[test]
    fn config_parses_and_rejects_unknown_fields() {
        let c: RenderConfig =
            toml::from_str("engine = \"workbench\"\npasses = [\"rgb\", \"depth\"]").unwrap();
        assert_eq!(c.engine, Engine::Workbench);
        assert_eq!(c.passes, vec![Pass::Rgb, Pass::Depth]);
        assert!(toml::from_str::<RenderConfig>("sample = 3").is_err());
        let bad = RenderConfig {
            denoiser: "optix".into(),
            ..Default::default()
        };
        assert!(format!("{:#}", bad.validate().unwrap_err()).contains("[render] denoiser"));
    }
}
