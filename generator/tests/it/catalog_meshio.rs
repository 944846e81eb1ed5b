//! Mesh files: PLY (ASCII and binary), OBJ and STL read back the same mesh.

use generator::catalog::{meshio, TriMesh};
use std::fmt::Write;

fn tetra() -> TriMesh {
    TriMesh {
        vertices: vec![
            [0.0, 0.0, 0.0],
            [0.1, 0.0, 0.0],
            [0.0, 0.1, 0.0],
            [0.0, 0.0, 0.1],
        ],
        faces: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    }
}

fn same(a: &TriMesh, b: &TriMesh) {
    assert_eq!(a.faces.len(), b.faces.len());
    // STL stores unique vertices in its own order: compare triangles by position.
    let tri = |m: &TriMesh| -> Vec<[[i64; 3]; 3]> {
        let mut t: Vec<[[i64; 3]; 3]> = m
            .faces
            .iter()
            .map(|f| f.map(|i| m.vertices[i as usize].map(|x| (x * 1e6).round() as i64)))
            .collect();
        t.sort();
        t
    };
    assert_eq!(tri(a), tri(b));
}

#[test]
fn binary_ply_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.ply");
    meshio::write_ply(&p, &tetra()).unwrap();
    same(&meshio::read_mesh(&p).unwrap(), &tetra());
}

#[test]
fn ascii_ply_with_quads_and_extra_properties() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("q.ply");
    let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                property float z\nproperty float nx\nelement face 1\n\
                property list uchar int vertex_indices\nend_header\n\
                0 0 0 1\n1 0 0 1\n1 1 0 1\n0 1 0 1\n4 0 1 2 3\n";
    std::fs::write(&p, text).unwrap();
    let m = meshio::read_mesh(&p).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
}

#[test]
fn obj_and_stl() {
    let dir = tempfile::tempdir().unwrap();
    let t = tetra();
    let mut obj = String::from("# tetra\n");
    for v in &t.vertices {
        writeln!(obj, "v {} {} {}", v[0], v[1], v[2]).unwrap();
    }
    for f in &t.faces {
        writeln!(obj, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1).unwrap();
    }
    std::fs::write(dir.path().join("t.obj"), obj).unwrap();
    same(&meshio::read_mesh(&dir.path().join("t.obj")).unwrap(), &t);

    let mut stl = String::from("solid t\n");
    for f in &t.faces {
        stl += "facet normal 0 0 0\nouter loop\n";
        for &i in f {
            let v = t.vertices[i as usize];
            writeln!(stl, "vertex {} {} {}", v[0], v[1], v[2]).unwrap();
        }
        stl += "endloop\nendfacet\n";
    }
    stl += "endsolid t\n";
    std::fs::write(dir.path().join("t.stl"), stl).unwrap();
    same(&meshio::read_mesh(&dir.path().join("t.stl")).unwrap(), &t);
}

#[test]
fn bad_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.off");
    std::fs::write(&p, "OFF\n").unwrap();
    assert!(format!(
        "{:#}",
        anyhow::Error::from(meshio::read_mesh(&p).unwrap_err())
    )
    .contains(".off"));
    let p = dir.path().join("bad.ply");
    std::fs::write(&p, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 2\n").unwrap();
    let e = format!(
        "{:#}",
        anyhow::Error::from(meshio::read_mesh(&p).unwrap_err())
    );
    assert!(
        e.contains("bad.ply") && e.contains("past the 1 vertices"),
        "{e}"
    );
    assert!(meshio::read_mesh(&dir.path().join("none.stl")).is_err());
}
