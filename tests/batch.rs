//! `objnerf batch` (issue 57): an 8-job manifest on demo scenes (three seeds; extract, remove,
//! export; one object or two; a click or a click and a box) run locally, every job's output and
//! the summary checked; a rerun does nothing; a broken line stops everything before it starts;
//! a failed job is recorded and the others run. The same manifest on Ray: `tests/batch_ray.rs`.

mod batch_jobs;
mod common;

use batch_jobs::{batch, check_outputs, eight_job_manifest, files, read_json};
use objnerf::demo::{write_demo_scene, DemoOptions};
use serde_json::{json, Value};

#[test]
fn eight_jobs_run_resume_and_a_broken_line_runs_nothing() {
    if !common::sam_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let manifest = eight_job_manifest(dir.path());
    let out = dir.path().join("out");

    let run = batch(&[&manifest], &["--out", out.to_str().unwrap()]);
    assert!(run.status.success(), "the batch failed");
    let summary = read_json(&out.join("summary.json"));
    assert_eq!(summary["counts"], json!({"ok": 8}), "{summary}");
    check_outputs(&out, &summary);
    let table = String::from_utf8_lossy(&run.stdout).to_string();
    for j in summary["jobs"].as_array().unwrap() {
        let id = j["id"].as_str().unwrap();
        assert!(
            table
                .lines()
                .any(|l| l.starts_with(id) && l.contains(" ok ")),
            "{id} not in the table:\n{table}"
        );
    }
    assert_eq!(std::fs::read_dir(out.join("records")).unwrap().count(), 8);

    // A rerun does nothing: every job skipped, every file of the jobs and their logs untouched.
    let before: Vec<_> = ["mug_s1", "mug_torus_s3", "scene_s2", "logs"]
        .iter()
        .map(|d| files(&out.join(d)))
        .collect();
    let again = batch(&[&manifest], &["--out", out.to_str().unwrap()]);
    assert!(again.status.success());
    let summary2 = read_json(&out.join("summary.json"));
    assert_eq!(summary2["counts"], json!({"skipped": 8}), "{summary2}");
    for (j1, j2) in summary["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(summary2["jobs"].as_array().unwrap())
    {
        assert_eq!(j1["scores"], j2["scores"]);
        assert_eq!(
            j1["seconds"], j2["seconds"],
            "a skipped job keeps the time of its run"
        );
    }
    let after: Vec<_> = ["mug_s1", "mug_torus_s3", "scene_s2", "logs"]
        .iter()
        .map(|d| files(&out.join(d)))
        .collect();
    assert_eq!(before, after, "a rerun touched a job's files");

    // One broken line: an error naming the file and the line, and nothing runs.
    let text = std::fs::read_to_string(&manifest).unwrap();
    for (bad_line, want) in [
        (
            r#"{"id": "x", "scene": "scenes/s1", "extract": {"view": "view_000.png""#,
            "not a job",
        ),
        (
            r#"{"id": "x", "scene": "scenes/s1", "extract": {"view": "view_000.png", "objects": [{"name": "mug", "points": [[50, 50]]}], "options": {"stepz": 5}}}"#,
            "--stepz",
        ),
        (
            r#"{"id": "x", "scene": "scenes/nowhere", "export": {}}"#,
            "does not exist",
        ),
        (
            r#"{"id": "mug_s1", "scene": "scenes/s1", "export": {}}"#,
            "used twice",
        ),
    ] {
        let mut lines: Vec<&str> = text.lines().collect();
        lines.insert(4, bad_line);
        let broken = dir.path().join("broken.jsonl");
        std::fs::write(&broken, lines.join("\n")).unwrap();
        let out2 = dir.path().join("out_broken");
        let o = batch(&[&broken], &["--out", out2.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        let at = format!("{}:5: ", broken.display());
        assert!(
            err.contains(&at) && err.contains(want),
            "'{at}' and '{want}' not in: {err}"
        );
        assert!(!out2.exists(), "a broken manifest wrote {}", out2.display());
    }
}

/// A job that fails is recorded with its error and does not stop the others; the rerun tries
/// it again and skips the rest. (No SAM: export of a scene, removal with a folder that is no
/// segmentation.)
#[test]
fn a_failed_job_is_recorded_and_the_others_run() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    let opts = DemoOptions {
        views: 4,
        width: 64,
        height: 48,
        ..Default::default()
    };
    write_demo_scene(&opts, &scene).unwrap();
    let manifest = dir.path().join("jobs.jsonl");
    let jobs = [
        json!({"id": "bad_remove", "scene": "scene", "remove": {"segment": "scene", "objects": ["mug"]}}),
        json!({"id": "export", "scene": "scene", "export": {}}),
    ];
    let text: Vec<String> = jobs.iter().map(|j| j.to_string()).collect();
    std::fs::write(&manifest, text.join("\n")).unwrap();
    let out = dir.path().join("out");
    for (pass, want) in [
        (1, json!({"failed": 1, "ok": 1})),
        (2, json!({"failed": 1, "skipped": 1})),
    ] {
        let o = batch(&[&manifest], &["--out", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(1), "pass {pass}");
        let s = read_json(&out.join("summary.json"));
        assert_eq!(s["counts"], want, "pass {pass}");
        let failed = &s["jobs"][0];
        assert_eq!(failed["status"], "failed");
        let error = failed["error"].as_str().unwrap();
        assert!(
            error.starts_with("remove: ") && error.contains("scene/report.json"),
            "{error}"
        );
        assert!(
            !out.join("bad_remove").exists(),
            "a failed job left a folder"
        );
        let log = std::fs::read_to_string(out.join("logs/bad_remove.log")).unwrap();
        assert!(
            log.contains("$ objnerf remove") && log.contains("error: "),
            "{log}"
        );
        assert!(String::from_utf8_lossy(&o.stdout).contains("bad_remove failed: remove: "));
    }
    assert!(out.join("export/export/transforms.json").is_file());
    // One job by id, as an engine runs it: the record comes back on stdout.
    let one = batch(
        &[&manifest],
        &["--out", out.to_str().unwrap(), "--job", "export"],
    );
    assert!(one.status.success());
    let r: Value = serde_json::from_slice(&one.stdout).unwrap();
    assert_eq!(r["status"], "skipped");
    let line = batch(
        &[&manifest],
        &["--out", out.to_str().unwrap(), "--line", "3"],
    );
    assert!(String::from_utf8_lossy(&line.stderr).contains(":3: no job on this line"));
}
