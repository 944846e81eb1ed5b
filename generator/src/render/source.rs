//! What rendering needs besides the plans ([`crate::plan::PlanSource`]):
//! the object meshes, their part boxes and the scene. The real source is
//! the catalog and the planner (`planner_source`); [`StaticSource`] renders
//! given plans.

use super::error::{RenderError, Result};
use super::parts::PartBox;
use super::SceneGeometry;
use crate::plan::{PlanError, PlanSource, PlannedKey};
use grasp_schema::{SequenceKey, SequencePlan};
use std::collections::BTreeMap;

/// A triangle mesh in the object frame (Z up, origin at the bottom centre).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<[f64; 3]>,
    pub faces: Vec<[u32; 3]>,
}

/// A plan source that can also give what the renderer draws.
pub trait RenderSource: PlanSource {
    fn mesh(&self, object: &str) -> Result<Mesh>;
    fn scene(&self) -> SceneGeometry;
    /// The object's grasp-part boxes in catalog order (the `part` pass).
    fn parts(&self, object: &str) -> Result<Vec<PartBox>>;
    /// The object's own colour (linear RGB), used when the plan keeps it.
    fn object_color(&self, object: &str) -> [f64; 3] {
        crate::appearance::default_object_color(object)
    }
    /// The real object's plausible colours (the catalog's `color`), from
    /// which a foreign world draws its own; `None` when unknown.
    fn object_color_range(&self, _object: &str) -> Option<crate::catalog::ColorRange> {
        None
    }
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
    fn keys(&self) -> crate::plan::error::Result<Vec<PlannedKey>> {
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

    fn plan(&self, key: &SequenceKey) -> crate::plan::error::Result<SequencePlan> {
        self.plans
            .iter()
            .find(|p| &p.key == key)
            .cloned()
            .ok_or_else(|| PlanError::NoPlan { id: key.id() })
    }
}

impl RenderSource for StaticSource {
    fn mesh(&self, object: &str) -> Result<Mesh> {
        match self.meshes.get(object) {
            Some(m) => Ok(m.clone()),
            None => Err(RenderError::NoObjectData {
                what: "mesh",
                object: object.to_string(),
            }),
        }
    }

    fn scene(&self) -> SceneGeometry {
        self.scene.clone()
    }

    fn parts(&self, object: &str) -> Result<Vec<PartBox>> {
        match self.parts.get(object) {
            Some(p) => Ok(p.clone()),
            None => Err(RenderError::NoObjectData {
                what: "part boxes",
                object: object.to_string(),
            }),
        }
    }
}
