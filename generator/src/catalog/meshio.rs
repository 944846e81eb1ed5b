//! Reading triangle meshes (PLY ASCII or binary, OBJ, STL; metres) and
//! writing binary PLY.

use super::error::{CatalogError, MeshError, Result};
use super::mesh::TriMesh;
use std::io::{BufReader, Write};
use std::path::Path;

/// Reads a mesh by its extension. Polygons are fan-triangulated.
pub fn read_mesh(path: &Path) -> Result<TriMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let mesh = match ext.as_str() {
        "ply" => read_ply(path),
        "obj" => read_obj(path),
        "stl" => read_stl(path),
        _ => Err(MeshError::UnsupportedFormat(ext)),
    }
    .map_err(|source| CatalogError::ReadMesh {
        path: path.to_path_buf(),
        source,
    })?;
    check(&mesh).map_err(|source| CatalogError::BadMesh {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(mesh)
}

fn check(mesh: &TriMesh) -> Result<(), MeshError> {
    if mesh.faces.is_empty() {
        return Err(MeshError::NoTriangles);
    }
    let n = mesh.vertices.len();
    if let Some((i, f)) = mesh
        .faces
        .iter()
        .enumerate()
        .find(|(_, f)| f.iter().any(|&v| v as usize >= n))
    {
        return Err(MeshError::FacePastVertices {
            face: i,
            indices: *f,
            vertices: n,
        });
    }
    if mesh.vertices.iter().flatten().any(|x| !x.is_finite()) {
        return Err(MeshError::NonFinite);
    }
    Ok(())
}

fn fan(polygon: &[u32], faces: &mut Vec<[u32; 3]>) {
    for k in 1..polygon.len().saturating_sub(1) {
        faces.push([polygon[0], polygon[k], polygon[k + 1]]);
    }
}

fn read_ply(path: &Path) -> Result<TriMesh, MeshError> {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};
    let file = std::fs::File::open(path)?;
    let mut reader = BufReader::new(file);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut reader)
        .map_err(MeshError::Ply)?;
    let scalar = |p: &Property| -> Option<f64> {
        Some(match *p {
            Property::Float(v) => v as f64,
            Property::Double(v) => v,
            Property::Char(v) => v as f64,
            Property::UChar(v) => v as f64,
            Property::Short(v) => v as f64,
            Property::UShort(v) => v as f64,
            Property::Int(v) => v as f64,
            Property::UInt(v) => v as f64,
            _ => return None,
        })
    };
    let mut mesh = TriMesh::default();
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or(MeshError::NoElement("vertex"))?;
    for (i, v) in vertices.iter().enumerate() {
        let coord = |k: &'static str| -> Result<f64, MeshError> {
            v.get(k).and_then(scalar).ok_or(MeshError::NoCoordinate {
                vertex: i,
                coordinate: k,
            })
        };
        mesh.vertices.push([coord("x")?, coord("y")?, coord("z")?]);
    }
    let faces = ply
        .payload
        .get("face")
        .ok_or(MeshError::NoElement("face"))?;
    for (i, f) in faces.iter().enumerate() {
        let list = f
            .get("vertex_indices")
            .or_else(|| f.get("vertex_index"))
            .ok_or(MeshError::NoIndices(i))?;
        let idx: Vec<u32> = match list {
            Property::ListInt(v) => v.iter().map(|&x| x as u32).collect(),
            Property::ListUInt(v) => v.clone(),
            Property::ListShort(v) => v.iter().map(|&x| x as u32).collect(),
            Property::ListUShort(v) => v.iter().map(|&x| x as u32).collect(),
            Property::ListChar(v) => v.iter().map(|&x| x as u32).collect(),
            Property::ListUChar(v) => v.iter().map(|&x| x as u32).collect(),
            _ => return Err(MeshError::IndicesNotIntegers(i)),
        };
        fan(&idx, &mut mesh.faces);
    }
    Ok(mesh)
}

fn read_obj(path: &Path) -> Result<TriMesh, MeshError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = tobj::load_obj(path, &options)?;
    let mut mesh = TriMesh::default();
    for model in models {
        let base = mesh.vertices.len() as u32;
        let m = model.mesh;
        mesh.vertices.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]),
        );
        mesh.faces.extend(
            m.indices
                .chunks_exact(3)
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }
    Ok(mesh)
}

fn read_stl(path: &Path) -> Result<TriMesh, MeshError> {
    let mut file = std::fs::File::open(path)?;
    let stl = stl_io::read_stl(&mut file).map_err(MeshError::Stl)?;
    Ok(TriMesh {
        vertices: stl
            .vertices
            .iter()
            .map(|v| [v[0] as f64, v[1] as f64, v[2] as f64])
            .collect(),
        faces: stl
            .faces
            .iter()
            .map(|f| f.vertices.map(|i| i as u32))
            .collect(),
    })
}

/// Writes a binary little-endian PLY, atomically (temp file + rename).
pub fn write_ply(path: &Path, mesh: &TriMesh) -> Result<()> {
    let mut bytes = Vec::new();
    write!(
        bytes,
        "ply\nformat binary_little_endian 1.0\ncomment grasp-gen\nelement vertex {}\n\
         property double x\nproperty double y\nproperty double z\nelement face {}\n\
         property list uchar uint vertex_indices\nend_header\n",
        mesh.vertices.len(),
        mesh.faces.len()
    )
    .map_err(|e| CatalogError::io("writing", path, e))?;
    for v in &mesh.vertices {
        for x in v {
            bytes.extend(x.to_le_bytes());
        }
    }
    for f in &mesh.faces {
        bytes.push(3);
        for i in f {
            bytes.extend(i.to_le_bytes());
        }
    }
    Ok(grasp_support::atomic::write_atomic(path, &bytes)?)
}
