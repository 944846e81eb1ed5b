//! The geometric check: every grasp box must touch its object's mesh.
//!
//! A box touches the mesh when any of these holds (after the YCB data's
//! README, checked in this order because the first two are cheap):
//! 1. a mesh vertex lies in the box;
//! 2. the surface point closest to the box centre lies in the box;
//! 3. one of the 11 x 11 x 11 grid samples of the box lies inside the mesh;
//! 4. the box lies entirely inside the mesh's convex hull (a box in an
//!    opening, such as the mug's top grasp, which the hand reaches through
//!    the opening).

use super::error::{CatalogError, Result};
use super::mesh::TriMesh;
use super::model::{GraspPart, ObjectSpec};
use crate::geometry::{convex_hull, MeshQuery};

/// Grid samples per box edge.
const GRID: usize = 11;
/// Slack for points on the box faces (metres).
const MARGIN: f64 = 1e-6;

/// How a box touches its mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Touch {
    Vertex,
    ClosestPoint,
    GridSample,
    InsideHull,
}

impl Touch {
    pub fn describe(self) -> &'static str {
        match self {
            Touch::Vertex => "a mesh vertex lies in the box",
            Touch::ClosestPoint => "the surface point closest to the centre lies in the box",
            Touch::GridSample => "a grid sample of the box lies inside the mesh",
            Touch::InsideHull => "the box lies inside the convex hull (an opening)",
        }
    }
}

/// Checks every part of an object against its mesh.
pub fn check_object_geometry(object: &ObjectSpec) -> Result<Vec<Touch>> {
    let mesh = object.mesh()?;
    let query = MeshQuery::new(&mesh).map_err(|source| CatalogError::GeometryAt {
        what: object.context("mesh"),
        source,
    })?;
    let mut hull: Option<TriMesh> = None;
    let mut touches = Vec::new();
    for (i, part) in object.parts.iter().enumerate() {
        match touch(part, &mesh, &query, &mut hull)? {
            Some(t) => touches.push(t),
            None => {
                let (_, d) = query.closest_points(&[part.center])?[0];
                return Err(CatalogError::invalid(
                    object.context(&format!("parts[{i}] ('{}')", part.name)),
                    format!(
                        "the box does not touch the mesh (its centre {:?} is {:.1} mm from the surface, \
                         no vertex or grid sample of it is on or inside the mesh, and it is not inside the \
                         convex hull)",
                        part.center,
                        d * 1e3
                    ),
                ));
            }
        }
    }
    Ok(touches)
}

/// How `part` touches the mesh, or `None`.
pub fn touch(
    part: &GraspPart,
    mesh: &TriMesh,
    query: &MeshQuery,
    hull: &mut Option<TriMesh>,
) -> crate::geometry::Result<Option<Touch>> {
    if mesh.vertices.iter().any(|v| part.contains(*v, MARGIN)) {
        return Ok(Some(Touch::Vertex));
    }
    let (closest, _) = query.closest_points(&[part.center])?[0];
    if part.contains(closest, MARGIN) {
        return Ok(Some(Touch::ClosestPoint));
    }
    if query.contains(&grid(part))?.into_iter().any(|b| b) {
        return Ok(Some(Touch::GridSample));
    }
    if hull.is_none() {
        *hull = Some(convex_hull(&mesh.vertices)?);
    }
    let hull = hull.as_ref().expect("set above");
    if part.corners().iter().all(|c| inside_convex(hull, *c)) {
        return Ok(Some(Touch::InsideHull));
    }
    Ok(None)
}

/// The box's grid samples, corners included.
pub fn grid(part: &GraspPart) -> Vec<[f64; 3]> {
    let r = part.rotation_matrix();
    let mut out = Vec::with_capacity(GRID * GRID * GRID);
    for i in 0..GRID {
        for j in 0..GRID {
            for k in 0..GRID {
                let f = |n: usize, s: f64| (n as f64 / (GRID - 1) as f64 - 0.5) * s;
                let local = nalgebra::Vector3::new(
                    f(i, part.size[0]),
                    f(j, part.size[1]),
                    f(k, part.size[2]),
                );
                let p = nalgebra::Vector3::from(part.center) + r * local;
                out.push(p.into());
            }
        }
    }
    out
}

/// Whether `p` is inside a closed convex mesh with outward faces.
fn inside_convex(hull: &TriMesh, p: [f64; 3]) -> bool {
    use super::shapes::{cross, dot};
    hull.faces.iter().all(|f| {
        let [a, b, c] = f.map(|i| hull.vertices[i as usize]);
        let n = cross(
            [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
            [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
        );
        dot(n, [p[0] - a[0], p[1] - a[1], p[2] - a[2]]) <= 1e-12
    })
}
