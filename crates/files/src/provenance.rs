//! Provenance: which inputs produced a result, by content hash.

use std::path::Path;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// One input file of a result: its path as given and the SHA-256 of its bytes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputDigest {
    /// Path as the command or the scene named it.
    pub path: String,
    /// What it is (`scene`, `actuator`, `urdf`, `rig`, `log`, ...).
    pub role: String,
    /// Lower-case hex SHA-256 of the file's bytes.
    pub sha256: String,
    /// Size, bytes.
    pub bytes: u64,
}

/// Lower-case hex SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    let d = Sha256::digest(bytes);
    let mut s = String::with_capacity(64);
    for b in d {
        s.push_str(&format!("{b:02x}"));
    }
    s
}

impl InputDigest {
    /// Hashes a file (read whole; inputs are size-limited when they are parsed).
    pub fn of_file(path: &Path, role: &str) -> std::io::Result<Self> {
        let bytes = std::fs::read(path)?;
        Ok(Self {
            path: path.display().to_string(),
            role: role.to_string(),
            sha256: sha256_hex(&bytes),
            bytes: bytes.len() as u64,
        })
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn sha256_of_abc_is_the_fips_180_example() {
        assert_eq!(
            super::sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
