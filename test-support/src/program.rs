//! A program run as a user runs it, and the conventions every one of the
//! three keeps (docs/testing.md): a user error is one `Error: ...` line
//! without a backtrace and exit code 1, printing into a closed pipe ends
//! by SIGPIPE without a panic, and logs into a pipe carry no colour codes.

use std::ffi::OsStr;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Output, Stdio};

/// One of the workspace's binaries (`env!("CARGO_BIN_EXE_NAME")`).
#[derive(Debug, Clone)]
pub struct Program {
    path: PathBuf,
}

/// What a finished run printed.
#[derive(Debug)]
pub struct Finished {
    pub status: ExitStatus,
    pub stdout: String,
    pub stderr: String,
}

impl Program {
    pub fn new(path: impl Into<PathBuf>) -> Program {
        Program { path: path.into() }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A command for this program, with a backtrace asked for: a user error
    /// must not show one even then.
    pub fn command<I, S>(&self, args: I) -> Command
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        let mut command = Command::new(&self.path);
        command.args(args).env("RUST_BACKTRACE", "1");
        command
    }

    /// Runs `args` to the end, stdin closed.
    pub fn run<I, S>(&self, args: I) -> Finished
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        let out = self
            .command(args)
            .stdin(Stdio::null())
            .output()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", self.path.display()));
        Finished::from(out)
    }

    /// Runs `args`, which must succeed.
    pub fn ok<I, S>(&self, args: I) -> Finished
    where
        I: IntoIterator<Item = S> + Clone,
        S: AsRef<OsStr>,
    {
        let done = self.run(args.clone());
        assert!(
            done.status.success(),
            "{} {:?} failed ({:?}):\n{}\n{}",
            self.name(),
            quoted(args),
            done.status,
            done.stdout,
            done.stderr
        );
        done
    }

    /// Runs `args`, which must fail as a user error does (see
    /// [`Finished::assert_user_error`]); the error line.
    pub fn user_error<I, S>(&self, args: I) -> String
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        self.run(args).assert_user_error()
    }

    /// Runs `args` with stdout a pipe whose reading end is already closed,
    /// as in `PROGRAM ... | head -0`; its status and stderr.
    pub fn into_closed_pipe<I, S>(&self, args: I) -> (ExitStatus, String)
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        let (reader, writer) = std::io::pipe().expect("a pipe");
        drop(reader);
        let out = self
            .command(args)
            .stdin(Stdio::null())
            .stdout(writer)
            .stderr(Stdio::piped())
            .output()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", self.path.display()));
        (
            out.status,
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }

    /// Runs `args` into a closed pipe ([`Program::into_closed_pipe`]) and
    /// checks that it ends by SIGPIPE, quietly; its stderr.
    pub fn assert_quiet_in_closed_pipe<I, S>(&self, args: I) -> String
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        let (status, stderr) = self.into_closed_pipe(args);
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert_eq!(status.signal(), Some(libc::SIGPIPE), "{status:?} {stderr}");
        stderr
    }

    fn name(&self) -> String {
        self.path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    }
}

impl From<Output> for Finished {
    fn from(out: Output) -> Finished {
        Finished {
            status: out.status,
            stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        }
    }
}

impl Finished {
    /// The last line of stderr (where a failed program says why).
    pub fn last_line(&self) -> &str {
        self.stderr.lines().last().unwrap_or_default()
    }

    /// Checks that the run failed as a user error does: exit code 1, no
    /// panic, no backtrace although one was asked for, and the reason on
    /// the last line after `Error: `; that line.
    pub fn assert_user_error(&self) -> String {
        let stderr = &self.stderr;
        assert_eq!(self.status.code(), Some(1), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(!stderr.to_lowercase().contains("backtrace"), "{stderr}");
        let last = self.last_line();
        assert!(last.starts_with("Error: "), "{stderr}");
        last.to_string()
    }
}

/// Checks that `log` (a program's stderr into a pipe) has no ANSI colour
/// codes.
pub fn assert_no_colour_codes(log: &str) {
    assert!(
        !log.contains('\x1b'),
        "ANSI escape codes in a pipe: {log:?}"
    );
}

fn quoted<I, S>(args: I) -> Vec<String>
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    args.into_iter()
        .map(|a| a.as_ref().to_string_lossy().into_owned())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failing_program_is_reported_with_its_output() {
        let sh = Program::new("/bin/sh");
        assert_eq!(sh.ok(["-c", "echo hi"]).stdout, "hi\n");
        let failed = std::panic::catch_unwind(|| sh.ok(["-c", "echo why >&2; exit 3"]));
        let message = failed.expect_err("a failure is an assertion");
        let text = message
            .downcast_ref::<String>()
            .cloned()
            .unwrap_or_default();
        assert!(text.contains("why") && text.contains("sh"), "{text}");
    }

    #[test]
    fn a_user_error_needs_code_1_and_its_reason_last() {
        let sh = Program::new("/bin/sh");
        let line = sh.user_error(["-c", "echo 'Error: no such file x.toml' >&2; exit 1"]);
        assert_eq!(line, "Error: no such file x.toml");
        for script in [
            "echo 'Error: x' >&2; exit 2",
            "echo 'Error: x' >&2; echo 'stack backtrace:' >&2; exit 1",
            "echo 'x' >&2; exit 1",
        ] {
            let result = std::panic::catch_unwind(|| sh.user_error(["-c", script]));
            assert!(result.is_err(), "{script} passed as a user error");
        }
    }

    #[test]
    fn writing_into_a_closed_pipe_ends_by_sigpipe() {
        let sh = Program::new("/bin/sh");
        sh.assert_quiet_in_closed_pipe(["-c", "while :; do echo y; done"]);
        let quiet = std::panic::catch_unwind(|| sh.assert_quiet_in_closed_pipe(["-c", "true"]));
        assert!(quiet.is_err(), "an exit without writing is not SIGPIPE");
    }
}
