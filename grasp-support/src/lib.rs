//! What the programs share besides data types: the binaries' `main`
//! wrapper and logging ([`cli`]), atomic file writes ([`atomic`]), config
//! files in layers ([`layers`]), where the project's Python environment is
//! ([`venv`]) and the tests' prerequisites ([`prerequisite`]). The data
//! types live in `grasp-schema`, which depends on none of this.

pub mod atomic;
pub mod cli;
pub mod layers;
pub mod prerequisite;
pub mod venv;
