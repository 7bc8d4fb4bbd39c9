//! `docs/self-checks.md` is the one list of the self-checks: every warning code the library can
//! raise is in it, every code in it is raised where it says, and every floor it quotes has the
//! value of the constant in the code.

mod common;

use common::{repo_root, rust_files};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// A row of the table: code, file, and the floors as (constant, value).
struct Row {
    code: String,
    file: PathBuf,
    floors: Vec<(String, String)>,
}

fn rows() -> Vec<Row> {
    let doc = std::fs::read_to_string(repo_root().join("docs/self-checks.md")).unwrap();
    let tick = |s: &str| s.trim().trim_matches('`').to_string();
    doc.lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            let floors = cells[4]
                .split(", `")
                .map(|f| {
                    let (name, value) = f.split_once('=').expect("floor as `NAME` = value");
                    (tick(name), value.trim().to_string())
                })
                .collect();
            Row {
                code: tick(cells[1]),
                file: repo_root().join(tick(cells[3])),
                floors,
            }
        })
        .collect()
}

/// A file's code before its `#[cfg(test)]` module.
fn library_code(file: &Path) -> String {
    let text = std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    match text.find("#[cfg(test)]") {
        Some(i) => text[..i].to_string(),
        None => text,
    }
}

/// The warning codes raised in `code`: the snake_case string literals that stand alone on their
/// line as an argument (the way every check passes its code to `Warning::new` or its helper).
fn codes_in(code: &str) -> BTreeSet<String> {
    code.lines()
        .filter_map(|l| l.trim().strip_prefix('"')?.strip_suffix("\","))
        .filter(|s| !s.is_empty() && s.chars().all(|c| c.is_ascii_lowercase() || c == '_'))
        .map(String::from)
        .collect()
}

#[test]
fn every_check_in_the_list_is_raised_where_it_says_with_the_floor_it_says() {
    let rows = rows();
    assert!(rows.len() >= 20, "only {} rows read", rows.len());
    for r in &rows {
        let code = library_code(&r.file);
        assert!(
            codes_in(&code).contains(&r.code),
            "{} is not raised in {}",
            r.code,
            r.file.display()
        );
        for (name, value) in &r.floors {
            let decl = code
                .lines()
                .find(|l| l.contains(&format!("const {name}:")))
                .unwrap_or_else(|| panic!("{name} is not a constant in {}", r.file.display()));
            let actual = decl
                .rsplit('=')
                .next()
                .unwrap()
                .trim()
                .trim_end_matches(';');
            assert_eq!(actual, value, "{name} in {}", r.file.display());
        }
    }
}

#[test]
fn every_warning_the_library_raises_is_in_the_list() {
    let listed: BTreeSet<String> = rows().into_iter().map(|r| r.code).collect();
    let mut files = Vec::new();
    rust_files(&repo_root().join("src"), &mut files);
    let mut raised = BTreeSet::new();
    for f in files {
        let code = library_code(&f);
        if code.contains("Warning::new(") {
            raised.extend(codes_in(&code));
        }
    }
    let missing: Vec<_> = raised.difference(&listed).collect();
    assert!(
        missing.is_empty(),
        "raised but not in docs/self-checks.md: {missing:?}"
    );
    assert!(
        raised.len() >= 20,
        "only {} codes found in the code",
        raised.len()
    );
}
