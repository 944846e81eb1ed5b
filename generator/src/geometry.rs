//! Batched geometric queries on a mesh: ray casts, inside tests and closest
//! surface points.
//!
//! Rays and inside tests run in the embedded Python through trimesh
//! (`blender_scripts.geometry`), with Embree when `embreex` is installed and
//! trimesh's rtree intersector otherwise. Every call is one batched Python
//! call with the arrays passed as bytes. Closest points run in Rust on a BVH
//! (`bvh`), because trimesh's version loops in Python per point.

mod bvh;
pub mod error;

pub use bvh::{closest_on_triangle, TriangleTree};
pub use error::{GeometryError, Result};

use crate::catalog::TriMesh;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

const PY_MODULE: &str = "blender_scripts.geometry";

/// A mesh loaded into trimesh with its ray intersector, plus a Rust BVH for
/// closest points. Build it once per mesh and query it in batches.
pub struct MeshQuery {
    py: Py<PyAny>,
    tree: TriangleTree,
    watertight: bool,
    backend: String,
}

impl std::fmt::Debug for MeshQuery {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshQuery")
            .field("backend", &self.backend)
            .field("watertight", &self.watertight)
            .finish_non_exhaustive()
    }
}

/// Which ray intersector trimesh uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RayBackend {
    /// Embree when `embreex` is installed, else trimesh's rtree intersector.
    Auto,
    /// trimesh's rtree-based intersector (`ray_triangle`), always.
    Triangle,
}

impl MeshQuery {
    pub fn new(mesh: &TriMesh) -> Result<MeshQuery> {
        MeshQuery::with_backend(mesh, RayBackend::Auto)
    }

    pub fn with_backend(mesh: &TriMesh, backend: RayBackend) -> Result<MeshQuery> {
        check_mesh(mesh)?;
        crate::python::init(&["numpy", "trimesh", PY_MODULE])?;
        let vertices = points_to_bytes(&mesh.vertices);
        let faces: Vec<u8> = mesh
            .faces
            .iter()
            .flat_map(|f| f.iter().flat_map(|i| i.to_le_bytes()))
            .collect();
        let (py, watertight, backend) = Python::attach(|py| -> PyResult<_> {
            let class = py.import(PY_MODULE)?.getattr("MeshQuery")?;
            let obj = class.call1((
                PyBytes::new(py, &vertices),
                PyBytes::new(py, &faces),
                backend == RayBackend::Auto,
            ))?;
            let watertight: bool = obj.getattr("is_watertight")?.extract()?;
            let backend: String = obj.getattr("backend")?.extract()?;
            Ok((obj.unbind(), watertight, backend))
        })
        .map_err(|e| GeometryError::trimesh("building the trimesh query object", e))?;
        Ok(MeshQuery {
            py,
            tree: TriangleTree::new(mesh),
            watertight,
            backend,
        })
    }

    /// Distance along each (unit) direction to the first hit with the mesh, or None. One batched Python call.
    pub fn first_hits(
        &self,
        origins: &[[f64; 3]],
        directions: &[[f64; 3]],
    ) -> Result<Vec<Option<f64>>> {
        if origins.len() != directions.len() {
            return Err(GeometryError::RayCount {
                origins: origins.len(),
                directions: directions.len(),
            });
        }
        let bytes = self.call(
            "first_hits",
            &[points_to_bytes(origins), points_to_bytes(directions)],
        )?;
        let hits: Vec<Option<f64>> = bytes
            .chunks_exact(8)
            .map(|c| {
                let d = f64::from_le_bytes(c.try_into().expect("chunk of 8"));
                (!d.is_nan()).then_some(d)
            })
            .collect();
        expect_len("first_hits", hits.len(), origins.len())?;
        Ok(hits)
    }

    /// Whether each point lies inside the mesh (meaningful for closed meshes).
    pub fn contains(&self, points: &[[f64; 3]]) -> Result<Vec<bool>> {
        let bytes = self.call("contains", &[points_to_bytes(points)])?;
        expect_len("contains", bytes.len(), points.len())?;
        Ok(bytes.into_iter().map(|b| b != 0).collect())
    }

