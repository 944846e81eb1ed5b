//! What the programs and libraries share besides data types: atomic file
//! writes ([`atomic`]), the io error that names its path ([`IoAt`]), config
//! files in layers ([`layers`]), a long step's progress as a log line
//! ([`progress`]), an error's chain on one line ([`error_chain`]) and where
//! the project's Python environment is ([`venv`]). Its API is typed: the
//! binaries' `main`, logging and anyhow live in `grasp-main`, which only
//! the binaries use. The data types live in `grasp-schema`, which depends
//! on none of this; the tests' set-up lives in `grasp-test-support`.

pub mod atomic;
mod io_at;
pub mod layers;
pub mod progress;
pub mod venv;

pub use io_at::IoAt;

/// An error and its causes on one line, "outer: cause: cause", as the
/// programs print them; for a library that keeps another's error as text.
pub fn error_chain(error: &dyn std::error::Error) -> String {
    let mut line = one_line(&error.to_string());
    let mut cause = error.source();
    while let Some(e) = cause {
        line.push_str(": ");
        line.push_str(&one_line(&e.to_string()));
        cause = e.source();
    }
    line
}

/// A number as a message shows it: `1e308`, not its 309 digits (Rust's
/// `{}` writes an f64 in full), small ones as `1e-9`.
pub fn num(x: f64) -> String {
    let a = x.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e9).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// An error's message on one line: its lines joined with ": ", and a
/// backtrace it captured left out (candle's errors print theirs in their
/// message when `RUST_BACKTRACE` is set; a user error shows none).
pub fn one_line(message: &str) -> String {
    let mut parts = Vec::new();
    for line in message.lines() {
        let t = line.trim();
        if is_backtrace_line(t) {
            break;
        }
        if !t.is_empty() {
            parts.push(t);
        }
    }
    parts.join(": ")
}

/// A line that starts a backtrace: `stack backtrace:`, or a frame such as
/// `0: candle_core::error::Error::bt`.
fn is_backtrace_line(trimmed: &str) -> bool {
    if trimmed == "stack backtrace:" || trimmed == "Stack backtrace:" {
        return true;
    }
    let digits = trimmed.bytes().take_while(u8::is_ascii_digit).count();
    digits > 0 && trimmed[digits..].starts_with(": ") && trimmed[digits + 2..].contains("::")
}

#[cfg(test)]
mod one_line_tests {
    use super::*;

    #[test]
    fn a_captured_backtrace_is_left_out_and_lines_are_joined() {
        let candle = "shape mismatch for head.fc.weight, expected: [5, 1000], got: [5, 1280]\n   \
             0: candle_core::error::Error::bt\n             at ~/.cargo/src/error.rs:260:25\n   \
             1: <candle_core::safetensors::MmapedSafetensors as X>::get\n";
        assert_eq!(
            one_line(candle),
            "shape mismatch for head.fc.weight, expected: [5, 1000], got: [5, 1280]"
        );
        assert_eq!(
            one_line("loading head\ntensor missing"),
            "loading head: tensor missing"
        );
        assert_eq!(one_line("2: not a frame"), "2: not a frame");
        assert_eq!(
            (num(1e308), num(1e-9), num(0.5), num(-1.0)),
            ("1e308".into(), "1e-9".into(), "0.5".into(), "-1".into())
        );
        assert_eq!(num(f64::NAN), "NaN");
    }
}
