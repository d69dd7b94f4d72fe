//! Paths between the files of a project: a file named from another folder than the one it was named from
//! (a tuned copy of a scene written into its output directory must still find the sheet and the URDF).

use std::path::{Component, Path, PathBuf};

/// `target` as a path relative to the folder `base_dir` (both made absolute and, where they exist,
/// canonical); `target` itself, absolute, when the two share no root (another drive).
pub fn relative_to(target: &Path, base_dir: &Path) -> PathBuf {
    let abs = |p: &Path| {
        let a = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        std::fs::canonicalize(&a).unwrap_or(a)
    };
    let (t, b) = (abs(target), abs(base_dir));
    let tc: Vec<Component> = t.components().collect();
    let bc: Vec<Component> = b.components().collect();
    if tc.first() != bc.first() {
        return t;
    }
    let common = tc.iter().zip(&bc).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..bc.len() {
        out.push("..");
    }
    for c in &tc[common..] {
        out.push(c.as_os_str());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sibling_folder_is_reached_through_the_parent() {
        assert_eq!(
            relative_to(
                Path::new("/a/b/pneumatics/s.toml"),
                Path::new("/a/b/out/tune")
            ),
            PathBuf::from("../../pneumatics/s.toml")
        );
        assert_eq!(
            relative_to(Path::new("/a/b/c.toml"), Path::new("/a/b")),
            PathBuf::from("c.toml")
        );
    }
}
