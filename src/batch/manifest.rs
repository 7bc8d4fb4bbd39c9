//! The batch manifest: JSON Lines, one job a line. A job is a scene and the stages to run on it,
//! in this order: `sfm`, `extract`, `remove`, `export`. Each stage becomes one `objnerf` command
//! line whose options are the command's own flags, so a stage means exactly what the command
//! means. Every line is checked when the manifest is read, before any job runs; an error names
//! the file and the line.
//!
//! ```json
//! {"id": "mug_s1", "scene": "scenes/s1",
//!  "extract": {"view": "view_000.png", "objects": [{"name": "mug", "points": [[52.5, 50.5]]}],
//!              "options": {"steps": 200, "frames": 2}},
//!  "remove": {"options": {"steps": 50}},
//!  "export": {"object": "mug"},
//!  "resources": {"cpus": 1, "memory_mb": 2048}}
//! ```

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

/// A stage's flags: `{"steps": 200, "time-budget": "none", "keep-cavities": true}` (an
/// underscore in a name reads as a hyphen; `true` is a bare flag, a list repeats the flag).
type Flags = BTreeMap<String, Value>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JobLine {
    id: String,
    scene: PathBuf,
    sfm: Option<SfmLine>,
    extract: Option<ExtractLine>,
    remove: Option<RemoveLine>,
    export: Option<ExportLine>,
    #[serde(default)]
    resources: Resources,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SfmLine {
    #[serde(default)]
    options: Flags,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ExtractLine {
    view: String,
    objects: Vec<ObjectLine>,
    #[serde(default)]
    options: Flags,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectLine {
    name: String,
    /// The view of this object's clicks, when not the extract's `view`.
    view: Option<String>,
    #[serde(default)]
    points: Vec<[f64; 2]>,
    /// Clicks on what is not the object.
    #[serde(default)]
    negative: Vec<[f64; 2]>,
    #[serde(rename = "box")]
    bbox: Option<[f64; 4]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RemoveLine {
    /// Default: the objects the job extracts.
    objects: Option<Vec<String>>,
    /// An `objnerf segment` run; default: the job's own extract's `segment/`.
    segment: Option<PathBuf>,
    #[serde(default)]
    options: Flags,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ExportLine {
    object: Option<String>,
    #[serde(default)]
    background: bool,
    #[serde(default)]
    options: Flags,
}

/// What a job asks of the machine that runs it (read by the Ray driver; the local runner runs
/// one job at a time and ignores it).
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Resources {
    pub cpus: Option<f64>,
    pub memory_mb: Option<u64>,
}

/// One stage of a job as the `objnerf` command line that runs it (without the program name),
/// run in the job's folder: its output is the relative folder named after the stage.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StageCommand {
    pub stage: String,
    pub args: Vec<String>,
}

/// One checked job.
#[derive(Clone, Debug, Serialize)]
pub struct Job {
    pub id: String,
    /// The manifest line it was read from (1-based).
    pub line: usize,
    pub scene: PathBuf,
    pub resources: Resources,
    pub stages: Vec<StageCommand>,
}

/// A checked manifest.
#[derive(Clone, Debug)]
pub struct Manifest {
    pub path: PathBuf,
    pub jobs: Vec<Job>,
}

/// Folders and files of a batch's output folder that are not jobs.
pub const RESERVED_IDS: [&str; 3] = ["logs", "records", "summary.json"];

impl Manifest {
    /// Read and check every line of `path`; relative scene and segment paths are taken from the
    /// manifest's folder. Blank lines are skipped.
    pub fn read(path: &Path) -> Result<Manifest> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let path = std::path::absolute(path).map_err(|e| Error::io(path, e))?;
        let base = path.parent().unwrap_or(Path::new("/")).to_path_buf();
        let mut jobs: Vec<Job> = Vec::new();
        let mut ids = HashSet::new();
        for (i, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let at = |msg: String| Error::invalid(format!("{}:{}: {msg}", path.display(), i + 1));
            let job = parse_job(line, i + 1, &base).map_err(at)?;
            if !ids.insert(job.id.clone()) {
                return Err(at(format!("job id '{}' is used twice", job.id)));
            }
            jobs.push(job);
        }
        if jobs.is_empty() {
            return Err(Error::invalid(format!(
                "{}: the manifest holds no job (one JSON object a line)",
                path.display()
            )));
        }
        Ok(Manifest { path, jobs })
    }

    /// The job named `id`.
    pub fn job(&self, id: &str) -> Result<&Job> {
        self.jobs
            .iter()
            .find(|j| j.id == id)
            .ok_or_else(|| Error::invalid(format!("{}: no job '{id}'", self.path.display())))
    }

    /// The job on line `line` of the file (1-based, as a Slurm array index).
    pub fn job_on_line(&self, line: usize) -> Result<&Job> {
        self.jobs.iter().find(|j| j.line == line).ok_or_else(|| {
            Error::invalid(format!(
                "{}:{line}: no job on this line ({} lines hold jobs, the last on line {})",
                self.path.display(),
                self.jobs.len(),
                self.jobs.last().map_or(0, |j| j.line)
            ))
        })
    }
}

fn parse_job(line: &str, number: usize, base: &Path) -> std::result::Result<Job, String> {
    let j: JobLine = serde_json::from_str(line).map_err(|e| format!("not a job: {e}"))?;
    check_id(&j.id)?;
    let scene = base.join(&j.scene);
    if !scene.exists() {
        return Err(format!("scene {} does not exist", scene.display()));
    }
    if let Some(c) = j.resources.cpus {
        if !(c > 0.0 && c.is_finite()) {
            return Err(format!("resources.cpus must be above 0, not {c}"));
        }
    }
    if j.resources.memory_mb == Some(0) {
        return Err("resources.memory_mb must be above 0".into());
    }
    let stages = stage_commands(&j, &scene, base)?;
    Ok(Job {
        id: j.id,
        line: number,
        scene,
        resources: j.resources,
        stages,
    })
}

/// A job's folder name: letters, digits, `_`, `-` and `.` (not first).
fn check_id(id: &str) -> std::result::Result<(), String> {
    let ok = !id.is_empty()
        && id.len() <= 100
        && id.chars().next().is_some_and(|c| c.is_ascii_alphanumeric())
        && id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c));
    if !ok {
        return Err(format!(
            "job id '{id}': use letters, digits, '_', '-' and '.' (not first), at most 100"
        ));
    }
    if RESERVED_IDS.contains(&id) {
        return Err(format!(
            "job id '{id}' is the name of the batch's own {id} in the output folder"
        ));
    }
    Ok(())
}

/// The stages' command lines, in order; each stage reads what the one before it wrote.
fn stage_commands(
    j: &JobLine,
    scene: &Path,
    base: &Path,
) -> std::result::Result<Vec<StageCommand>, String> {
    if j.sfm.is_none() && j.extract.is_none() && j.remove.is_none() && j.export.is_none() {
        return Err("the job has no stage: give sfm, extract, remove or export".into());
    }
    let scene = scene.display().to_string();
    let mut stages = Vec::new();
    // After sfm, the stages read its model (relative to the job's folder).
    let scene = match &j.sfm {
        Some(s) => {
            let mut args = vec!["sfm".into(), scene, "--out".into(), "sfm".into()];
            args.extend(flags("sfm", &s.options, &["out", "overwrite", "json"])?);
            stages.push(StageCommand {
                stage: "sfm".into(),
                args,
            });
            "sfm".to_string()
        }
        None => scene,
    };
    if let Some(e) = &j.extract {
        stages.push(extract_command(e, &scene)?);
    }
    if let Some(r) = &j.remove {
        stages.push(remove_command(r, j.extract.as_ref(), &scene, base)?);
    }
    if let Some(x) = &j.export {
        stages.push(export_command(x, j.extract.is_some(), &scene)?);
    }
    Ok(stages)
}

fn extract_command(e: &ExtractLine, scene: &str) -> std::result::Result<StageCommand, String> {
    if e.objects.is_empty() {
        return Err("extract.objects is empty: give at least one object".into());
    }
    let mut args = vec![
        "extract".into(),
        scene.into(),
        "--view".into(),
        e.view.clone(),
    ];
    for o in &e.objects {
        if o.points.is_empty() {
            return Err(format!(
                "extract: object '{}' has no points (a box needs at least one click with it)",
                o.name
            ));
        }
        args.extend(["--object".into(), o.name.clone()]);
        if let Some(v) = &o.view {
            args.extend(["--view".into(), v.clone()]);
        }
        for (p, sign) in o
            .points
            .iter()
            .map(|p| (p, ""))
            .chain(o.negative.iter().map(|p| (p, ",bg")))
        {
            args.extend(["--point".into(), format!("{},{}{sign}", p[0], p[1])]);
        }
        if let Some(b) = o.bbox {
            args.extend([
                "--box".into(),
                format!("{},{},{},{}", b[0], b[1], b[2], b[3]),
            ]);
        }
    }
    args.extend(["--out".into(), "extract".into()]);
    let own = ["out", "overwrite", "json", "view", "object", "point", "box"];
    args.extend(flags("extract", &e.options, &own)?);
    Ok(StageCommand {
        stage: "extract".into(),
        args,
    })
}

fn remove_command(
    r: &RemoveLine,
    extract: Option<&ExtractLine>,
    scene: &str,
    base: &Path,
) -> std::result::Result<StageCommand, String> {
    let segment = match (&r.segment, extract) {
        (Some(s), _) => {
            let s = base.join(s);
            if !s.exists() {
                return Err(format!("remove.segment {} does not exist", s.display()));
            }
            s.display().to_string()
        }
        (None, Some(_)) => "extract/segment".into(),
        (None, None) => {
            return Err(
                "remove needs a segmentation: give remove.segment, or an extract stage".into(),
            )
        }
    };
    let objects = match (&r.objects, extract) {
        (Some(o), _) => o.clone(),
        (None, Some(e)) => e.objects.iter().map(|o| o.name.clone()).collect(),
        (None, None) => return Err("remove.objects: name the objects to remove".into()),
    };
    if objects.is_empty() {
        return Err("remove.objects is empty".into());
    }
    let mut args = vec!["remove".into(), scene.into(), "--segment".into(), segment];
    for o in objects {
        args.extend(["--object".into(), o]);
    }
    args.extend(["--out".into(), "remove".into()]);
    let own = ["out", "overwrite", "segment", "object"];
    args.extend(flags("remove", &r.options, &own)?);
    Ok(StageCommand {
        stage: "remove".into(),
        args,
    })
}

fn export_command(
    x: &ExportLine,
    has_extract: bool,
    scene: &str,
) -> std::result::Result<StageCommand, String> {
    if (x.object.is_some() || x.background) && !has_extract {
        return Err("export.object and export.background need an extract stage in the job".into());
    }
    // A job's export is of its extract run when it has one, else of its scene.
    let input = if has_extract { "extract" } else { scene };
    let mut args = vec![
        "export".into(),
        "nerfstudio".into(),
        input.into(),
        "--out".into(),
        "export".into(),
    ];
    if let Some(o) = &x.object {
        args.extend(["--object".into(), o.clone()]);
    }
    if x.background {
        args.push("--background".into());
    }
    let own = ["out", "overwrite", "object", "background"];
    args.extend(flags("export", &x.options, &own)?);
    Ok(StageCommand {
        stage: "export".into(),
        args,
    })
}

/// `{"steps": 200, "keep_cavities": true}` as `--steps 200 --keep-cavities`. Flags the batch
/// sets itself (`own`) are refused; the command's parser checks the rest.
fn flags(stage: &str, options: &Flags, own: &[&str]) -> std::result::Result<Vec<String>, String> {
    let mut args = Vec::new();
    for (name, value) in options {
        let flag = name.replace('_', "-");
        if own.contains(&flag.as_str()) {
            return Err(format!(
                "{stage}.options.{name}: set by the batch itself, not an option here"
            ));
        }
        let values = match value {
            Value::Array(items) => items.clone(),
            v => vec![v.clone()],
        };
        for v in values {
            match v {
                Value::Bool(true) => args.push(format!("--{flag}")),
                Value::Bool(false) => {}
                Value::Number(n) => args.extend([format!("--{flag}"), n.to_string()]),
                Value::String(s) => args.extend([format!("--{flag}"), s]),
                other => {
                    return Err(format!(
                        "{stage}.options.{name}: {other} is not a flag's value (a number, a string, true or false)"
                    ))
                }
            }
        }
    }
    Ok(args)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn manifest(dir: &Path, lines: &[&str]) -> Result<Manifest> {
        std::fs::create_dir_all(dir.join("scene")).unwrap();
        let path = dir.join("jobs.jsonl");
        std::fs::write(&path, lines.join("\n")).unwrap();
        Manifest::read(&path)
    }

    #[test]
    fn stages_become_command_lines_in_order() {
        let dir = tempfile::tempdir().unwrap();
        // One line in the file: the JSON is broken over lines here for reading.
        let line = r#"{"id": "a", "scene": "scene", "export": {"object": "mug"}, "remove": {"options": {"memory_mb": 512, "keep": false}},
                    "extract": {"view": "v0", "objects": [{"name": "mug", "points": [[1.5, 2]], "negative": [[3, 4]], "box": [0, 0, 9, 9]},
                                                          {"name": "cup", "view": "v1", "points": [[5, 6]]}],
                                "options": {"steps": 200, "time_budget": "none", "frames": [2], "keep-cavities": true}},
                    "resources": {"cpus": 2}}"#
            .replace('\n', " ");
        let m = manifest(dir.path(), &["", &line]).unwrap();
        let job = &m.jobs[0];
        assert_eq!((job.id.as_str(), job.line), ("a", 2));
        assert_eq!(job.resources.cpus, Some(2.0));
        let scene = dir.path().join("scene").display().to_string();
        let stages: Vec<String> = job.stages.iter().map(|s| s.args.join(" ")).collect();
        assert_eq!(
            stages,
            [
                format!("extract {scene} --view v0 --object mug --point 1.5,2 --point 3,4,bg --box 0,0,9,9 --object cup --view v1 --point 5,6 --out extract --frames 2 --keep-cavities --steps 200 --time-budget none"),
                format!("remove {scene} --segment extract/segment --object mug --object cup --out remove --memory-mb 512"),
                "export nerfstudio extract --out export --object mug".to_string(),
            ]
        );
    }

    #[test]
    fn bad_lines_name_the_line_and_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let ok = r#"{"id": "a", "scene": "scene", "export": {}}"#;
        for (bad, want) in [
            (r#"{"id": "a", "scene": "scene"}"#, "no stage"),
            (
                r#"{"id": "../a", "scene": "scene", "export": {}}"#,
                "job id '../a'",
            ),
            (
                r#"{"id": "logs", "scene": "scene", "export": {}}"#,
                "batch's own logs",
            ),
            (
                r#"{"id": "b", "scene": "scene", "export": {}, "sfn": {}}"#,
                "unknown field `sfn`",
            ),
            (
                r#"{"id": "b", "scene": "scene", "remove": {"objects": ["mug"]}}"#,
                "needs a segmentation",
            ),
            (
                r#"{"id": "b", "scene": "scene", "export": {"background": true}}"#,
                "need an extract stage",
            ),
            (
                r#"{"id": "b", "scene": "scene", "export": {"options": {"out": "x"}}}"#,
                "set by the batch",
            ),
            (
                r#"{"id": "b", "scene": "scene", "export": {"options": {"downscale": null}}}"#,
                "not a flag's value",
            ),
            (
                r#"{"id": "b", "scene": "scene", "export": {}, "resources": {"cpus": 0}}"#,
                "cpus must be above 0",
            ),
            (
                r#"{"id": "b", "scene": "scene", "extract": {"view": "v", "objects": [{"name": "m", "box": [0, 0, 1, 1]}]}}"#,
                "has no points",
            ),
            (ok, "used twice"),
        ] {
            let e = manifest(dir.path(), &[ok, bad]).unwrap_err().to_string();
            assert!(
                e.contains("jobs.jsonl:2: ") && e.contains(want),
                "{want}: {e}"
            );
        }
        let e = manifest(dir.path(), &["", " "]).unwrap_err().to_string();
        assert!(e.contains("holds no job"), "{e}");
    }
}
