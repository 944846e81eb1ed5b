//! The built-in catalog: the paper's 15 objects and 31 pairs (Table 1),
//! closed outward meshes in the object frame, and every box touching its
//! mesh. Runs always (the procedural meshes need no data).

use generator::catalog::{builtin_dir, Catalog, MeshSource};
use generator::geometry::MeshQuery;
use grasp_schema::{GraspType, Preshape};

fn catalog() -> Catalog {
    Catalog::load_dir(&builtin_dir()).expect("the built-in catalog validates")
}

/// Table 1 of the paper: grasp types per object (the superscripts).
fn table1() -> Vec<(&'static str, Vec<GraspType>)> {
    use GraspType::*;
    vec![
        (
            "001_chips_can",
            vec![LargeDiameter, LargeDiameter, Sphere4Fingers],
        ),
        (
            "006_mustard_bottle",
            vec![LargeDiameter, LargeDiameter, Tripod],
        ),
        (
            "010_potted_meat_can",
            vec![MediumWrap, MediumWrap, Sphere4Fingers, Sphere4Fingers],
        ),
        ("011_banana", vec![Prismatic4Fingers, Tripod]),
        ("018_plum", vec![PowerSphere]),
        ("019_pitcher_base", vec![AdductedThumb, Prismatic4Fingers]),
        (
            "025_mug",
            vec![
                LargeDiameter,
                Sphere4Fingers,
                Sphere4Fingers,
                Prismatic2Fingers,
            ],
        ),
        ("029_plate", vec![AdductedThumb, AdductedThumb]),
        ("031_spoon", vec![Prismatic4Fingers]),
        (
            "033_spatula",
            vec![AdductedThumb, AdductedThumb, Prismatic4Fingers],
        ),
        ("037_scissors", vec![AdductedThumb, Prismatic4Fingers]),
        ("040_large_marker", vec![Prismatic4Fingers]),
        ("048_hammer", vec![SmallDiameter]),
        ("055_baseball", vec![PowerSphere]),
        ("red_wood_block", vec![Tripod]),
    ]
}

#[test]
fn builtin_catalog_has_the_papers_objects_and_pairs() {
    let c = catalog();
    let mut got: Vec<(String, Vec<GraspType>)> = c
        .objects
        .iter()
        .map(|o| {
            let mut g: Vec<GraspType> = o.parts.iter().map(|p| p.grasp_type).collect();
            g.sort();
            (o.id.clone(), g)
        })
        .collect();
    got.sort();
    let mut want: Vec<(String, Vec<GraspType>)> = table1()
        .into_iter()
        .map(|(id, mut g)| {
            g.sort();
            (id.to_string(), g)
        })
        .collect();
    want.sort();
    assert_eq!(got, want);
    assert_eq!(c.pairs().len(), 31);
    let per: Vec<(Preshape, usize)> = c.pairs_per_preshape();
    let count = |p: Preshape| per.iter().find(|(q, _)| *q == p).unwrap().1;
    assert_eq!(count(Preshape::Power), 15);
    assert_eq!(count(Preshape::Lateral), 6);
    assert_eq!(count(Preshape::Pinch), 6);
    assert_eq!(count(Preshape::Pinch3), 4);
}

#[test]
fn pairs_are_in_a_stable_order_and_index_real_parts() {
    let c = catalog();
    let pairs = c.pairs();
    assert_eq!(pairs, catalog().pairs());
    let ids: Vec<&str> = pairs.iter().map(|(id, _)| id.as_str()).collect();
    let mut sorted = ids.clone();
    sorted.sort();
    assert_eq!(ids, sorted, "objects in id order");
    for (id, i) in &pairs {
        assert!(c.object(id).unwrap().parts.get(*i).is_some());
    }
}

#[test]
fn procedural_meshes_are_closed_outward_and_in_the_object_frame() {
    for o in &catalog().objects {
        assert!(matches!(o.mesh, MeshSource::Procedural(_)), "{}", o.id);
        let m = o.mesh().unwrap();
        let q = MeshQuery::new(&m).unwrap();
        assert!(q.is_watertight(), "{} is not watertight", o.id);
        assert!(m.signed_volume() > 0.0, "{} faces inward", o.id);
        let (lo, hi) = m.bounds();
        assert!(lo[2].abs() < 1e-9, "{} does not rest on z = 0", o.id);
        assert!(
            (lo[0] + hi[0]).abs() < 1e-9 && (lo[1] + hi[1]).abs() < 1e-9,
            "{}",
            o.id
        );
        // Within 10 % (or 3 mm) of the real size on every axis.
        for k in 0..3 {
            let (got, want) = (hi[k] - lo[k], o.size[k]);
            assert!(
                (got - want).abs() <= (0.10 * want).max(0.003),
                "{} axis {k}: mesh {got:.4} m vs real {want:.4} m",
                o.id
            );
        }
    }
}

#[test]
fn every_box_touches_its_mesh_and_only_the_mug_top_needs_the_hull_rule() {
    use generator::catalog::validate::{check_object_geometry, Touch};
    for o in &catalog().objects {
        let touches = check_object_geometry(o).unwrap();
        for (p, t) in o.parts.iter().zip(touches) {
            let hull_ok = o.id == "025_mug" && p.name == "top";
            assert_eq!(
                t == Touch::InsideHull,
                hull_ok,
                "{} {}: {t:?}",
                o.id,
                p.name
            );
        }
    }
}

#[test]
fn box_axes_are_proper_rotations() {
    for o in &catalog().objects {
        for p in &o.parts {
            let r = p.rotation_matrix();
            assert!((r.determinant() - 1.0).abs() < 1e-9, "{} {}", o.id, p.name);
        }
    }
}

#[test]
fn the_drawing_shows_the_mesh_and_the_boxes_in_their_colours() {
    let c = catalog();
    let o = c.object("025_mug").unwrap();
    let img = generator::raster::render_object(o, &o.mesh().unwrap());
    let count = |c: image::Rgb<u8>| img.pixels().filter(|p| **p == c).count();
    let power = generator::raster::preshape_colour(Preshape::Power);
    let pinch3 = generator::raster::preshape_colour(Preshape::Pinch3);
    assert!(count(power) > 200);
    assert!(count(pinch3) > 50);
    assert_eq!(
        count(generator::raster::preshape_colour(Preshape::Lateral)),
        0
    );
    // Shaded mesh pixels: greys that are neither background nor a box colour.
    let grey = img
        .pixels()
        .filter(|p| p[0] > 40 && p[0] < 200 && p[0].abs_diff(p[2]) < 30)
        .count();
    assert!(grey > 20_000, "{grey} mesh pixels");
}
