//! The programs' `main`, for the binaries alone (`grasp-gen`, `grasp-train`,
//! `hannes-run` all call [`main`]): the libraries return typed errors, and
//! anyhow lives only here and in the binaries. What every program does the
//! same way:
//!
//! - an error prints as one line, `Error: context: cause: root cause`, and
//!   never a backtrace, whatever `RUST_BACKTRACE` says (user errors are not
//!   bugs); a panic, which is a bug, keeps Rust's report and backtrace;
//! - an error may carry its exit code ([`Failure`]); any other error exits
//!   with 1 (clap's usage errors exit with 2 before `main`'s body runs);
//! - logs go to stderr, at `info` unless `RUST_LOG` says otherwise, coloured
//!   only when stderr is a terminal ([`init_logging`]), so that log files
//!   and CI output carry no ANSI escape codes;
//! - printing to a closed pipe (`grasp-gen render | head -1`) ends the
//!   program quietly the way it ends C programs: killed by SIGPIPE (a
//!   shell reports status 141), after the main thread unwound, so
//!   temporary files and child processes are cleaned up.
//!
//! Rust ignores SIGPIPE, so `println!` to a closed pipe panics with
//! "failed printing to stdout: Broken pipe". Restoring SIGPIPE's default
//! action instead would also kill a program writing to a dead worker's pipe,
//! an error the generator handles; so only that panic is recognised.

use std::fmt;
use std::io::Write;
use std::panic::{self, AssertUnwindSafe, PanicHookInfo};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

/// An error that ends the program with a chosen exit code.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Failure {
    pub code: u8,
    pub reason: String,
}

impl Failure {
    pub fn new(code: u8, reason: impl Into<String>) -> Self {
        Failure {
            code,
            reason: reason.into(),
        }
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.reason)
    }
}

impl std::error::Error for Failure {}

/// Exit code of an error: the code of the first [`Failure`] in its chain,
/// else 1.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    // `downcast_ref` also finds a Failure given as context; the chain finds
    // one wrapped as the source of another error.
    e.downcast_ref::<Failure>()
        .or_else(|| e.chain().find_map(|c| c.downcast_ref::<Failure>()))
        .map_or(1, |f| f.code)
}

/// The one line printed for an error.
pub fn error_line(e: &anyhow::Error) -> String {
    // Each cause on one line, a backtrace it captured left out (candle's).
    let chain: Vec<String> = e
        .chain()
        .map(|c| grasp_support::one_line(&c.to_string()))
        .collect();
    format!("Error: {}", chain.join(": "))
}

/// The programs' log subscriber: stderr, `RUST_LOG` (default `info`), ANSI
/// colours only on a terminal.
pub fn init_logging() {
    use std::io::IsTerminal;
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .init();
}

/// Runs a program's body with the conventions above:
/// `fn main() -> ExitCode { grasp_main::main(|| { ... }) }`.
pub fn main(body: impl FnOnce() -> anyhow::Result<()>) -> ExitCode {
    install_panic_hook();
    match panic::catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            let _ = writeln!(std::io::stderr(), "{}", error_line(&e));
            ExitCode::from(exit_code(&e))
        }
        Err(_) if CLOSED_PIPE.load(Ordering::SeqCst) => die_of_sigpipe(),
        Err(payload) => panic::resume_unwind(payload),
    }
}

/// Ends the process now with `code`, after flushing stdout and stderr,
/// without running exit handlers or C++ static destructors: a program that
/// loaded Blender's `bpy` would otherwise end with Blender's leak detector
/// report of its own statics ("Not freed memory blocks: ...") although
/// nothing went wrong. Only for a body whose work is done.
pub fn exit_now(code: u8) -> ! {
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    // SAFETY: _exit only ends the process; nothing runs after it.
    unsafe { libc::_exit(i32::from(code)) }
}

/// Set once a print to a closed stdout or stderr panicked.
static CLOSED_PIPE: AtomicBool = AtomicBool::new(false);

fn install_panic_hook() {
    let default = panic::take_hook();
    panic::set_hook(Box::new(move |info| {
        if !is_print_to_closed_pipe(info) {
            return default(info);
        }
        CLOSED_PIPE.store(true, Ordering::SeqCst);
        // The main thread unwinds to `main`, which then ends the process;
        // another thread would just die and leave the program running.
        if std::thread::current().name() != Some("main") {
            die_of_sigpipe();
        }
    }));
}

/// Whether a panic is `print!`'s (or `eprint!`'s) on a closed pipe.
fn is_print_to_closed_pipe(info: &PanicHookInfo<'_>) -> bool {
    let payload = info.payload();
    let message = payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied());
    let Some(message) = message else {
        return false;
    };
    let broken_pipe = std::io::Error::from_raw_os_error(libc::EPIPE).to_string();
    (message.starts_with("failed printing to stdout")
        || message.starts_with("failed printing to stderr"))
        && message.ends_with(&broken_pipe)
}

/// Ends the process the way a closed pipe ends a C program.
fn die_of_sigpipe() -> ! {
    // SAFETY: restoring a signal's default action and raising it are
    // async-signal-safe and touch no Rust state.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        libc::raise(libc::SIGPIPE);
    }
    std::process::exit(128 + libc::SIGPIPE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context;

    #[test]
    fn the_first_failure_in_the_chain_gives_the_exit_code() {
        let plain = anyhow::anyhow!("bad config");
        assert_eq!(exit_code(&plain), 1);
        let failed: anyhow::Error = Failure::new(4, "cannot reach the hand").into();
        let wrapped = Err::<(), _>(failed).context("approach 2").unwrap_err();
        assert_eq!(exit_code(&wrapped), 4);
        assert_eq!(
            error_line(&wrapped),
            "Error: approach 2: cannot reach the hand"
        );
        let as_context = anyhow::anyhow!("no such device")
            .context(Failure::new(5, "cannot start"))
            .context("run");
        assert_eq!(exit_code(&as_context), 5);
        assert_eq!(
            error_line(&as_context),
            "Error: run: cannot start: no such device"
        );
    }

    #[test]
    fn the_error_line_holds_the_whole_chain_and_no_backtrace() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file");
        let e = Err::<(), _>(io)
            .context("cannot read config run.toml")
            .unwrap_err();
        let line = error_line(&e);
        assert_eq!(line, "Error: cannot read config run.toml: No such file");
        assert!(!line.contains('\n'));
    }
}
