//! Reading a catalog folder: one TOML file per object, checked field by
//! field, then geometrically (every box must touch its mesh).

use super::error::{CatalogError, Result};
use super::mesh::TriMesh;
use super::model::*;
use super::{meshio, validate};
use grasp_schema::{GraspType, Preshape};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// Environment variable that points at the catalog folder to use.
pub const OBJECTS_ENV_VAR: &str = "GRASP_OBJECTS";

/// The object catalog: objects sorted by id, each with its parts.
#[derive(Debug, Clone, Default)]
pub struct Catalog {
    pub objects: Vec<ObjectSpec>,
    /// The folder it was read from.
    pub dir: PathBuf,
}

/// A part as written in a file: the rotation is either a quaternion or the
/// box's X axis and approach (Z) axis in the object frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartFile {
    pub name: String,
    pub grasp_type: GraspType,
    pub center: [f64; 3],
    pub size: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation_wxyz: Option<[f64; 4]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x_axis: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z_axis: Option<[f64; 3]>,
    #[serde(default)]
    pub upside_down: UpsideDown,
    #[serde(default)]
    pub pronation: Pronation,
    #[serde(default)]
    pub table_border: bool,
}

/// One object file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectFile {
    pub id: String,
    pub name: String,
    pub category: String,
    pub size: [f64; 3],
    pub mesh: MeshSource,
    pub parts: Vec<PartFile>,
    /// Plausible colours of the real object (HSV ranges of its sRGB colour).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<ColorRange>,
}

impl Catalog {
    /// Reads and validates every `*.toml` in `dir`, including the geometric
    /// check of every box against its mesh.
    pub fn load_dir(dir: &Path) -> Result<Catalog> {
        let catalog = Catalog::load_dir_unchecked(dir)?;
        for object in &catalog.objects {
            validate::check_object_geometry(object)?;
        }
        Ok(catalog)
    }

    /// Reads every `*.toml` in `dir` and checks fields, ids and meshes, but
    /// not the boxes against the meshes.
    pub fn load_dir_unchecked(dir: &Path) -> Result<Catalog> {
        let entries = std::fs::read_dir(dir)
            .map_err(|e| CatalogError::io("reading the catalog folder", dir, e))?;
        let mut files: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(CatalogError::Empty {
                dir: dir.to_path_buf(),
            });
        }
        let mut objects = Vec::new();
        let mut ids: HashSet<String> = HashSet::new();
        for file in &files {
            let object = read_object(file)?;
            if !ids.insert(object.id.clone()) {
                let first = objects
                    .iter()
                    .find(|o: &&ObjectSpec| o.id == object.id)
                    .and_then(|o| o.source.as_ref())
                    .map(|p| p.display().to_string())
                    .unwrap_or_default();
                return Err(CatalogError::DuplicateId {
                    path: file.clone(),
                    id: object.id,
                    first,
                });
            }
            objects.push(object);
        }
        objects.sort_by(|a, b| a.id.cmp(&b.id));
        Ok(Catalog {
            objects,
            dir: dir.to_path_buf(),
        })
    }

    /// The catalog in `$GRASP_OBJECTS`, or else the repository's `objects/`.
    pub fn builtin() -> Result<Catalog> {
        Catalog::load_dir(&builtin_dir())
    }

    pub fn object(&self, id: &str) -> Option<&ObjectSpec> {
        self.objects.iter().find(|o| o.id == id)
    }

    /// Every grasp-type/object-part pair as (object id, part index), objects
    /// in id order and parts in file order.
    pub fn pairs(&self) -> Vec<(String, usize)> {
        self.objects
            .iter()
            .flat_map(|o| (0..o.parts.len()).map(move |i| (o.id.clone(), i)))
            .collect()
    }

    /// Number of pairs per pre-shape, in `Preshape::ALL` order.
    pub fn pairs_per_preshape(&self) -> Vec<(Preshape, usize)> {
        Preshape::ALL
            .iter()
            .map(|&p| {
                let n = self
                    .objects
                    .iter()
                    .flat_map(|o| &o.parts)
                    .filter(|part| part.grasp_type.preshape() == p)
                    .count();
                (p, n)
            })
            .collect()
    }
}

/// Fails unless both catalogs have the same objects with the same grasp
/// types, counted per object.
pub fn compare_grasp_types(a: &Catalog, b: &Catalog) -> Result<()> {
    let summary = |c: &Catalog| -> Vec<(String, Vec<GraspType>)> {
        c.objects
            .iter()
            .map(|o| {
                let mut g: Vec<GraspType> = o.parts.iter().map(|p| p.grasp_type).collect();
                g.sort();
                (o.id.clone(), g)
            })
            .collect()
    };
    let (sa, sb) = (summary(a), summary(b));
    if sa != sb {
        return Err(CatalogError::GraspTypesDiffer {
            a_dir: a.dir.clone(),
            a: format!("{sa:?}"),
            b_dir: b.dir.clone(),
            b: format!("{sb:?}"),
        });
    }
    Ok(())
}

