//! Stopping cleanly on SIGINT (Ctrl-C), SIGTERM (`kill`, a service manager,
//! `scripts/main.sh`) and SIGHUP (the terminal closed): each sets a flag the
//! loops poll, so they return and destructors run (the simulated hand's
//! link is removed). The first signal is remembered ([`received`]): `run`
//! names it and exits with its code ([`Signal::exit_code`]). A second
//! signal ends the process at once.

use serde::{Serialize, Serializer};
use std::fmt;
use std::io;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};

static STOP: AtomicBool = AtomicBool::new(false);
/// The first signal received (0: none yet).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(signal: libc::c_int) {
    // Recorded before the flag, so whoever sees the flag finds the signal.
    if SIGNAL
        .compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst)
        .is_err()
    {
        // SAFETY: `_exit` is async-signal-safe.
        unsafe { libc::_exit(128 + signal) };
    }
    STOP.store(true, Ordering::SeqCst);
}

/// A signal that stopped the program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Signal(pub i32);

impl Signal {
    pub fn name(self) -> String {
        match self.0 {
            libc::SIGINT => "SIGINT".into(),
            libc::SIGTERM => "SIGTERM".into(),
            libc::SIGHUP => "SIGHUP".into(),
            n => format!("signal {n}"),
        }
    }

    /// The shell's convention for a program ended by signal N: 128 + N
    /// (130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP), so a script
    /// running `hannes-run` tells a stop from any failure of an approach.
    pub fn exit_code(self) -> u8 {
        u8::try_from(128 + self.0).unwrap_or(u8::MAX)
    }
}

impl fmt::Display for Signal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

impl Serialize for Signal {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.name())
    }
}

/// The first signal received since the handlers were installed, if any.
pub fn received() -> Option<Signal> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        n => Some(Signal(n)),
    }
}

/// Installs the handlers (once; later calls return the same flag) and
/// returns the flag they set.
pub fn stop_flag() -> io::Result<&'static AtomicBool> {
    for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: the handler only touches atomics and calls `_exit`, all
        // async-signal-safe; the sigaction struct is fully set.
        let r = unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut())
        };
        if r != 0 {
            return Err(io::Error::last_os_error());
        }
    }
    Ok(&STOP)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signals_are_named_and_exit_like_a_shell_reports_them() {
        assert_eq!(Signal(libc::SIGINT).name(), "SIGINT");
        assert_eq!(Signal(libc::SIGINT).exit_code(), 130);
        assert_eq!(Signal(libc::SIGTERM).exit_code(), 143);
        assert_eq!(Signal(libc::SIGHUP).exit_code(), 129);
        assert_eq!(
            serde_json::to_string(&Signal(libc::SIGTERM)).unwrap(),
            "\"SIGTERM\""
        );
    }
}
