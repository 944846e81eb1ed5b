//! Where the sequences to render come from: their keys in canonical order,
//! their plans, the object meshes and the scene. The real source wraps the
//! catalog and the planner; [`StaticSource`] renders given plans.

use super::parts::PartBox;
use super::SceneGeometry;
use anyhow::{bail, Context, Result};
use grasp_schema::taxonomy::Preshape;
use grasp_schema::{SequenceKey, SequencePlan};
use std::collections::BTreeMap;

/// A key with what the dataset layout needs before planning.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedKey {
    pub key: SequenceKey,
    pub category: String,
    pub preshape: Preshape,
}

/// A triangle mesh in the object frame (Z up, origin at the bottom centre).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<[f64; 3]>,
    pub faces: Vec<[u32; 3]>,
}

pub trait PlanSource: Send + Sync {
    /// Every sequence of the dataset, in canonical order. Folder numbers and
    /// shards derive from positions in this list, so it must not depend on
    /// the shard or on what is already rendered.
    fn keys(&self) -> Result<Vec<PlannedKey>>;
    fn plan(&self, key: &SequenceKey) -> Result<SequencePlan>;
    fn mesh(&self, object: &str) -> Result<Mesh>;
    fn scene(&self) -> SceneGeometry;
    /// The object's grasp-part boxes in catalog order (the `part` pass).
    fn parts(&self, object: &str) -> Result<Vec<PartBox>>;
    /// The object's own colour (linear RGB), used when the plan keeps it.
    fn object_color(&self, object: &str) -> [f64; 3] {
        default_object_color(object)
    }
}

/// A stable, muted colour per object id (the catalog carries no materials):
/// a hue from a hash of the id.
pub fn default_object_color(object: &str) -> [f64; 3] {
    let [h, s, v] = default_object_hsv(object);
    crate::appearance::hsv_to_linear_rgb(h, s, v)
}

/// [`default_object_color`] as HSV (of its sRGB colour).
pub fn default_object_hsv(object: &str) -> [f64; 3] {
    let hash = object.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    [(hash % 360) as f64 / 360.0, 0.55, 0.75]
}

/// Renders a fixed set of plans with given meshes (tests, re-renders).
pub struct StaticSource {
    pub plans: Vec<SequencePlan>,
    pub meshes: BTreeMap<String, Mesh>,
    /// Part boxes per object (needed only for the `part` pass).
    pub parts: BTreeMap<String, Vec<PartBox>>,
    pub scene: SceneGeometry,
}

impl PlanSource for StaticSource {
    fn keys(&self) -> Result<Vec<PlannedKey>> {
        Ok(self
            .plans
            .iter()
            .map(|p| PlannedKey {
                key: p.key.clone(),
                category: p.category.clone(),
                preshape: p.preshape,
            })
            .collect())
    }

    fn plan(&self, key: &SequenceKey) -> Result<SequencePlan> {
        self.plans
            .iter()
            .find(|p| &p.key == key)
            .cloned()
            .with_context(|| format!("no plan for sequence {}", key.id()))
    }

    fn mesh(&self, object: &str) -> Result<Mesh> {
        match self.meshes.get(object) {
            Some(m) => Ok(m.clone()),
            None => bail!("no mesh for object '{object}'"),
        }
    }

    fn scene(&self) -> SceneGeometry {
        self.scene.clone()
    }

    fn parts(&self, object: &str) -> Result<Vec<PartBox>> {
        match self.parts.get(object) {
            Some(p) => Ok(p.clone()),
            None => bail!("no part boxes for object '{object}'"),
        }
    }
}
