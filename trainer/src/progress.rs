//! Progress of long steps (features, training epochs, evaluation): a bar on
//! a terminal, and a log line at most every [`LOG_INTERVAL`] otherwise, so
//! that a job's log (`scripts/main.sh`, a cluster's output file) shows
//! where a step is and how long it has left instead of minutes of silence.

use indicatif::{ProgressBar, ProgressStyle};
use std::cell::{Cell, RefCell};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// How often a step's progress is logged when stderr is not a terminal.
pub const LOG_INTERVAL: Duration = Duration::from_secs(30);

/// A step's progress: `inc` as units finish, `finish` at the end.
pub struct Progress {
    bar: ProgressBar,
    log: Option<LogLines>,
}

/// The log-line form of a bar.
struct LogLines {
    prefix: String,
    len: u64,
    pos: Cell<u64>,
    started: Instant,
    last: Cell<Instant>,
    message: RefCell<String>,
}

/// A progress bar on a terminal, log lines elsewhere.
pub fn bar(len: u64, prefix: &str) -> Progress {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{prefix:>10} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}")
            .expect("valid template"),
    );
    bar.set_prefix(prefix.to_string());
    let now = Instant::now();
    let log = (!std::io::stderr().is_terminal()).then(|| LogLines {
        prefix: prefix.to_string(),
        len,
        pos: Cell::new(0),
        started: now,
        last: Cell::new(now),
        message: RefCell::new(String::new()),
    });
    Progress { bar, log }
}

impl Progress {
    pub fn set_message(&self, message: String) {
        if let Some(log) = &self.log {
            *log.message.borrow_mut() = message.clone();
        }
        self.bar.set_message(message);
    }

    pub fn inc(&self, n: u64) {
        self.bar.inc(n);
        if let Some(log) = &self.log {
            log.pos.set(log.pos.get() + n);
            let now = Instant::now();
            if now.duration_since(log.last.get()) >= LOG_INTERVAL {
                log.last.set(now);
                tracing::info!("{}", log.line(now));
            }
        }
    }

    /// Ends the bar; a step that logged progress logs its end too.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
        if let Some(log) = &self.log {
            if log.last.get() != log.started {
                tracing::info!("{}", log.line(Instant::now()));
            }
        }
    }
}

impl LogLines {
    fn line(&self, now: Instant) -> String {
        grasp_support::progress::progress_line(
            &self.prefix,
            self.pos.get(),
            self.len,
            now.duration_since(self.started),
            &self.message.borrow(),
        )
    }
}
