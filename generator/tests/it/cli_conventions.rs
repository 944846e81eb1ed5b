//! Conventions shared by every program (grasp_main,
//! grasp_test_support::program): a closed stdout ends `grasp-gen` quietly,
//! and a user error prints its message, not a backtrace, even under
//! `RUST_BACKTRACE=1`.

use crate::render_common;

use grasp_test_support::Program;

fn grasp_gen() -> Program {
    Program::new(env!("CARGO_BIN_EXE_grasp-gen"))
}

#[test]
fn printing_into_a_closed_pipe_ends_quietly() {
    // `grasp-gen objects list | head -0`: the reader is gone before the
    // first line is printed.
    grasp_gen().assert_quiet_in_closed_pipe(["objects", "list"]);
}

#[test]
fn a_user_error_prints_its_message_without_a_backtrace() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.toml");
    let plans = dir.path().join("plans.jsonl");
    let line = grasp_gen().user_error([
        "plan".as_ref(),
        "--config".as_ref(),
        missing.as_os_str(),
        "--out".as_ref(),
        plans.as_os_str(),
    ]);
    assert!(line.contains("missing.toml"), "{line}");
}

#[test]
fn doctor_ends_a_healthy_check_without_blenders_leak_report() {
    // Issue 60, case 16: 13 lines of "Freeing memory after the leak
    // detector has run" and "Error: Not freed memory blocks", exit 0.
    if !render_common::have_blender() {
        return;
    }
    let done = grasp_gen().ok(["doctor"]);
    let all = format!("{}{}", done.stdout, done.stderr);
    assert!(done.stdout.contains("bpy import: ok"), "{all}");
    assert!(
        !all.contains("Not freed memory") && !all.contains("leak detector"),
        "{all}"
    );
    assert!(!all.contains("Error"), "{all}");
}
