//! The planner: scene sampling, the validity search and frame generation.
//!
//! * `object_geometry`: what the planner knows of each object.
//! * `search`: candidate scenes and the validity search.
//! * `assemble`: an accepted scene made into a `SequencePlan`.

mod assemble;
mod object_geometry;
mod search;

pub use object_geometry::ObjectGeometry;

use super::selection::selected_pairs;
use crate::catalog::Catalog;
use crate::config::GeneratorConfig;
use crate::plan::error::{PlanError, Result};
use crate::randomize::{self, ApproachDraw};
use grasp_schema::plan::{CameraIntrinsics, SequenceKey, SequencePlan};
use grasp_schema::Condition;
use nalgebra::Vector3;
use std::collections::BTreeMap;

/// Plans sequences. Holds each object's mesh query.
pub struct Planner {
    config: GeneratorConfig,
    objects: BTreeMap<String, ObjectGeometry>,
    /// `[appearance] image_dir`'s textures, listed once.
    images: Vec<String>,
    /// `[randomize]` as it acts (every lever off with its master switch off).
    levers: crate::randomize::RandomizeConfig,
}

/// Every sequence the config asks for, in a deterministic order (pair,
/// condition, index).
pub fn sequence_keys(config: &GeneratorConfig, catalog: &Catalog) -> Vec<SequenceKey> {
    let d = &config.dataset;
    let mut keys = Vec::new();
    for (object, part) in selected_pairs(&config.dataset, catalog) {
        for &condition in &d.conditions {
            for index in 0..d.sequences_per_pair {
                keys.push(SequenceKey {
                    object: object.id.clone(),
                    part: part.name.clone(),
                    index,
                    condition,
                });
            }
        }
    }
    keys
}

/// The values of a sequence drawn before its search: the lens and the
/// approach levers.
struct SequenceDraws {
    intrinsics: CameraIntrinsics,
    fov_scale: f64,
    principal_point_shift: [f64; 2],
    approach: ApproachDraw,
    /// `[randomize.proportions]`'s per-axis factors ([1, 1, 1] with the
    /// lever off).
    proportions: [f64; 3],
}

impl Planner {
    /// Builds mesh queries (trimesh) for every object the config selects.
    pub fn new(config: &GeneratorConfig, catalog: &Catalog) -> Result<Planner> {
        config.plan.validate()?;
        let mut geometries = Vec::new();
        let mut seen = std::collections::BTreeSet::new();
        for (object, _) in selected_pairs(&config.dataset, catalog) {
            if !seen.insert(object.id.clone()) {
                continue;
            }
            let mesh = object.mesh().map_err(|e| PlanError::Mesh {
                object: object.id.clone(),
                source: Box::new(e),
            })?;
            let query =
                crate::geometry::MeshQuery::new(&mesh).map_err(|source| PlanError::MeshQuery {
                    object: object.id.clone(),
                    source,
                })?;
            geometries.push(ObjectGeometry::new(object.clone(), &mesh, Box::new(query))?);
        }
        Planner::from_geometries(config, geometries)
    }

    /// A planner over prepared geometries (any [`RayCaster`](crate::plan::validity::RayCaster)).
    pub fn from_geometries(
        config: &GeneratorConfig,
        objects: Vec<ObjectGeometry>,
    ) -> Result<Planner> {
        config.validate()?;
        Ok(Planner {
            config: config.clone(),
            objects: objects
                .into_iter()
                .map(|g| (g.spec.id.clone(), g))
                .collect(),
            images: config.appearance.images()?,
            levers: config.randomize.effective(),
        })
    }

    pub fn config(&self) -> &GeneratorConfig {
        &self.config
    }

    pub fn object(&self, id: &str) -> Option<&ObjectGeometry> {
        self.objects.get(id)
    }

    /// Plans one sequence: a pure function of the key, the dataset seed and
    /// the config.
    pub fn plan(&self, key: &SequenceKey) -> Result<SequencePlan> {
        let geo = self
            .objects
            .get(&key.object)
            .ok_or_else(|| PlanError::UnknownObject {
                object: key.object.clone(),
                known: Some(self.objects.keys().cloned().collect::<Vec<_>>().join(", ")),
            })?;
        let (part_index, part) = geo
            .spec
            .parts
            .iter()
            .enumerate()
            .find(|(_, p)| p.name == key.part)
            .ok_or_else(|| PlanError::UnknownPart {
                object: key.object.clone(),
                part: key.part.clone(),
                quoted: false,
                parts: Some(
                    geo.spec
                        .parts
                        .iter()
                        .map(|p| p.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", "),
                ),
            })?;
        let stream = key.stream_seed(self.config.dataset.seed);
        let mut draws = self.sequence_draws(key.condition, stream);
        if !geo.spec.mesh.is_procedural() {
            // A mesh from a file is a real object, not a family's model:
            // its proportions are its own (the YCB meshes of a test world).
            draws.proportions = [1.0; 3];
        }
        let resized;
        let geo = if draws.proportions == [1.0; 3] {
            geo
        } else {
            resized = geo.stretched(Vector3::from(draws.proportions));
            &resized
        };
        let accepted = self
            .search(geo, part_index, key.condition, stream, &draws)
            .map_err(|e| PlanError::Planning {
                id: key.id(),
                source: Box::new(e),
            })?;
        self.build_plan(key, geo, part_index, part, stream, &draws, accepted)
    }

    /// The lens (`[randomize.fov]`, or `unseen_look`'s own, and the
    /// principal point) and the approach levers of a sequence, each from its
    /// own sub-stream.
    fn sequence_draws(&self, condition: Condition, stream: u64) -> SequenceDraws {
        let r = &self.levers;
        let (intrinsics, fov_scale, principal_point_shift) = self.lens(condition, stream);
        SequenceDraws {
            intrinsics,
            fov_scale,
            principal_point_shift,
            approach: randomize::approach(r, self.config.plan.trajectory.standoff_m, stream),
            proportions: randomize::proportions(r, stream),
        }
    }

    /// The lens of a sequence drawn from `stream`: its intrinsics, lens
    /// factor and principal-point shift.
    fn lens(&self, condition: Condition, stream: u64) -> (CameraIntrinsics, f64, [f64; 2]) {
        let r = &self.levers;
        let fov = if condition == Condition::UnseenLook {
            Some(self.config.appearance.unseen_look.fov_scale)
        } else {
            r.fov.enabled.then_some(r.fov.scale)
        };
        let shift = r
            .principal_point
            .enabled
            .then_some(r.principal_point.max_shift);
        let base = self.config.plan.camera.intrinsics();
        randomize::intrinsics(&base, fov, shift, stream)
    }
}
