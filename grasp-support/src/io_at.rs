//! A file or folder operation that failed, with what was being done and
//! where: the io variant every library error of the project wraps.

use std::path::PathBuf;

/// `action path`, with the `std::io::Error` as its source: "cannot read
/// runs/main/data/train/manifest.jsonl: No such file or directory".
#[derive(Debug, thiserror::Error)]
#[error("{action} {}", path.display())]
pub struct IoAt {
    /// What was being done ("cannot read", "reading object file", ...).
    pub action: &'static str,
    pub path: PathBuf,
    #[source]
    pub source: std::io::Error,
}

impl IoAt {
    pub fn new(action: &'static str, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        IoAt {
            action,
            path: path.into(),
            source,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::IoAt;

    #[test]
    fn the_message_names_the_action_and_path_and_the_cause_follows() {
        let e = IoAt::new(
            "cannot read",
            "data/manifest.jsonl",
            std::io::Error::new(std::io::ErrorKind::NotFound, "gone"),
        );
        assert_eq!(e.to_string(), "cannot read data/manifest.jsonl");
        assert_eq!(
            crate::error_chain(&e),
            "cannot read data/manifest.jsonl: gone"
        );
    }
}
