//! SHA-256 of weight files (recorded in checkpoints and feature-cache keys,
//! checked when a checkpoint is loaded).

use crate::error::{ModelError, Result};
use sha2::{Digest, Sha256};
use std::path::Path;

/// SHA-256 of a file's bytes, hex.
pub fn file_sha256(path: &Path) -> Result<String> {
    let mut file = std::fs::File::open(path).map_err(|e| ModelError::read("file", path, e))?;
    let mut hasher = Sha256::new();
    std::io::copy(&mut file, &mut hasher).map_err(|e| ModelError::read("file", path, e))?;
    Ok(hex(&hasher.finalize()))
}

/// SHA-256 of `bytes`, hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_digest_and_missing_file() {
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let err = file_sha256(Path::new("/nonexistent/weights.pth")).unwrap_err();
        assert!(err.is_missing(), "{err}");
        assert!(err.to_string().contains("weights.pth"), "{err}");
    }
}
