//! One object's geometry as the planner needs it: the mesh query, extents,
//! bounding sphere, part boxes and a silhouette outline, at catalog size or
//! stretched by `[randomize.proportions]`.

use crate::catalog::{GraspPart, ObjectSpec, TriMesh};
use crate::plan::error::{PlanError, Result};
use crate::plan::validity::{Obb, RayCaster, ScaledCaster};
use crate::plan::wrist;
use nalgebra::Vector3;
use std::rc::Rc;

/// One object's geometry as the planner needs it.
pub struct ObjectGeometry {
    pub spec: ObjectSpec,
    /// Ray casts against the object's mesh (object frame).
    pub caster: Rc<dyn RayCaster>,
    /// Extent of the mesh along the object's Z (min, max).
    pub z_range: [f64; 2],
    /// Bounding sphere of the mesh (object frame).
    pub sphere_center: Vector3<f64>,
    pub sphere_radius: f64,
    /// The parts' boxes, in the catalog's part order (object frame).
    pub boxes: Vec<Obb>,
    /// Up to 6000 mesh triangles, for drawing the object's silhouette.
    pub outline: Vec<[Vector3<f64>; 3]>,
}

impl ObjectGeometry {
    pub fn new(spec: ObjectSpec, mesh: &TriMesh, caster: Box<dyn RayCaster>) -> Result<Self> {
        if mesh.vertices.is_empty() {
            return Err(PlanError::BadObject {
                object: spec.id.clone(),
                part: None,
                reason: "the mesh has no vertices".into(),
            });
        }
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for v in &mesh.vertices {
            let v = Vector3::from(*v);
            lo = lo.inf(&v);
            hi = hi.sup(&v);
        }
        let center = (lo + hi) / 2.0;
        let radius = mesh
            .vertices
            .iter()
            .map(|v| (Vector3::from(*v) - center).norm())
            .fold(0.0, f64::max);
        let boxes = spec
            .parts
            .iter()
            .map(|p| part_box(&spec.id, p))
            .collect::<Result<Vec<_>>>()?;
        Ok(ObjectGeometry {
            spec,
            caster: Rc::from(caster),
            z_range: [lo.z, hi.z],
            sphere_center: center,
            sphere_radius: radius,
            boxes,
            outline: mesh
                .faces
                .iter()
                .step_by(mesh.faces.len().div_ceil(6000).max(1))
                .filter(|f| f.iter().all(|&i| (i as usize) < mesh.vertices.len()))
                .map(|f| f.map(|i| Vector3::from(mesh.vertices[i as usize])))
                .collect(),
        })
    }
}

impl ObjectGeometry {
    /// The same object stretched about its frame's origin by `scale` along
    /// the frame's X, Y, Z (`[randomize.proportions]`): mesh, part boxes and
    /// every derived extent. Ray casts go through the catalog-size mesh, so
    /// stretching builds no new mesh query.
    pub fn stretched(&self, scale: Vector3<f64>) -> ObjectGeometry {
        let boxes: Vec<Obb> = self.boxes.iter().map(|b| b.stretched(&scale)).collect();
        let mut spec = self.spec.clone();
        for (p, b) in spec.parts.iter_mut().zip(&boxes) {
            p.center = b.center.into();
            p.size = (b.half * 2.0).into();
            let q = b.rotation.into_inner();
            p.rotation_wxyz = [q.w, q.i, q.j, q.k];
        }
        let outline = self
            .outline
            .iter()
            .map(|t| t.map(|v| v.component_mul(&scale)))
            .collect();
        ObjectGeometry {
            spec,
            caster: Rc::new(ScaledCaster::new(self.caster.clone(), scale)),
            z_range: self.z_range.map(|z| z * scale.z),
            sphere_center: self.sphere_center.component_mul(&scale),
            sphere_radius: self.sphere_radius * scale.max(),
            boxes,
            outline,
        }
    }
}

fn part_box(object: &str, p: &GraspPart) -> Result<Obb> {
    let q = p.rotation_wxyz;
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    let bad = |reason: String| PlanError::BadObject {
        object: object.to_string(),
        part: Some(p.name.clone()),
        reason,
    };
    if !(norm.is_finite() && norm > 1e-9) {
        return Err(bad(format!("rotation_wxyz {q:?} is not a rotation")));
    }
    if !p.size.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Err(bad(format!("size {:?} must be positive", p.size)));
    }
    Ok(Obb {
        center: Vector3::from(p.center),
        rotation: wrist::from_wxyz(q),
        half: Vector3::from(p.size) / 2.0,
    })
}
