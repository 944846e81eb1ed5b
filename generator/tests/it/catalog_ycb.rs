//! The YCB catalog variant, built from `../shared/ycb` when it is present:
//! the same grasp types per object as the built-in catalog, every box
//! touching its real mesh, and pairs in the authors' scene order.

use generator::catalog::cli::compare_grasp_types;
use generator::catalog::{builtin_dir, Catalog};
use std::path::PathBuf;

/// `../shared/ycb`; without it the test is skipped, or fails under
/// `GRASP_REQUIRE_SHARED=1` (`scripts/test.sh`).
fn ycb_dir(test: &str) -> Option<PathBuf> {
    grasp_test_support::prerequisite::require_ycb(test, &generator::python::workspace_root())
}

#[test]
fn imported_ycb_catalog_matches_the_builtin_and_touches_real_meshes() {
    let Some(ycb) = ycb_dir("imported_ycb_catalog_matches_the_builtin_and_touches_real_meshes")
    else {
        return;
    };
    let out = tempfile::tempdir().unwrap();
    let files = generator::catalog::ycb::import(&ycb, out.path()).unwrap();
    assert_eq!(files.len(), 15);
    assert!(out.path().join("001_chips_can.hull.ply").is_file());
    // load_dir runs the geometric check: every box touches its real mesh.
    let imported = Catalog::load_dir(out.path()).unwrap();
    let builtin = Catalog::load_dir_unchecked(&builtin_dir()).unwrap();
    compare_grasp_types(&builtin, &imported).unwrap();
    assert_eq!(imported.pairs().len(), 31);
    // The real objects take the built-in objects' plausible colours.
    for spec in &builtin.objects {
        let real = imported.object(&spec.id).unwrap();
        assert!(real.color.is_some() || spec.color.is_none(), "{}", spec.id);
        assert_eq!(real.color, spec.color, "{}", spec.id);
    }

    // Pairs follow the authors' scene order (scene_pair_order).
    let ann: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ycb.join("annotations.json")).unwrap())
            .unwrap();
    let order: Vec<(String, String)> = ann["scene_pair_order"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["object_id"].as_str().unwrap().to_string(),
                p["grasp_type"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    for c in [&imported, &builtin] {
        let got: Vec<(String, String)> = c
            .pairs()
            .into_iter()
            .map(|(id, i)| {
                let g = c.object(&id).unwrap().parts[i]
                    .grasp_type
                    .name()
                    .to_string();
                (id, g)
            })
            .collect();
        assert_eq!(got, order, "{}", c.dir.display());
    }
}

#[test]
fn imported_objects_stand_upright_in_the_object_frame() {
    let Some(ycb) = ycb_dir("imported_objects_stand_upright_in_the_object_frame") else {
        return;
    };
    let out = tempfile::tempdir().unwrap();
    generator::catalog::ycb::import(&ycb, out.path()).unwrap();
    let c = Catalog::load_dir_unchecked(out.path()).unwrap();
    for o in &c.objects {
        let m = o.mesh().unwrap();
        let (lo, hi) = m.bounds();
        assert!(lo[2].abs() < 1e-6, "{} rests on z = 0", o.id);
        assert!((lo[0] + hi[0]).abs() < 1e-6 && (lo[1] + hi[1]).abs() < 1e-6);
    }
    // Flat objects lie flat once standing: height is their smallest extent.
    for id in [
        "011_banana",
        "031_spoon",
        "033_spatula",
        "037_scissors",
        "048_hammer",
        "040_large_marker",
    ] {
        let s = c.object(id).unwrap().size;
        assert!(s[2] < s[0].max(s[1]) / 3.0, "{id}: {s:?}");
    }
    // The mug's top box points down (approach from above).
    let mug = c.object("025_mug").unwrap();
    let top = mug
        .parts
        .iter()
        .find(|p| p.grasp_type.name() == "sphere_4fingers")
        .unwrap();
    assert!(top.rotation_matrix()[(2, 2)] < -0.99);
}
