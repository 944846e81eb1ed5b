//! Building a catalog variant from YCB meshes and the authors' annotation
//! file (`annotations.json`, boxes already converted into the mesh frame).
//!
//! Per object: the standing rotation takes `up_axis_in_mesh_frame` to +Z,
//! then a translation puts the bottom centre of the bounding box at the
//! origin; the boxes get the same transform. Each object file points at its
//! mesh in place (nothing is copied), except the chips can, whose convex
//! hull of `points.xyz` is written next to the object files.

use super::error::{AnnotationError, CatalogError, Result};
use super::load::{ObjectFile, PartFile};
use super::mesh::TriMesh;
use super::meshio;
use super::model::{MeshSource, Pronation, UpsideDown};
use grasp_support::atomic::write_atomic;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The paper's 15 objects (021 and 026 are in the data but not the paper).
pub const PAPER_OBJECTS: [&str; 15] = [
    "001_chips_can",
    "006_mustard_bottle",
    "010_potted_meat_can",
    "011_banana",
    "018_plum",
    "019_pitcher_base",
    "025_mug",
    "029_plate",
    "031_spoon",
    "033_spatula",
    "037_scissors",
    "040_large_marker",
    "048_hammer",
    "055_baseball",
    "red_wood_block",
];

/// Writes one object file per paper object into `out`; returns the files.
pub fn import(ycb: &Path, out: &Path) -> Result<Vec<PathBuf>> {
    let ann_path = ycb.join("annotations.json");
    let text = std::fs::read_to_string(&ann_path)
        .map_err(|e| CatalogError::io("reading", &ann_path, e))?;
    let ann: Value = serde_json::from_str(&text).map_err(|source| CatalogError::MalformedJson {
        path: ann_path.clone(),
        source,
    })?;
    std::fs::create_dir_all(out).map_err(|e| CatalogError::io("creating", out, e))?;
    let mut files = Vec::new();
    for id in PAPER_OBJECTS {
        let obj = ann.pointer(&format!("/objects/{id}")).ok_or_else(|| {
            CatalogError::invalid(ann_path.display().to_string(), format!("no object '{id}'"))
        })?;
        let file = import_object(ycb, out, id, obj)
            .map_err(|e| e.at(format!("{}: object '{id}'", ann_path.display())))?;
        files.push(file);
    }
    Ok(files)
}

fn import_object(ycb: &Path, out: &Path, id: &str, obj: &Value) -> Result<PathBuf> {
    let meshes = ycb.join("meshes");
    let (mesh_path, mesh) = match id {
        "001_chips_can" => {
            let points = read_xyz(&meshes.join("001_chips_can.points.xyz"))?;
            let hull = crate::geometry::convex_hull(&points)?;
            let path = out.join("001_chips_can.hull.ply");
            meshio::write_ply(&path, &hull)?;
            (path, hull)
        }
        "red_wood_block" => {
            let path = meshes.join("red_wood_block.synthetic.ply");
            let m = meshio::read_mesh(&path)?;
            (path, m)
        }
        _ => {
            let path = meshes.join(format!("{id}.ply"));
            let m = meshio::read_mesh(&path)?;
            (path, m)
        }
    };
    let up = vec3(obj, "/up_axis_in_mesh_frame")?;
    let r = standing_rotation(up)?;
    let (lo, hi) = super::load::transform(mesh, &r, [0.0; 3]).bounds();
    let t = Vector3::new(-(lo[0] + hi[0]) / 2.0, -(lo[1] + hi[1]) / 2.0, -lo[2]);
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let grasps = obj["grasps"]
        .as_array()
        .ok_or(AnnotationError::Missing("'grasps' list"))?;
    let boxes = obj["boxes_in_mesh_frame"]
        .as_array()
        .ok_or(AnnotationError::Missing("'boxes_in_mesh_frame' list"))?;
    if grasps.len() != boxes.len() {
        return Err(AnnotationError::Count {
            grasps: grasps.len(),
            boxes: boxes.len(),
        }
        .into());
    }
    let mut parts = Vec::new();
    let mut names = Vec::<String>::new();
    for (g, b) in grasps.iter().zip(boxes) {
        let part = import_part(g, b, &r, &t, &names).map_err(|e| {
            CatalogError::from(e).at(format!("grasp '{}'", g["raw_name"].as_str().unwrap_or("?")))
        })?;
        names.push(part.name.clone());
        parts.push(part);
    }
    let file = ObjectFile {
        id: id.to_string(),
        name: obj["paper_name"].as_str().unwrap_or(id).to_string(),
        category: obj["category_repo_label"]
            .as_str()
            .unwrap_or(id)
            .to_string(),
        size: [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]].map(round6),
        mesh: MeshSource::File {
            path: std::path::absolute(&mesh_path).unwrap_or(mesh_path),
            rotation_wxyz: [q.w, q.i, q.j, q.k].map(round9),
            translation: [t.x, t.y, t.z].map(round9),
        },
        parts,
        // The real objects' colours are not in the annotations: the
        // built-in object of the same id gives its plausible range (what a
        // scene draws the object's colour from), so that a real mesh is not
        // drawn in a colour no such object has.
        color: builtin_color(id),
    };
    let text = format!(
        "# Imported by `grasp-gen objects import-ycb` from the YCB annotations.\n{}",
        toml::to_string(&file).map_err(AnnotationError::Serialise)?
    );
    let path = out.join(format!("{id}.toml"));
    write_atomic(&path, text.as_bytes())?;
    Ok(path)
}

