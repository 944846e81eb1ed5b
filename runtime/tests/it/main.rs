//! The runtime's integration tests, one binary: a module per concern.
//! `lite_checkpoint` stays a binary of its own (tests/lite_checkpoint.rs):
//! it sets RUST_BACKTRACE in its process.

mod cli;
mod cli_common;
mod cli_recording;
mod cli_signals;
mod common;
mod decision_age;
mod faults;
mod link;
