//! What the workspace's tests repeat: running a program as a user does and
//! checking its command-line conventions ([`program`]), and the
//! prerequisites that live outside the repository ([`prerequisite`]).
//! A dev-dependency only: nothing the programs ship links it.

pub mod prerequisite;
pub mod program;

pub use program::Program;
