//! Tests whose prerequisite lies outside the repository: the Python venv
//! with Blender (`scripts/setup.sh`), the authors' YCB release in
//! `../shared/ycb`, a GPU that Blender's Cycles can render on, and a
//! headless Chromium (Debian's `chromium`, which `scripts/setup.sh`
//! installs where missing). Rust's test harness has no "skipped" status, so a test
//! without its prerequisite prints `SKIPPED: <test>: <reason>` to stderr and
//! returns; under the test command (`scripts/test.sh` sets
//! [`REQUIRE_BLENDER_ENV`], [`REQUIRE_SHARED_ENV`] and
//! [`REQUIRE_BROWSER_ENV`] to 1) it fails instead, so that CI can never
//! pass without having run it.

use std::path::{Path, PathBuf};

/// Set to 1 to make a missing venv (bpy, trimesh, the pip-installed
/// weights) a test failure instead of a skip.
pub const REQUIRE_BLENDER_ENV: &str = "GRASP_REQUIRE_BLENDER";
/// Set to 1 to make a missing `../shared` (the YCB release) a test failure
/// instead of a skip.
pub const REQUIRE_SHARED_ENV: &str = "GRASP_REQUIRE_SHARED";
/// Set to 1 to make a machine without a GPU that Cycles reports a test
/// failure instead of a skip. `scripts/test.sh` leaves it unset: CI has no
/// GPU. Set it on a workstation to be sure the GPU test ran.
pub const REQUIRE_GPU_ENV: &str = "GRASP_REQUIRE_GPU";
/// Set to 1 to make a machine without Chromium (the pages' browser test)
/// a test failure instead of a skip.
pub const REQUIRE_BROWSER_ENV: &str = "GRASP_REQUIRE_BROWSER";
/// The browser's names, looked up on `PATH` in this order (Debian's
/// package installs `chromium`).
pub const BROWSERS: [&str; 3] = ["chromium", "chromium-browser", "google-chrome"];

/// Whether `var` is set to 1.
pub fn required(var: &str) -> bool {
    std::env::var(var).is_ok_and(|v| v == "1")
}

/// Whether `test` may run: true when `missing` is `None`. Otherwise it
/// panics when `require_env` is 1, and else reports the skip and returns
/// false.
pub fn check(test: &str, require_env: &str, missing: Option<String>) -> bool {
    match missing {
        None => true,
        Some(reason) if required(require_env) => {
            panic!("{test}: {require_env}=1 but {reason}")
        }
        Some(reason) => {
            eprintln!("SKIPPED: {test}: {reason} (set {require_env}=1 to fail instead)");
            false
        }
    }
}

/// The YCB release beside the repository (`WORKSPACE/../shared/ycb`), or
/// why it is missing.
pub fn ycb_dir(workspace_root: &Path) -> Result<PathBuf, String> {
    let dir = workspace_root.join("../shared/ycb");
    if dir.join("annotations.json").is_file() {
        Ok(dir)
    } else {
        Err(format!(
            "the YCB release is absent (no {})",
            dir.join("annotations.json").display()
        ))
    }
}

/// [`ycb_dir`] checked for `test`: `None` when the test is skipped.
pub fn require_ycb(test: &str, workspace_root: &Path) -> Option<PathBuf> {
    match ycb_dir(workspace_root) {
        Ok(dir) => Some(dir),
        Err(why) => {
            check(test, REQUIRE_SHARED_ENV, Some(why));
            None
        }
    }
}

/// The first of [`BROWSERS`] on `PATH`, or why there is none.
pub fn browser() -> Result<PathBuf, String> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    for name in BROWSERS {
        for dir in std::env::split_paths(&path) {
            let candidate = dir.join(name);
            if is_executable(&candidate) {
                return Ok(candidate);
            }
        }
    }
    Err(format!(
        "no headless browser on PATH ({}; scripts/setup.sh installs Debian's chromium)",
        BROWSERS.join(", ")
    ))
}

fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

/// [`browser`] checked for `test`: `None` when the test is skipped.
pub fn require_browser(test: &str) -> Option<PathBuf> {
    match browser() {
        Ok(path) => Some(path),
        Err(why) => {
            check(test, REQUIRE_BROWSER_ENV, Some(why));
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn present_prerequisites_run_and_missing_ones_skip_or_fail() {
        let var = "GRASP_TEST_PREREQUISITE_UNIT";
        assert!(check("t", var, None));
        std::env::remove_var(var);
        assert!(!check("t", var, Some("nothing here".into())));
        std::env::set_var(var, "1");
        let failed = std::panic::catch_unwind(|| check("t", var, Some("nothing here".into())));
        std::env::remove_var(var);
        let message = failed.expect_err("a required prerequisite fails the test");
        let text = message
            .downcast_ref::<String>()
            .cloned()
            .unwrap_or_default();
        assert!(
            text.contains("nothing here") && text.contains(var),
            "{text}"
        );
    }

    #[test]
    fn a_folder_without_the_release_is_absent() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("repo");
        std::fs::create_dir_all(&root).unwrap();
        std::fs::create_dir_all(dir.path().join("shared/ycb")).unwrap();
        assert!(ycb_dir(&root).unwrap_err().contains("annotations.json"));
        std::fs::write(dir.path().join("shared/ycb/annotations.json"), "{}").unwrap();
        assert_eq!(
            ycb_dir(&root).unwrap(),
            root.join("../shared/ycb"),
            "found beside the repository"
        );
    }
}
