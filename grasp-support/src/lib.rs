//! What the programs share besides data types: the binaries' `main`
//! wrapper and logging ([`cli`]), atomic file writes ([`atomic`]), config
//! files in layers ([`layers`]) and where the project's Python environment
//! is ([`venv`]). The data types live in `grasp-schema`, which depends on
//! none of this; the tests' set-up lives in `grasp-test-support`.

pub mod atomic;
pub mod cli;
pub mod layers;
pub mod venv;
