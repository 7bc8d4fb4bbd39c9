//! Path arithmetic for formats that store paths relative to the file that lists them. Lexical
//! (no symlinks resolved) except [`same_file_or_path`].

use std::path::{Component, Path, PathBuf};

/// `path` with `.` components dropped and `..` folded where it follows a normal component.
pub fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir
                if matches!(out.components().next_back(), Some(Component::Normal(_))) =>
            {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// `path` made absolute against the current folder, then normalised.
pub fn absolute(path: &Path) -> PathBuf {
    normalize(&std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()))
}

/// `path` relative to the folder `base`, by components (no file system access).
pub fn relative_to(path: &Path, base: &Path) -> PathBuf {
    let (p, b) = (absolute(path), absolute(base));
    let pc: Vec<_> = p.components().collect();
    let bc: Vec<_> = b.components().collect();
    let common = pc.iter().zip(&bc).take_while(|(a, b)| a == b).count();
    let mut out = PathBuf::new();
    for _ in common..bc.len() {
        out.push("..");
    }
    for c in &pc[common..] {
        out.push(c);
    }
    out
}

/// Whether two paths name the same file: by the file system where both exist, else by their
/// normalised absolute forms.
pub fn same_file_or_path(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => absolute(a) == absolute(b),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths() {
        assert_eq!(
            relative_to(Path::new("/a/b/c.png"), Path::new("/a")),
            Path::new("b/c.png")
        );
        assert_eq!(
            relative_to(Path::new("/a/b/c.png"), Path::new("/a/d/")),
            Path::new("../b/c.png")
        );
        assert_eq!(
            relative_to(Path::new("/a/./b/../c.png"), Path::new("/a")),
            Path::new("c.png")
        );
        assert_eq!(normalize(Path::new("./train/r_0")), Path::new("train/r_0"));
        assert_eq!(normalize(Path::new("../x/./y")), Path::new("../x/y"));
    }
}
