//! What the programs share besides data types: the binaries' `main`
//! wrapper and logging ([`cli`]), atomic file writes ([`atomic`]), the io
//! error that names its path ([`IoAt`]), config
//! files in layers ([`layers`]) and where the project's Python environment
//! is ([`venv`]). The data types live in `grasp-schema`, which depends on
//! none of this; the tests' set-up lives in `grasp-test-support`.

pub mod atomic;
pub mod cli;
mod io_at;
pub mod layers;
pub mod venv;

pub use io_at::IoAt;

/// An error and its causes on one line, "outer: cause: cause", as the
/// programs print them; for a library that keeps another's error as text.
pub fn error_chain(error: &dyn std::error::Error) -> String {
    let mut line = error.to_string();
    let mut cause = error.source();
    while let Some(e) = cause {
        line.push_str(": ");
        line.push_str(&e.to_string());
        cause = e.source();
    }
    line
}