    /// Closest surface point and its distance, per query point.
    pub fn closest_points(&self, points: &[[f64; 3]]) -> Result<Vec<([f64; 3], f64)>> {
        points
            .iter()
            .map(|&p| self.tree.closest_point(p).ok_or(GeometryError::Empty))
            .collect()
    }

    /// Distances to the surface by trimesh's own `closest_point` (slow; for
    /// benchmarks against `closest_points`).
    pub fn trimesh_closest_distances(&self, points: &[[f64; 3]]) -> Result<Vec<f64>> {
        let bytes = self.call("closest_points_trimesh", &[points_to_bytes(points)])?;
        Ok(bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("chunk of 8")))
            .collect())
    }

    pub fn is_watertight(&self) -> bool {
        self.watertight
    }

    fn call(&self, method: &str, args: &[Vec<u8>]) -> Result<Vec<u8>> {
        Python::attach(|py| -> PyResult<Vec<u8>> {
            let args: Vec<Bound<'_, PyBytes>> = args.iter().map(|a| PyBytes::new(py, a)).collect();
            let args = pyo3::types::PyTuple::new(py, args)?;
            let out = self.py.bind(py).call_method1(method, args)?;
            Ok(out.downcast::<PyBytes>()?.as_bytes().to_vec())
        })
        .map_err(|e| GeometryError::trimesh(format!("trimesh {method}"), e))
    }
}

/// The convex hull of a point set, through trimesh (qhull).
pub fn convex_hull(points: &[[f64; 3]]) -> Result<TriMesh> {
    if points.len() < 4 {
        return Err(GeometryError::TooFewPoints(points.len()));
    }
    crate::python::init(&["numpy", "trimesh", "scipy", PY_MODULE])?;
    let input = points_to_bytes(points);
    let (v, f) = Python::attach(|py| -> PyResult<(Vec<u8>, Vec<u8>)> {
        let out = py
            .import(PY_MODULE)?
            .getattr("convex_hull")?
            .call1((PyBytes::new(py, &input),))?;
        let (v, f): (Bound<'_, PyBytes>, Bound<'_, PyBytes>) = out.extract()?;
        Ok((v.as_bytes().to_vec(), f.as_bytes().to_vec()))
    })
    .map_err(|e| GeometryError::trimesh("trimesh convex hull", e))?;
    Ok(TriMesh {
        vertices: bytes_to_points(&v),
        faces: f
            .chunks_exact(12)
            .map(|c| {
                [0, 1, 2].map(|k| u32::from_le_bytes(c[4 * k..4 * k + 4].try_into().expect("4")))
            })
            .collect(),
    })
}

fn check_mesh(mesh: &TriMesh) -> Result<()> {
    if mesh.faces.is_empty() {
        return Err(GeometryError::NoTriangles);
    }
    let n = mesh.vertices.len();
    if let Some(f) = mesh
        .faces
        .iter()
        .find(|f| f.iter().any(|&i| i as usize >= n))
    {
        return Err(GeometryError::FacePastVertices {
            face: *f,
            vertices: n,
        });
    }
    if mesh.vertices.iter().flatten().any(|x| !x.is_finite()) {
        return Err(GeometryError::NonFinite);
    }
    Ok(())
}

fn expect_len(what: &'static str, got: usize, want: usize) -> Result<()> {
    if got != want {
        return Err(GeometryError::ResultCount { what, got, want });
    }
    Ok(())
}

fn points_to_bytes(points: &[[f64; 3]]) -> Vec<u8> {
    points
        .iter()
        .flat_map(|p| p.iter().flat_map(|x| x.to_le_bytes()))
        .collect()
}

fn bytes_to_points(bytes: &[u8]) -> Vec<[f64; 3]> {
    bytes
        .chunks_exact(24)
        .map(|c| [0, 1, 2].map(|k| f64::from_le_bytes(c[8 * k..8 * k + 8].try_into().expect("8"))))
        .collect()
}
