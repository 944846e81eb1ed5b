//! `[randomize.profiles]`: the built-in objects' families of shapes (handle
//! and rim profiles). Member 0 is the catalog's model bit for bit; every
//! other member is a closed mesh near the model's size that touches every
//! part box of the catalog; the planner draws a member per sequence from its
//! own stream, records it, and plans against that member's mesh.

use generator::catalog::validate::touch;
use generator::catalog::Catalog;
use generator::config::GeneratorConfig;
use generator::geometry::MeshQuery;
use generator::plan::Planner;
use grasp_schema::{Condition, SequenceKey, SequencePlan};

fn extents(m: &generator::catalog::TriMesh) -> [f64; 3] {
    let (lo, hi) = m.bounds();
    [0, 1, 2].map(|i| hi[i] - lo[i])
}

#[test]
fn every_member_is_a_closed_mesh_on_the_catalogs_part_boxes() {
    let catalog = Catalog::builtin().unwrap();
    let mut with_profiles = 0;
    for object in &catalog.objects {
        let model = object.mesh().unwrap();
        assert_eq!(object.member_mesh(0).unwrap(), model, "{}", object.id);
        if !object.mesh.has_profiles() {
            assert_eq!(object.member_mesh(5).unwrap(), model, "{}", object.id);
            continue;
        }
        with_profiles += 1;
        let size = extents(&model);
        for k in 1..=24 {
            let m = object.member_mesh(k).unwrap();
            let at = format!("{} member {k}", object.id);
            assert_ne!(m, model, "{at}");
            assert!(m.signed_volume() > 0.0, "{at}: not outward");
            for (a, b) in extents(&m).iter().zip(size) {
                assert!((a / b - 1.0).abs() < 0.2, "{at}: extents {a} against {b}");
            }
            let query = MeshQuery::new(&m).unwrap();
            let mut hull = None;
            for part in &object.parts {
                let t = touch(part, &m, &query, &mut hull).unwrap();
                assert!(t.is_some(), "{at}: part {} off its box", part.name);
            }
        }
    }
    // Mug, pitcher, plate, hammer, scissors, spatula, spoon.
    assert_eq!(with_profiles, 7);
}

fn mug_config(members: Option<u32>) -> GeneratorConfig {
    let mut c = GeneratorConfig::default();
    c.dataset.objects = Some(vec!["025_mug".into(), "001_chips_can".into()]);
    match members {
        Some(n) => {
            c.randomize.profiles.enabled = true;
            c.randomize.profiles.members = n;
        }
        None => c.randomize.profiles.enabled = false,
    }
    c
}

fn plans(planner: &Planner, object: &str, part: &str, n: u32) -> Vec<SequencePlan> {
    (0..n)
        .map(|index| {
            let key = SequenceKey {
                object: object.into(),
                part: part.into(),
                index,
                condition: Condition::Default,
            };
            planner.plan(&key).unwrap()
        })
        .collect()
}

#[test]
fn the_plan_draws_records_and_reproduces_a_member() {
    let catalog = Catalog::builtin().unwrap();
    let on = Planner::new(&mug_config(Some(8)), &catalog).unwrap();
    let off = Planner::new(&mug_config(None), &catalog).unwrap();
    let drawn = plans(&on, "025_mug", "handle", 16);
    let mut members = std::collections::BTreeSet::new();
    for (i, (p, q)) in drawn
        .iter()
        .zip(plans(&off, "025_mug", "handle", 16))
        .enumerate()
    {
        let m = p.object.shape_member;
        assert!(m < 8);
        members.insert(m);
        assert_eq!(q.object.shape_member, 0);
        assert!(!q.sampled.contains_key("shape_member"));
        if m == 0 {
            // The model's sequences are the plans the lever off makes.
            assert!(!p.sampled.contains_key("shape_member"));
            assert_eq!(p, &q, "sequence {i}");
        } else {
            assert_eq!(p.sampled["shape_member"], m);
            let json = serde_json::to_value(p).unwrap();
            assert_eq!(json["object"]["shape_member"], m);
        }
    }
    assert!(members.len() >= 4, "{members:?}");
    // Reproducible from the key and seed.
    assert_eq!(drawn, plans(&on, "025_mug", "handle", 16));
    // A can has one member, the model.
    for p in plans(&on, "001_chips_can", "top", 6) {
        assert_eq!(p.object.shape_member, 0);
    }
}

#[test]
fn a_family_size_out_of_range_is_refused_by_name() {
    for n in [0, 65] {
        let e = Planner::new(&mug_config(Some(n)), &Catalog::builtin().unwrap())
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains("[randomize.profiles] members"), "{e}");
    }
}
