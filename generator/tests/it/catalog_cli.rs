//! `grasp-gen objects ...` end to end on the built-in catalog.

use grasp_test_support::Program;

fn grasp_gen(args: &[&str]) -> (bool, String, String) {
    let done = Program::new(env!("CARGO_BIN_EXE_grasp-gen")).run(args);
    (done.status.success(), done.stdout, done.stderr)
}

#[test]
fn list_prints_15_objects_31_pairs_and_pairs_per_preshape() {
    let (ok, out, err) = grasp_gen(&["objects", "list"]);
    assert!(ok, "{err}");
    assert!(out.contains("15 objects, 31 pairs"), "{out}");
    for line in [
        "power    15 pairs",
        "lateral  6 pairs",
        "pinch    6 pairs",
        "pinch3   4 pairs",
    ] {
        assert!(out.contains(line), "{line}: {out}");
    }
    assert!(out.contains("025_mug") && out.contains("prismatic_2fingers"));
}

#[test]
fn check_validates_every_builtin_box() {
    let (ok, out, err) = grasp_gen(&["objects", "check"]);
    assert!(ok, "{err}");
    assert_eq!(out.matches("touches:").count(), 31, "{out}");
    assert!(out.trim_end().ends_with("ok"));
}

#[test]
fn check_fails_with_the_file_and_field_on_a_bad_catalog() {
    let dir = tempfile::tempdir().unwrap();
    let src = generator::catalog::builtin_dir().join("018_plum.toml");
    let text = std::fs::read_to_string(src).unwrap();
    std::fs::write(
        dir.path().join("018_plum.toml"),
        text.replace("power_sphere", "power_orb"),
    )
    .unwrap();
    let (ok, _, err) = grasp_gen(&[
        "objects",
        "check",
        "--catalog",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        err.contains("018_plum.toml") && err.contains("power_orb") && err.contains("grasp_type"),
        "{err}"
    );
}

#[test]
fn show_writes_pngs() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("mug.png");
    let (ok, _, err) = grasp_gen(&["objects", "show", "025_mug", "--png", png.to_str().unwrap()]);
    assert!(ok, "{err}");
    let img = image::open(&png).unwrap();
    assert!(img.width() >= 1000 && img.height() >= 400);
    let all = dir.path().join("all");
    let (ok, _, err) = grasp_gen(&["objects", "show", "--all", "--out", all.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert_eq!(std::fs::read_dir(&all).unwrap().count(), 15);
    let (ok, _, err) = grasp_gen(&[
        "objects",
        "show",
        "999_nothing",
        "--png",
        png.to_str().unwrap(),
    ]);
    assert!(
        !ok && err.contains("999_nothing") && err.contains("025_mug"),
        "{err}"
    );
}
