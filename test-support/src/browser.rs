//! A page opened in headless Chromium as a user's browser would open it
//! from disk: the DOM after its scripts ran, the console's messages, and a
//! screenshot. Find the browser with [`crate::prerequisite::require_browser`].

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// What the browser made of a page.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The document after its scripts ran (`--dump-dom`).
    pub dom: String,
    /// The browser's log (`--enable-logging=stderr`): console messages and
    /// uncaught exceptions appear as `CONSOLE` lines.
    pub log: String,
}

impl Rendered {
    /// Console lines that report an uncaught script error.
    pub fn script_errors(&self) -> Vec<&str> {
        self.log
            .lines()
            .filter(|l| l.contains("CONSOLE") && l.contains("Uncaught"))
            .collect()
    }
}

/// How long one browser run may take before the test fails.
const TIMEOUT: Duration = Duration::from_secs(120);

fn base(browser: &Path, profile: &Path) -> Command {
    let mut c = Command::new(browser);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        "--no-first-run",
        "--disable-extensions",
        "--allow-file-access-from-files",
        "--enable-logging=stderr",
        "--v=0",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

fn url(page: &Path, fragment: &str) -> String {
    let abs = std::path::absolute(page).unwrap_or_else(|_| page.to_path_buf());
    match fragment {
        "" => format!("file://{}", abs.display()),
        f => format!("file://{}#{f}", abs.display()),
    }
}

/// Runs `cmd` to the end (at most [`TIMEOUT`]): stdout and stderr.
fn run(mut cmd: Command, what: &str) -> (String, String) {
    let child = cmd
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start the browser for {what}: {e}"));
    let id = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    let out = match rx.recv_timeout(TIMEOUT) {
        Ok(out) => out.unwrap_or_else(|e| panic!("the browser failed on {what}: {e}")),
        Err(_) => {
            // SAFETY: kill(2) on the child this function started.
            unsafe { libc::kill(id as i32, libc::SIGKILL) };
            panic!("the browser took over {TIMEOUT:?} on {what}");
        }
    };
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Opens `page` and returns its DOM after the scripts ran.
pub fn dump_dom(browser: &Path, page: &Path) -> Rendered {
    dump_dom_at(browser, page, "")
}

/// [`dump_dom`] at `page#fragment` (what a page's script reads from the
/// address, e.g. preset filters).
pub fn dump_dom_at(browser: &Path, page: &Path, fragment: &str) -> Rendered {
    let profile = tempdir("dom");
    let mut cmd = base(browser, &profile);
    cmd.arg("--dump-dom").arg(url(page, fragment));
    let (dom, log) = run(cmd, &page.display().to_string());
    let _ = std::fs::remove_dir_all(&profile);
    Rendered { dom, log }
}

/// A `width` x `height` screenshot of `page` into `png`; returns the log.
pub fn screenshot(browser: &Path, page: &Path, png: &Path, width: u32, height: u32) -> String {
    let profile = tempdir("shot");
    let mut cmd = base(browser, &profile);
    cmd.arg(format!("--screenshot={}", png.display()))
        .arg(format!("--window-size={width},{height}"))
        .arg(url(page, ""));
    let (_, log) = run(cmd, &page.display().to_string());
    let _ = std::fs::remove_dir_all(&profile);
    assert!(
        png.is_file(),
        "the browser wrote no screenshot of {}:\n{log}",
        page.display()
    );
    log
}

/// A fresh browser profile folder (parallel tests must not share one).
fn tempdir(what: &str) -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("grasp-browser-{}-{what}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
