//! The layout rules of ARCHITECTURE.md, checked on the source text:
//!
//! 1. Modules import only their own tier or lower:
//!    `util ← scene ← (sam, models, segment, space) ← field ← supervision ← fit ← removal ←
//!    (mesh, render, edit, export, demo) ← pipeline ← (bench, batch) ← cli`.
//! 2. No two modules import each other, at any depth: neither two top-level modules nor two files
//!    (a cycle through `mod.rs` re-exports counts).
//! 3. Only the command line prints, draws progress bars or reads argv; `main.rs` stays short.
//!
//! Imports are read from `crate::` and `super::` paths (in `use` statements, with their braces
//! expanded, and inline), outside `#[cfg(test)]` modules.

mod common;

use common::rust_files;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Each top-level module's tier: it may import its own tier and lower ones.
const TIERS: &[(&str, u32)] = &[
    ("error", 0),
    ("util", 0),
    ("scene", 1),
    ("sam", 2),
    ("models", 2),
    ("segment", 2),
    ("space", 2),
    ("field", 3),
    ("supervision", 4),
    ("fit", 5),
    ("removal", 6),
    ("mesh", 7),
    ("render", 7),
    ("edit", 7),
    ("export", 7),
    ("demo", 7),
    ("pipeline", 8),
    ("bench", 9),
    ("batch", 9),
    ("cli", 10),
];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The file's module path (`src/field/io.rs` -> [field, io]; `src/field/mod.rs` -> [field]).
fn module_path(file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src()).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts
        .last()
        .is_some_and(|l| l == "mod" || l == "lib" || l == "main")
    {
        parts.pop();
    }
    parts
}

/// The code without comments, string contents and `#[cfg(test)]` modules (which by this
/// project's convention close the file).
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => text,
    };
    let mut out = String::with_capacity(text.len());
    let b: Vec<char> = text.chars().collect();
    let mut i = 0;
    while i < b.len() {
        if b[i] == '/' && b.get(i + 1) == Some(&'/') {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
        } else if b[i] == '"' {
            out.push('"');
            i += 1;
            while i < b.len() && b[i] != '"' {
                i += if b[i] == '\\' { 2 } else { 1 };
            }
            out.push('"');
            i += 1;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    out
}

/// Expand a `use` tree (`a::{b, c::{d, e}}`) into full paths.
fn expand(tree: &str) -> Vec<String> {
    let tree: String = tree.chars().filter(|c| !c.is_whitespace()).collect();
    let Some(open) = tree.find('{') else {
        return vec![tree.split(" as ").next().unwrap_or(&tree).to_string()];
    };
    let prefix = &tree[..open];
    let inner = &tree[open + 1..tree.rfind('}').unwrap()];
    let mut parts = Vec::new();
    let (mut depth, mut start) = (0, 0);
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&inner[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[start..]);
    parts
        .into_iter()
        .filter(|p| !p.is_empty())
        .flat_map(|p| {
            expand(p).into_iter().map(move |q| {
                if q == "self" {
                    prefix.trim_end_matches("::").to_string()
                } else {
                    format!("{prefix}{q}")
                }
            })
        })
        .collect()
}

/// Paths a file refers to: (is a `pub use` re-export, path).
fn references(code: &str) -> Vec<(bool, String)> {
    let mut refs = Vec::new();
    // `use` statements, braces expanded.
    let mut rest = code;
    while let Some(i) = rest.find("use ") {
        let before = &rest[..i];
        let at_start = before.is_empty()
            || before.ends_with(|c: char| c.is_whitespace() || c == ';' || c == '{' || c == '}');
        let end = rest[i..].find(';').map(|e| i + e).unwrap_or(rest.len());
        if at_start {
            let public = before.trim_end().ends_with("pub") || before.trim_end().ends_with(')');
            for p in expand(&rest[i + 4..end]) {
                refs.push((public, p));
            }
        }
        rest = &rest[(end + 1).min(rest.len())..];
    }
    // Inline paths (`crate::a::b(...)`): the run of `word::` after `crate` or `super`.
    let bytes = code.as_bytes();
    for key in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(i) = code[from..].find(key) {
            let s = from + i;
            from = s + key.len();
            // Inside a longer path (`a::super::`, the second `super` of `super::super::`).
            if s > 0
                && (bytes[s - 1].is_ascii_alphanumeric()
                    || bytes[s - 1] == b'_'
                    || bytes[s - 1] == b':')
            {
                continue;
            }
            let mut e = s;
            while e < code.len()
                && (bytes[e].is_ascii_alphanumeric() || bytes[e] == b'_' || bytes[e] == b':')
            {
                e += 1;
            }
            refs.push((false, code[s..e].trim_end_matches(':').to_string()));
        }
    }
    refs
}

/// The folder holding module `at`'s children.
fn module_dir(at: &[String]) -> PathBuf {
    at.iter().fold(src(), |d, p| d.join(p))
}

