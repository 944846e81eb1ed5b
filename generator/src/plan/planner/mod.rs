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
use crate::catalog::validate::touch;
use crate::catalog::{Catalog, ObjectSpec};
use crate::config::GeneratorConfig;
use crate::plan::error::{PlanError, Result};
use crate::randomize::{self, ApproachDraw};
use grasp_schema::plan::{CameraIntrinsics, SequenceKey, SequencePlan};
use grasp_schema::Condition;
use nalgebra::Vector3;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

/// Plans sequences. Holds each object's mesh query.
pub struct Planner {
    config: GeneratorConfig,
    objects: BTreeMap<String, ObjectGeometry>,
    /// The other members of the objects' families of shapes
    /// (`[randomize.profiles]`), built when a sequence first draws one.
    members: RefCell<BTreeMap<(String, u32), Rc<ObjectGeometry>>>,
    /// `[appearance] image_dir`'s textures, listed once.
    images: Vec<String>,
    /// `[randomize]` as it acts (every lever off with its master switch off).
    levers: crate::randomize::RandomizeConfig,
}

/// The planner's geometry of member `member` of an object's family of
/// shapes (0: its model), with its mesh query. Another member must touch
/// every part box of the catalog, as `grasp-gen objects validate` checks
/// the model.
fn geometry(object: &ObjectSpec, member: u32) -> Result<ObjectGeometry> {
    let mesh = object.member_mesh(member).map_err(|e| PlanError::Mesh {
        object: object.id.clone(),
        source: Box::new(e),
    })?;
    let query_error = |source| PlanError::MeshQuery {
        object: object.id.clone(),
        source,
    };
    let query = crate::geometry::MeshQuery::new(&mesh).map_err(query_error)?;
    if member > 0 {
        let mut hull = None;
        for part in &object.parts {
            if touch(part, &mesh, &query, &mut hull)
                .map_err(query_error)?
                .is_none()
            {
                return Err(PlanError::BadObject {
                    object: object.id.clone(),
                    part: Some(part.name.clone()),
                    reason: format!(
                        "member {member} of its family of shapes ([randomize.profiles]) does not \
                         touch the part's box"
                    ),
                });
            }
        }
    }
    ObjectGeometry::new(object.clone(), &mesh, Box::new(query))
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
    /// `[randomize.profiles]`'s member of the object's family (0 with the
    /// lever off, or for an object with one member).
    shape_member: u32,
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
            geometries.push(geometry(object, 0)?);
        }
        Planner::from_geometries(config, geometries)
    }

    /// A planner over prepared geometries (any [`RayCaster`]).
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
            members: RefCell::default(),
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
        if !geo.spec.mesh.has_profiles() {
            draws.shape_member = 0;
        }
        let member;
        let geo = match draws.shape_member {
            0 => geo,
            m => {
                member = self.member(&geo.spec, m)?;
                &*member
            }
        };
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
            shape_member: randomize::profile_member(r, stream),
        }
    }

    /// Member `m` of the object's family of shapes, built once.
    fn member(&self, spec: &ObjectSpec, m: u32) -> Result<Rc<ObjectGeometry>> {
        let key = (spec.id.clone(), m);
        if let Some(g) = self.members.borrow().get(&key) {
            return Ok(g.clone());
        }
        let g = Rc::new(geometry(spec, m)?);
        self.members.borrow_mut().insert(key, g.clone());
        Ok(g)
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
