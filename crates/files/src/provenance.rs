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
    hex(&Sha256::digest(bytes))
}

fn hex(d: &[u8]) -> String {
    let mut s = String::with_capacity(64);
    for b in d {
        s.push_str(&format!("{b:02x}"));
    }
    s
}

/// SHA-256 of bytes that come in pieces (a file read line by line).
#[derive(Clone, Debug, Default)]
pub struct Sha256Hasher(Sha256);

impl Sha256Hasher {
    /// An empty hash.
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }
    /// The lower-case hex digest of everything added.
    pub fn finish(self) -> String {
        hex(&self.0.finalize())
    }
}

impl InputDigest {
    /// Hashes a file, in blocks (a large log is never held whole).
    pub fn of_file(path: &Path, role: &str) -> std::io::Result<Self> {
        use std::io::Read;
        let mut f = std::fs::File::open(path)?;
        let mut h = Sha256Hasher::new();
        let mut buf = vec![0u8; 1 << 16];
        let mut bytes = 0u64;
        loop {
            let n = f.read(&mut buf)?;
            if n == 0 {
                break;
            }
            h.update(&buf[..n]);
            bytes += n as u64;
        }
        Ok(Self {
            path: path.display().to_string(),
            role: role.to_string(),
            sha256: h.finish(),
            bytes,
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
        let mut h = super::Sha256Hasher::new();
        h.update(b"a");
        h.update(b"bc");
        assert_eq!(h.finish(), super::sha256_hex(b"abc"));
    }
}