/// A path relative to the crate root, from `crate::`/`super::` paths seen in module `at`.
fn absolute(path: &str, at: &[String], is_mod_file: bool) -> Option<Vec<String>> {
    let mut parts: Vec<&str> = path.split("::").collect();
    let mut base: Vec<String> = match parts.first()? {
        &"crate" => {
            parts.remove(0);
            vec![]
        }
        &"super" => {
            // `super` of a mod.rs is its parent; of a file `a/b.rs`, the module `a`.
            let mut b = at.to_vec();
            b.pop();
            let _ = is_mod_file;
            parts.remove(0);
            while parts.first() == Some(&"super") {
                b.pop();
                parts.remove(0);
            }
            b
        }
        &"self" => {
            parts.remove(0);
            at.to_vec()
        }
        // A child module named without a prefix (`pub use train::Trainer;` in a mod.rs).
        first
            if module_dir(at).join(format!("{first}.rs")).is_file()
                || module_dir(at).join(first).join("mod.rs").is_file() =>
        {
            at.to_vec()
        }
        _ => return None,
    };
    base.extend(
        parts
            .iter()
            .filter(|p| !p.is_empty() && **p != "*")
            .map(|p| p.to_string()),
    );
    Some(base)
}

/// The file a module path lands in: the deepest existing module file; through a `mod.rs`, a name
/// it re-exports lands in the file it comes from.
fn resolve(
    path: &[String],
    reexports: &BTreeMap<PathBuf, BTreeMap<String, Vec<String>>>,
) -> Option<PathBuf> {
    let root = src();
    let mut file: Option<PathBuf> = None;
    let mut dir = root.clone();
    for (k, part) in path.iter().enumerate() {
        let as_file = dir.join(format!("{part}.rs"));
        let as_dir = dir.join(part).join("mod.rs");
        if as_file.is_file() {
            file = Some(as_file);
            dir = dir.join(part);
        } else if as_dir.is_file() {
            file = Some(as_dir);
            dir = dir.join(part);
        } else {
            // An item: if the module file is a mod.rs re-exporting it, follow the re-export.
            let f = file.clone()?;
            if let Some(target) = reexports.get(&f).and_then(|m| m.get(part)) {
                if target.as_slice() != &path[..k] {
                    return resolve(target, reexports).or(Some(f));
                }
            }
            return Some(f);
        }
    }
    file
}

struct Source {
    file: PathBuf,
    module: Vec<String>,
    refs: Vec<(bool, Vec<String>)>,
}

fn sources() -> Vec<Source> {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    files.sort();
    files
        .into_iter()
        .map(|file| {
            let code = code_of(&std::fs::read_to_string(&file).unwrap());
            let module = module_path(&file);
            let is_mod = file.ends_with("mod.rs");
            let refs = references(&code)
                .into_iter()
                .filter_map(|(public, p)| Some((public, absolute(&p, &module, is_mod)?)))
                .collect();
            Source { file, module, refs }
        })
        .collect()
}

/// `pub use` re-exports of every mod.rs: name -> the module path it comes from.
fn reexports(sources: &[Source]) -> BTreeMap<PathBuf, BTreeMap<String, Vec<String>>> {
    let mut out = BTreeMap::new();
    for s in sources.iter().filter(|s| s.file.ends_with("mod.rs")) {
        let mut names = BTreeMap::new();
        for (public, p) in &s.refs {
            if *public && p.len() > 1 {
                names.insert(p.last().unwrap().clone(), p.clone());
            }
        }
        out.insert(s.file.clone(), names);
    }
    out
}

fn tier(module: &str) -> u32 {
    TIERS
        .iter()
        .find(|(m, _)| *m == module)
        .map(|t| t.1)
        .unwrap_or_else(|| {
            panic!("module '{module}' has no tier: add it to TIERS and ARCHITECTURE.md")
        })
}

