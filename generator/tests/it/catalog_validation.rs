//! Bad catalogs give errors that name the file and the field.

use generator::catalog::{meshio, Catalog, TriMesh};
use std::path::Path;

const MUG: &str = "025_mug.toml";

/// Copies the built-in mug (and the plum) into a temp catalog, applying
/// `edit` to the mug's text.
fn catalog_with(edit: impl Fn(&str) -> String) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let src = generator::catalog::builtin_dir();
    let mug = std::fs::read_to_string(src.join(MUG)).unwrap();
    std::fs::write(dir.path().join(MUG), edit(&mug)).unwrap();
    std::fs::copy(src.join("018_plum.toml"), dir.path().join("018_plum.toml")).unwrap();
    dir
}

fn error_of(dir: &Path) -> String {
    format!(
        "{:#}",
        anyhow::Error::from(Catalog::load_dir(dir).unwrap_err())
    )
}

#[test]
fn the_unedited_copy_loads() {
    let dir = catalog_with(str::to_string);
    assert_eq!(Catalog::load_dir(dir.path()).unwrap().pairs().len(), 5);
}

#[test]
fn unknown_grasp_type() {
    let dir = catalog_with(|s| s.replacen("\"large_diameter\"", "\"power_grip\"", 1));
    let e = error_of(dir.path());
    assert!(
        e.contains(MUG) && e.contains("grasp_type") && e.contains("power_grip"),
        "{e}"
    );
    assert!(e.contains("adducted_thumb"), "lists the valid names: {e}");
}

#[test]
fn duplicate_object_id() {
    let dir = catalog_with(str::to_string);
    let text = std::fs::read_to_string(dir.path().join(MUG)).unwrap();
    std::fs::write(dir.path().join("zz_copy.toml"), text).unwrap();
    let e = error_of(dir.path());
    assert!(
        e.contains("zz_copy.toml") && e.contains("'id'") && e.contains("025_mug"),
        "{e}"
    );
    assert!(e.contains(MUG), "names the other file too: {e}");
}

#[test]
fn duplicate_part_name() {
    let dir = catalog_with(|s| s.replacen("name = \"top\"", "name = \"body\"", 1));
    let e = error_of(dir.path());
    assert!(
        e.contains(MUG) && e.contains("parts[1]") && e.contains("duplicate part name 'body'"),
        "{e}"
    );
}

#[test]
fn zero_negative_and_nan_box_sizes() {
    for bad in ["0.0", "-0.01", "nan"] {
        let dir = catalog_with(|s| {
            s.replacen(
                "size = [0.0294, 0.0179, 0.0257]",
                &format!("size = [0.0294, {bad}, 0.0257]"),
                1,
            )
        });
        let e = error_of(dir.path());
        assert!(
            e.contains(MUG) && e.contains("parts[0] ('body').size[1]"),
            "{bad}: {e}"
        );
    }
}

#[test]
fn box_that_does_not_touch_the_mesh() {
    let dir = catalog_with(|s| {
        s.replacen(
            "center = [-0.046, 0.0, 0.044]",
            "center = [-0.2, 0.0, 0.044]",
            1,
        )
    });
    let e = error_of(dir.path());
    assert!(
        e.contains(MUG) && e.contains("parts[0] ('body')") && e.contains("does not touch"),
        "{e}"
    );
    // The unchecked loader accepts it: the geometric check is separate.
    assert!(Catalog::load_dir_unchecked(dir.path()).is_ok());
}

#[test]
fn box_beside_a_convex_object_is_not_saved_by_the_hull_rule() {
    // 2 mm beside the plum's top: outside the mesh and its hull.
    let dir = catalog_with(str::to_string);
    let plum = dir.path().join("018_plum.toml");
    let text = std::fs::read_to_string(&plum).unwrap();
    std::fs::write(
        &plum,
        text.replace("center = [0.0, 0.0, 0.046]", "center = [0.0, 0.0, 0.068]"),
    )
    .unwrap();
    let e = error_of(dir.path());
    assert!(
        e.contains("018_plum.toml") && e.contains("does not touch"),
        "{e}"
    );
}

fn file_mesh_catalog(mesh_line: &str) -> tempfile::TempDir {
    catalog_with(|s| {
        let start = s.find("[mesh.procedural]").unwrap();
        let end = s.find("[[parts]]").unwrap();
        format!("{}{mesh_line}\n\n{}", &s[..start], &s[end..])
    })
}

#[test]
fn missing_mesh_file() {
    let dir = file_mesh_catalog("[mesh.file]\npath = \"meshes/nothing.ply\"");
    let e = error_of(dir.path());
    assert!(
        e.contains(MUG) && e.contains("mesh.file.path") && e.contains("nothing.ply"),
        "{e}"
    );
}

#[test]
fn unreadable_mesh_file() {
    let dir = file_mesh_catalog("[mesh.file]\npath = \"broken.ply\"");
    std::fs::write(
        dir.path().join("broken.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n",
    )
    .unwrap();
    let e = error_of(dir.path());
    assert!(
        e.contains(MUG) && e.contains("mesh.file.path") && e.contains("broken.ply"),
        "{e}"
    );
}

#[test]
fn a_file_mesh_is_loaded_and_transformed_into_the_object_frame() {
    // The procedural mug written as PLY, shifted by 1 m and turned 90 degrees
    // about Z; the object file undoes both.
    let src = Catalog::load_dir_unchecked(&generator::catalog::builtin_dir()).unwrap();
    let mug = src.object("025_mug").unwrap().mesh().unwrap();
    let moved = TriMesh {
        vertices: mug
            .vertices
            .iter()
            .map(|v| [-v[1], v[0], v[2] + 1.0])
            .collect(),
        faces: mug.faces.clone(),
    };
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let dir = file_mesh_catalog(&format!(
        "[mesh.file]\npath = \"mug.ply\"\nrotation_wxyz = [{h}, 0.0, 0.0, {}]\ntranslation = [0.0, 0.0, -1.0]",
        -h
    ));
    meshio::write_ply(&dir.path().join("mug.ply"), &moved).unwrap();
    let c = Catalog::load_dir(dir.path()).unwrap();
    let back = c.object("025_mug").unwrap().mesh().unwrap();
    for (a, b) in back.vertices.iter().zip(&mug.vertices) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-9);
        }
    }
}

#[test]
fn malformed_file() {
    let dir = catalog_with(|s| s.replacen("radius = 0.0465", "radius = = 0.0465", 1));
    let e = error_of(dir.path());
    assert!(
        e.contains(MUG) && e.contains("malformed") && e.contains("line"),
        "{e}"
    );
    let dir = catalog_with(|s| s.replacen("height = 0.081", "heigth = 0.081", 1));
    let e = error_of(dir.path());
    assert!(
        e.contains(MUG) && e.contains("heigth"),
        "unknown field named: {e}"
    );
}

#[test]
fn bad_procedural_parameter_and_bad_axes() {
    let dir = catalog_with(|s| s.replacen("wall = 0.004", "wall = -0.004", 1));
    let e = error_of(dir.path());
    assert!(e.contains(MUG) && e.contains("'wall'"), "{e}");
    let dir =
        catalog_with(|s| s.replacen("z_axis = [1.0, 0.0, 0.0]", "z_axis = [0.0, 0.0, 1.0]", 1));
    let e = error_of(dir.path());
    assert!(
        e.contains(MUG) && e.contains("parts[0] ('body').rotation") && e.contains("perpendicular"),
        "{e}"
    );
}
