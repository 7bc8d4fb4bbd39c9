//! The README's figures come from measurements on record: a figure followed by a marker
//! `<!--quality:ID-->` must be in `examples/results/quality.json` (written by `bash
//! scripts/quality`) under that ID, with the value the README prints (to its printed decimals),
//! and from a run in which that figure's test passed. The README names the commit of that run.
//! And the README quotes no measured figure (dB, MiB, GiB, frames/s, rays/s) without a marker:
//! figures measured elsewhere live in `examples/results/` and `docs/`, which the README points to.
//! A threshold (a number after ≥, ≤, < or >) is a floor, not a measurement.

mod common;

use std::collections::HashMap;

const MARK: &str = "<!--quality:";

/// Every `(number, id)` the README marks: the number is the last one before the marker.
fn marked_figures(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find(MARK) {
        let before = &rest[..at];
        let after = &rest[at + MARK.len()..];
        let end = after.find("-->").expect("a marker ends with -->");
        let id = after[..end].trim().to_string();
        let number: String = before
            .trim_end_matches(|c: char| !c.is_ascii_digit())
            .chars()
            .rev()
            .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '-')
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        out.push((number, id));
        rest = &after[end..];
    }
    out
}

#[test]
fn marked_readme_figures_are_in_the_quality_run() {
    let root = common::repo_root();
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let marked = marked_figures(&readme);
    assert!(
        !marked.is_empty(),
        "the README marks no figure with {MARK}ID-->"
    );
    let quality: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("examples/results/quality.json")).unwrap(),
    )
    .unwrap();
    let mut figures: HashMap<String, (f64, bool)> = HashMap::new();
    for run in quality["runs"].as_array().unwrap() {
        for f in run["figures"].as_array().unwrap() {
            let pass = run["pass"].as_bool().unwrap() && f["pass"].as_bool().unwrap();
            figures.insert(
                f["figure"].as_str().unwrap().to_string(),
                (f["value"].as_f64().unwrap(), pass),
            );
        }
    }
    let commit = &quality["git_commit"].as_str().unwrap()[..7];
    assert!(
        readme.contains(commit),
        "the README does not name the quality run's commit {commit}"
    );
    let mut wrong = Vec::new();
    for (number, id) in &marked {
        let Some(&(value, pass)) = figures.get(id) else {
            wrong.push(format!("{id}: not in quality.json"));
            continue;
        };
        let decimals = number.split_once('.').map_or(0, |(_, d)| d.len());
        let printed = format!("{value:.decimals$}");
        if &printed != number {
            wrong.push(format!("{id}: README {number}, quality.json {printed}"));
        }
        if !pass {
            wrong.push(format!("{id}: its test failed in the quality run"));
        }
    }
    assert!(wrong.is_empty(), "README figures: {wrong:#?}");
}

/// The units of measured figures the README may quote only with a marker.
const MEASURED_UNITS: [&str; 5] = ["dB", "MiB", "GiB", "frames/s", "rays/s"];

/// Every measured figure in `text` with no marker between its number and its unit, as the text
/// around it, except thresholds (a number after ≥, ≤, < or >).
fn unmarked_figures(text: &str) -> Vec<String> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let starts_number = chars[i].is_ascii_digit()
            && (i == 0 || !(chars[i - 1].is_alphanumeric() || chars[i - 1] == '.'));
        if !starts_number {
            i += 1;
            continue;
        }
        let start = i;
        while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
            i += 1;
        }
        let rest: String = chars[i..chars.len().min(i + 12)].iter().collect();
        let unit = rest.trim_start_matches(' ');
        let measured = MEASURED_UNITS.iter().any(|u| {
            unit.strip_prefix(u)
                .is_some_and(|after| !after.starts_with(|c: char| c.is_alphanumeric()))
        });
        let before: String = chars[start.saturating_sub(3)..start].iter().collect();
        let threshold = before
            .trim_end()
            .ends_with(['≥', '≤', '<', '>', '='].as_slice());
        if measured && !threshold {
            let from = start.saturating_sub(30);
            let to = chars.len().min(i + 12);
            out.push(
                chars[from..to]
                    .iter()
                    .collect::<String>()
                    .replace('\n', " "),
            );
        }
    }
    out
}

#[test]
fn the_readme_quotes_measured_figures_only_from_the_quality_run() {
    let readme = std::fs::read_to_string(common::repo_root().join("README.md")).unwrap();
    let unmarked = unmarked_figures(&readme);
    assert!(
        unmarked.is_empty(),
        "README figures with no <!--quality:ID--> marker (quote them from the quality run, or \
         point to the results file that holds them): {unmarked:#?}"
    );
}

#[test]
fn the_figure_scanner_finds_unmarked_measurements_only() {
    let text = "held out 26.87 dB at 3000 steps, peak 1042 MiB; 29.70<!--quality:u--> dB \
                (floor ≥ 28 dB, warns < 24 dB); 9.0 frames/s; v2 dBm 3 dBx";
    let found = unmarked_figures(text);
    assert_eq!(found.len(), 3, "{found:#?}");
    assert!(found[0].contains("26.87 dB") && found[1].contains("1042 MiB"));
    assert!(found[2].contains("9.0 frames/s"));
}

#[test]
fn the_marker_reader_takes_the_number_before_each_marker() {
    let text = "mug 30.03<!--quality:a.b--> / 25.5 dB<!--quality: c -->, and -1<!--quality:d-->";
    assert_eq!(
        marked_figures(text),
        [
            ("30.03".to_string(), "a.b".to_string()),
            ("25.5".to_string(), "c".to_string()),
            ("-1".to_string(), "d".to_string()),
        ]
    );
}