/// Where the built-in catalog lives.
pub fn builtin_dir() -> PathBuf {
    match std::env::var_os(OBJECTS_ENV_VAR) {
        Some(dir) => PathBuf::from(dir),
        None => crate::python::workspace_root().join("objects"),
    }
}

impl ObjectSpec {
    /// The mesh in the object frame (built or loaded once, then cached).
    pub fn mesh(&self) -> Result<TriMesh> {
        if let Some(m) = self.mesh_cache.get() {
            return Ok(m.clone());
        }
        let mesh = match &self.mesh {
            MeshSource::Procedural(shape) => shape.mesh(),
            MeshSource::File {
                path,
                rotation_wxyz,
                translation,
            } => {
                let m =
                    meshio::read_mesh(path).map_err(|e| e.at(self.context("mesh.file.path")))?;
                let r = quaternion(*rotation_wxyz).map_err(|reason| {
                    CatalogError::invalid(self.context("mesh.file.rotation_wxyz"), reason)
                })?;
                transform(m, &r.to_rotation_matrix().into_inner(), *translation)
            }
        };
        Ok(self.mesh_cache.get_or_init(|| mesh).clone())
    }

    /// "FILE: object 'ID': field 'FIELD'", for error messages.
    pub fn context(&self, field: &str) -> String {
        let file = self
            .source
            .as_ref()
            .map(|p| format!("{}: ", p.display()))
            .unwrap_or_default();
        format!("{file}object '{}': field '{field}'", self.id)
    }

    pub fn part(&self, name: &str) -> Option<&GraspPart> {
        self.parts.iter().find(|p| p.name == name)
    }
}

impl GraspPart {
    /// Object-from-box rotation matrix; columns are the box's X, Y, Z axes.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        let [w, x, y, z] = self.rotation_wxyz;
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z))
            .to_rotation_matrix()
            .into_inner()
    }

    /// The eight corners of the box in the object frame.
    pub fn corners(&self) -> [[f64; 3]; 8] {
        let r = self.rotation_matrix();
        let c = Vector3::from(self.center);
        std::array::from_fn(|i| {
            let s = [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64];
            let local = Vector3::new(
                (s[0] - 0.5) * self.size[0],
                (s[1] - 0.5) * self.size[1],
                (s[2] - 0.5) * self.size[2],
            );
            (c + r * local).into()
        })
    }

    /// Whether a point (object frame) lies in the box, with a margin.
    pub fn contains(&self, p: [f64; 3], margin: f64) -> bool {
        let local =
            self.rotation_matrix().transpose() * (Vector3::from(p) - Vector3::from(self.center));
        (0..3).all(|k| local[k].abs() <= self.size[k] / 2.0 + margin)
    }
}

pub(crate) fn transform(mut m: TriMesh, r: &Matrix3<f64>, t: [f64; 3]) -> TriMesh {
    let t = Vector3::from(t);
    for v in &mut m.vertices {
        *v = (r * Vector3::from(*v) + t).into();
    }
    m
}

/// The unit quaternion `q`, or why it is not one.
fn quaternion(q: [f64; 4]) -> Result<UnitQuaternion<f64>, String> {
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !q.iter().all(|x| x.is_finite()) || (n - 1.0).abs() > 1e-3 {
        return Err(format!(
            "{q:?} is not a unit quaternion (w, x, y, z); its norm is {n}"
        ));
    }
    Ok(UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        q[0], q[1], q[2], q[3],
    )))
}

/// Parses one object file and checks its fields.
pub fn read_object(file: &Path) -> Result<ObjectSpec> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| CatalogError::io("reading object file", file, e))?;
    let raw: ObjectFile =
        toml::from_str(&text).map_err(|source| CatalogError::MalformedObject {
            path: file.to_path_buf(),
            source,
        })?;
    object_from_file(raw, file)
}