/// The plausible colours of the repository's built-in object `id` (None
/// when there is none, or no range).
fn builtin_color(id: &str) -> Option<super::ColorRange> {
    super::Catalog::load_dir_unchecked(&crate::python::workspace_root().join("objects"))
        .ok()
        .and_then(|c| c.object(id).and_then(|spec| spec.color))
}

fn import_part(
    g: &Value,
    b: &Value,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    taken: &[String],
) -> Result<PartFile, AnnotationError> {
    let grasp_type = g["grasp_type"]
        .as_str()
        .ok_or(AnnotationError::Missing("grasp_type"))?
        .parse()
        .map_err(AnnotationError::GraspType)?;
    let c = r * Vector3::from(vec3(b, "/center_m")?) + t;
    let m = b["rotation_matrix"]
        .as_array()
        .ok_or(AnnotationError::Missing("rotation_matrix"))?;
    let rows: Vec<[f64; 3]> = m
        .iter()
        .map(|row| {
            let v: Vec<f64> = row
                .as_array()
                .map(|a| a.iter().filter_map(Value::as_f64).collect())
                .unwrap_or_default();
            v.try_into()
                .map_err(|_| AnnotationError::Shape("rotation_matrix rows need 3 numbers"))
        })
        .collect::<Result<_, _>>()?;
    if rows.len() != 3 {
        return Err(AnnotationError::Shape("rotation_matrix needs 3 rows"));
    }
    let rb = r * Matrix3::from_fn(|i, j| rows[i][j]);
    let size = vec3(b, "/size_m")?;
    let side = g["side"].as_str().unwrap_or("none");
    let upside_down = match g["upside_down"].as_str().unwrap_or("never") {
        s if s.starts_with("required") => UpsideDown::Must,
        s if s.starts_with("optional") => UpsideDown::May,
        _ => UpsideDown::Never,
    };
    let behaviour = &g["script_behaviour"];
    let pronation = match behaviour["pronation_supination"].as_str().unwrap_or("") {
        s if s.starts_with("none") => Pronation::None,
        s if s.starts_with("forced supination") => Pronation::Supination,
        _ => Pronation::Shortest,
    };
    let mut name = g["grasp_type"].as_str().unwrap_or("part").to_string();
    if side != "none" {
        name = format!("{name}_{side}");
    }
    if upside_down == UpsideDown::Must {
        name = format!("{name}_upside_down");
    }
    let base = name.clone();
    let mut k = 2;
    while taken.contains(&name) {
        name = format!("{base}_{k}");
        k += 1;
    }
    Ok(PartFile {
        name,
        grasp_type,
        center: [c.x, c.y, c.z].map(round9),
        size: size.map(round9),
        rotation_wxyz: None,
        x_axis: Some([rb[(0, 0)], rb[(1, 0)], rb[(2, 0)]].map(round9)),
        z_axis: Some([rb[(0, 2)], rb[(1, 2)], rb[(2, 2)]].map(round9)),
        upside_down,
        pronation,
        table_border: behaviour["placed_on_table_border"]
            .as_bool()
            .unwrap_or(false),
    })
}

/// The rotation that takes `up` to +Z: the shortest one, or a half turn
/// about X when `up` points down.
pub fn standing_rotation(up: [f64; 3]) -> Result<Matrix3<f64>, AnnotationError> {
    let u = Vector3::from(up);
    if !(u.norm().is_finite() && u.norm() > 1e-9) {
        return Err(AnnotationError::NotADirection(up));
    }
    let u = u.normalize();
    let flip = if u.z < -0.999 {
        Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
    } else {
        Matrix3::identity()
    };
    let u2 = flip * u;
    let r = Rotation3::rotation_between(&u2, &Vector3::z())
        .map(|r| r.into_inner())
        .unwrap_or_else(Matrix3::identity);
    Ok(r * flip)
}

fn vec3(v: &Value, pointer: &str) -> Result<[f64; 3], AnnotationError> {
    let name = pointer.trim_start_matches('/').to_string();
    let Some(a) = v.pointer(pointer).and_then(Value::as_array) else {
        return Err(AnnotationError::NoVector(name));
    };
    let x: Vec<f64> = a.iter().filter_map(Value::as_f64).collect();
    x.try_into().map_err(|_| AnnotationError::NotThree(name))
}

fn read_xyz(path: &Path) -> Result<Vec<[f64; 3]>> {
    let text = std::fs::read_to_string(path).map_err(|e| CatalogError::io("reading", path, e))?;
    let not_three = |i: usize, source| CatalogError::NotThreeNumbers {
        path: path.to_path_buf(),
        line: i + 1,
        source,
    };
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            let v: Vec<f64> = l
                .split_whitespace()
                .take(3)
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|e| not_three(i, Some(e)))?;
            v.try_into().map_err(|_| not_three(i, None))
        })
        .collect()
}

fn round6(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

fn round9(x: f64) -> f64 {
    (x * 1e9).round() / 1e9
}

impl TriMesh {
    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.faces.len()
    }

    pub fn is_empty(&self) -> bool {
        self.faces.is_empty()
    }
}