/// A cycle in `graph`, if any, as the list of its nodes.
fn find_cycle<T: Ord + Clone>(graph: &BTreeMap<T, BTreeSet<T>>) -> Option<Vec<T>> {
    fn visit<T: Ord + Clone>(
        n: &T,
        graph: &BTreeMap<T, BTreeSet<T>>,
        state: &mut BTreeMap<T, u8>,
        stack: &mut Vec<T>,
    ) -> Option<Vec<T>> {
        state.insert(n.clone(), 1);
        stack.push(n.clone());
        for m in graph.get(n).into_iter().flatten() {
            match state.get(m).copied().unwrap_or(0) {
                1 => {
                    let i = stack.iter().position(|x| x == m).unwrap();
                    let mut c = stack[i..].to_vec();
                    c.push(m.clone());
                    return Some(c);
                }
                0 => {
                    if let Some(c) = visit(m, graph, state, stack) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(n.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for n in graph.keys() {
        if state.get(n).copied().unwrap_or(0) == 0 {
            if let Some(c) = visit(n, graph, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

/// The library's sources (the command line is part of the binary and imports `objnerf::`).
fn library(sources: &[Source]) -> impl Iterator<Item = &Source> {
    sources
        .iter()
        .filter(|s| !s.module.is_empty() && s.module[0] != "cli")
}

/// Every import in `sources` into a higher tier, as a line for the failure message.
fn upward_imports<'a>(sources: impl Iterator<Item = &'a Source>) -> Vec<String> {
    let mut bad = Vec::new();
    for s in sources {
        let own = tier(&s.module[0]);
        for (_, p) in &s.refs {
            let Some(top) = p.first() else { continue };
            if top == "Error" || top == "Result" || top == "Scene" {
                continue; // re-exported at the crate root from error and scene
            }
            if tier(top) > own {
                bad.push(format!(
                    "{} imports {} (tier {} > {own})",
                    s.file.display(),
                    p.join("::"),
                    tier(top)
                ));
            }
        }
    }
    bad
}

#[test]
fn modules_import_only_their_tier_or_lower() {
    let sources = sources();
    let bad = upward_imports(library(&sources));
    assert!(bad.is_empty(), "upward imports:\n{}", bad.join("\n"));
}

#[test]
fn no_two_modules_import_each_other() {
    let sources = sources();
    let re = reexports(&sources);
    let mut modules: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut files: BTreeMap<PathBuf, BTreeSet<PathBuf>> = BTreeMap::new();
    for s in library(&sources) {
        for (public, p) in &s.refs {
            let Some(top) = p.first() else { continue };
            if ["Error", "Result", "Scene"].contains(&top.as_str()) {
                continue;
            }
            if top != &s.module[0] {
                modules
                    .entry(s.module[0].clone())
                    .or_default()
                    .insert(top.clone());
            }
            // A mod.rs re-exporting its own submodules depends on nothing by doing so.
            if *public && s.file.ends_with("mod.rs") {
                continue;
            }
            if let Some(target) = resolve(p, &re) {
                if target != s.file {
                    files.entry(s.file.clone()).or_default().insert(target);
                }
            }
        }
    }
    if let Some(c) = find_cycle(&modules) {
        panic!("top-level modules import each other: {}", c.join(" -> "));
    }
    if let Some(c) = find_cycle(&files) {
        let names: Vec<String> = c
            .iter()
            .map(|f| f.strip_prefix(src()).unwrap().display().to_string())
            .collect();
        panic!("files import each other: {}", names.join(" -> "));
    }
}

#[test]
fn only_the_command_line_prints() {
    let sources = sources();
    let mut bad = Vec::new();
    for s in library(&sources) {
        let code = code_of(&std::fs::read_to_string(&s.file).unwrap());
        for needle in [
            "println!",
            "eprintln!",
            "print!",
            "eprint!",
            "dbg!",
            "indicatif",
            "env::args",
        ] {
            if code
                .match_indices(needle)
                .any(|(i, _)| i == 0 || !code.as_bytes()[i - 1].is_ascii_alphanumeric())
            {
                bad.push(format!("{}: {needle}", s.file.display()));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "library code that prints or reads argv:\n{}",
        bad.join("\n")
    );
    let main = std::fs::read_to_string(src().join("main.rs")).unwrap();
    assert!(
        main.lines().count() <= 40,
        "main.rs has {} lines",
        main.lines().count()
    );
}

#[test]
fn the_checker_sees_imports() {
    // The parser itself: braces, `self`, `super`, re-exports; so a broken checker cannot pass.
    assert_eq!(
        expand("crate::a::{b, c::{d, self}}"),
        ["crate::a::b", "crate::a::c::d", "crate::a::c"]
    );
    let at = vec!["field".to_string(), "io".to_string()];
    assert_eq!(
        absolute("super::train::X", &at, false).unwrap(),
        ["field", "train", "X"]
    );
    assert_eq!(
        references("x = super::super::render::f();"),
        [(false, "super::super::render::f".to_string())]
    );
    let re = reexports(&sources());
    assert_eq!(
        resolve(&["field".into(), "Trainer".into()], &re).unwrap(),
        src().join("field/train/mod.rs")
    );
    // The tiers of the pipeline: the field's core may not reach up to its supervision, the
    // fits, removal or the stages after them; removal may use the fits, not the pipeline.
    let planted = |module: &str, import: &str| Source {
        file: src().join(format!("{module}/planted.rs")),
        module: vec![module.to_string(), "planted".to_string()],
        refs: vec![(false, import.split("::").map(String::from).collect())],
    };
    for (module, import) in [
        ("field", "supervision::depth::add_sparse_depth"),
        ("field", "fit::FitOptions"),
        ("supervision", "fit::DepthMode"),
        ("fit", "removal::hole::find_unseen"),
        ("removal", "pipeline::remove::remove"),
        ("space", "field::Field"),
        ("mesh", "pipeline::extract"),
    ] {
        let s = [planted(module, import)];
        assert_eq!(upward_imports(s.iter()).len(), 1, "{module} -> {import}");
    }
    for (module, import) in [("removal", "fit::SceneFit"), ("fit", "space::Space")] {
        let s = [planted(module, import)];
        assert!(upward_imports(s.iter()).is_empty(), "{module} -> {import}");
    }
    let mut g: BTreeMap<u8, BTreeSet<u8>> = BTreeMap::new();
    g.entry(1).or_default().insert(2);
    g.entry(2).or_default().insert(1);
    assert!(find_cycle(&g).is_some());
}