/// Checks a parsed object file and builds the object.
pub fn object_from_file(raw: ObjectFile, file: &Path) -> Result<ObjectSpec> {
    let at = |field: &str| format!("{}: object '{}': field '{field}'", file.display(), raw.id);
    if raw.id.trim().is_empty() {
        return Err(CatalogError::invalid(
            file.display().to_string(),
            "field 'id' is empty",
        ));
    }
    check_positive(&raw.size, at, "size")?;
    let mut mesh = raw.mesh.clone();
    match &mut mesh {
        MeshSource::Procedural(shape) => {
            for (name, value) in shape.parameters() {
                if !(value.is_finite() && value > 0.0) {
                    return Err(CatalogError::invalid(
                        at("mesh.procedural"),
                        format!(
                            "mesh parameter '{name}' of kind '{}' must be a positive number, got {value}",
                            shape.kind()
                        ),
                    ));
                }
            }
        }
        MeshSource::File { path, .. } => {
            if path.is_relative() {
                *path = file.parent().unwrap_or(Path::new(".")).join(&*path);
            }
            if !path.is_file() {
                return Err(CatalogError::invalid(
                    at("mesh.file.path"),
                    format!("mesh file {} does not exist", path.display()),
                ));
            }
        }
    }
    if raw.parts.is_empty() {
        return Err(CatalogError::invalid(
            at("parts"),
            "an object needs at least one grasp part",
        ));
    }
    if let Some(c) = &raw.color {
        c.check().map_err(|e| {
            CatalogError::invalid(
                format!("{}: object '{}'", file.display(), raw.id),
                format!("field {e}"),
            )
        })?;
    }
    let mut names = HashSet::new();
    let mut parts = Vec::new();
    for (i, p) in raw.parts.iter().enumerate() {
        let field = |f: &str| at(&format!("parts[{i}] ('{}').{f}", p.name));
        if p.name.trim().is_empty() {
            return Err(CatalogError::invalid(
                field("name"),
                "the part name is empty",
            ));
        }
        if !names.insert(p.name.clone()) {
            return Err(CatalogError::invalid(
                field("name"),
                format!("duplicate part name '{}'", p.name),
            ));
        }
        check_positive(&p.size, field, "size")?;
        if !p.center.iter().all(|x| x.is_finite()) {
            return Err(CatalogError::invalid(
                field("center"),
                format!("{:?} is not finite", p.center),
            ));
        }
        let rotation =
            part_rotation(p).map_err(|reason| CatalogError::invalid(field("rotation"), reason))?;
        parts.push(GraspPart {
            name: p.name.clone(),
            grasp_type: p.grasp_type,
            center: p.center,
            rotation_wxyz: [rotation.w, rotation.i, rotation.j, rotation.k],
            size: p.size,
            upside_down: p.upside_down,
            pronation: p.pronation,
            table_border: p.table_border,
        });
    }
    Ok(ObjectSpec {
        id: raw.id,
        name: raw.name,
        category: raw.category,
        size: raw.size,
        mesh,
        parts,
        color: raw.color,
        source: Some(file.to_path_buf()),
        mesh_cache: Default::default(),
    })
}

/// Fails unless every component is a positive finite number; `at` builds
/// the "file: object: field" prefix for a field name.
fn check_positive(v: &[f64; 3], at: impl Fn(&str) -> String, field: &str) -> Result<()> {
    if let Some((k, x)) = v
        .iter()
        .enumerate()
        .find(|(_, x)| !(x.is_finite() && **x > 0.0))
    {
        return Err(CatalogError::invalid(
            format!("{} = {x}", at(&format!("{field}[{k}]"))),
            "sizes must be positive finite numbers (metres)",
        ));
    }
    Ok(())
}

/// The part's rotation from either a quaternion or its X and Z axes, or why
/// the fields give none.
fn part_rotation(p: &PartFile) -> Result<UnitQuaternion<f64>, String> {
    match (p.rotation_wxyz, p.x_axis, p.z_axis) {
        (Some(q), None, None) => quaternion(q),
        (None, Some(x), Some(z)) => {
            let (x, z) = (Vector3::from(x), Vector3::from(z));
            let (nx, nz) = (x.norm(), z.norm());
            if !(nx.is_finite() && nz.is_finite()) || nx < 1e-9 || nz < 1e-9 {
                return Err("x_axis and z_axis must be finite non-zero vectors".into());
            }
            let (x, z) = (x / nx, z / nz);
            if x.dot(&z).abs() > 0.02 {
                return Err(format!(
                    "x_axis and z_axis must be perpendicular (their cosine is {:.3})",
                    x.dot(&z)
                ));
            }
            // Orthonormalise, keeping Z (the approach axis) exact.
            let x = (x - z * x.dot(&z)).normalize();
            let y = z.cross(&x);
            let m = Matrix3::from_columns(&[x, y, z]);
            Ok(UnitQuaternion::from_rotation_matrix(
                &Rotation3::from_matrix_unchecked(m),
            ))
        }
        (None, None, None) => Err("give either rotation_wxyz or both x_axis and z_axis".into()),
        _ => Err("give either rotation_wxyz or both x_axis and z_axis, not a mix".into()),
    }
}
