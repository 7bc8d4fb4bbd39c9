//! What a job did, as the batch reports it: `records/<id>.json` per job, each job's own
//! `<id>/job.json`, and `summary.json` with the table printed at the end.

use crate::error::{Error, Result};
use crate::util::write_atomic;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Run now, and every stage succeeded.
    Ok,
    /// Run now; a stage failed (its error is in the record, its output in `logs/<id>.log`).
    Failed,
    /// Complete from an earlier run: left as it was.
    Skipped,
    /// No record: the job has not been run into this folder.
    NotRun,
}

impl Status {
    pub fn name(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Failed => "failed",
            Status::Skipped => "skipped",
            Status::NotRun => "not run",
        }
    }
}

/// One stage's child process.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StageRecord {
    pub stage: String,
    pub seconds: f64,
    /// The child's peak resident set (its rusage, COLMAP's included for sfm).
    pub peak_rss_mib: u64,
    /// Exit status, or `signal N` when it was killed.
    pub exit: String,
}

/// What a finished job wrote beside its outputs: `<id>/job.json`. Its stages' figures are
/// from the run that made it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobOutput {
    pub id: String,
    pub stages: Vec<StageRecord>,
    /// Key figures of the stages' reports (`extract.<object>.heldout_psnr`, `remove.fit_psnr`, ...).
    pub scores: BTreeMap<String, f64>,
    /// The self-checks that tripped, as the stages' reports give them, each with its `job_stage`.
    pub warnings: Vec<Value>,
}

impl JobOutput {
    pub fn seconds(&self) -> f64 {
        self.stages.iter().map(|s| s.seconds).sum()
    }

    pub fn peak_rss_mib(&self) -> u64 {
        self.stages
            .iter()
            .map(|s| s.peak_rss_mib)
            .max()
            .unwrap_or(0)
    }
}

/// One job in a batch run: `records/<id>.json` and a row of `summary.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobRecord {
    pub id: String,
    pub line: usize,
    pub status: Status,
    /// Wall time of its stages (for a skipped job: of the run that made it).
    pub seconds: f64,
    /// The largest peak RSS of its stages' processes.
    pub peak_rss_mib: u64,
    pub stages: Vec<StageRecord>,
    pub scores: BTreeMap<String, f64>,
    pub warnings: Vec<Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// The stages' output (relative to the batch folder).
    pub log: PathBuf,
}

impl JobRecord {
    /// A record of a job whose output is complete.
    pub fn from_output(line: usize, status: Status, out: JobOutput) -> JobRecord {
        JobRecord {
            id: out.id.clone(),
            line,
            status,
            seconds: out.seconds(),
            peak_rss_mib: out.peak_rss_mib(),
            log: log_path(&out.id),
            stages: out.stages,
            scores: out.scores,
            warnings: out.warnings,
            error: None,
        }
    }

    pub fn not_run(id: &str, line: usize) -> JobRecord {
        JobRecord {
            id: id.to_string(),
            line,
            status: Status::NotRun,
            seconds: 0.0,
            peak_rss_mib: 0,
            stages: vec![],
            scores: BTreeMap::new(),
            warnings: vec![],
            error: None,
            log: log_path(id),
        }
    }
}

/// `logs/<id>.log`, relative to the batch folder.
pub fn log_path(id: &str) -> PathBuf {
    Path::new("logs").join(format!("{id}.log"))
}

/// `records/<id>.json`, relative to the batch folder.
pub fn record_path(id: &str) -> PathBuf {
    Path::new("records").join(format!("{id}.json"))
}

/// Every job of a batch folder: `summary.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BatchSummary {
    pub manifest: PathBuf,
    pub out: PathBuf,
    /// Jobs by status name.
    pub counts: BTreeMap<String, usize>,
    /// The sum of the jobs' times (their wall time when run one at a time).
    pub job_seconds: f64,
    /// The largest peak RSS of any job.
    pub peak_rss_mib: u64,
    /// In the manifest's order.
    pub jobs: Vec<JobRecord>,
}

impl BatchSummary {
    pub fn new(manifest: &Path, out: &Path, jobs: Vec<JobRecord>) -> BatchSummary {
        let mut counts = BTreeMap::new();
        for j in &jobs {
            *counts.entry(j.status.name().to_string()).or_insert(0) += 1;
        }
        BatchSummary {
            manifest: manifest.to_path_buf(),
            out: out.to_path_buf(),
            counts,
            job_seconds: jobs.iter().map(|j| j.seconds).sum(),
            peak_rss_mib: jobs.iter().map(|j| j.peak_rss_mib).max().unwrap_or(0),
            jobs,
        }
    }

    pub fn count(&self, status: Status) -> usize {
        self.counts.get(status.name()).copied().unwrap_or(0)
    }

    /// Write `summary.json` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let json = serde_json::to_string_pretty(self).map_err(|e| Error::json(path, e))?;
        write_atomic(path, |w| w.write_all(json.as_bytes()))
    }

    /// The table a person reads: one row a job (status, time, peak memory, key scores,
    /// warnings), then each failed job's error.
    pub fn table(&self) -> String {
        let w = self
            .jobs
            .iter()
            .map(|j| j.id.len())
            .max()
            .unwrap_or(2)
            .max(2);
        let mut s = format!(
            "{:<w$}  {:<7}  {:>7}  {:>8}  scores; warnings\n",
            "id", "status", "time s", "peak MiB"
        );
        for j in &self.jobs {
            let scores: Vec<String> = j
                .scores
                .iter()
                .map(|(k, v)| format!("{k} {}", short(*v)))
                .collect();
            let codes: Vec<&str> = j
                .warnings
                .iter()
                .filter_map(|w| w["code"].as_str())
                .collect();
            let warnings = if codes.is_empty() {
                String::new()
            } else {
                format!("; {} warning(s): {}", codes.len(), codes.join(", "))
            };
            s += &format!(
                "{:<w$}  {:<7}  {:>7.1}  {:>8}  {}{warnings}\n",
                j.id,
                j.status.name(),
                j.seconds,
                j.peak_rss_mib,
                scores.join(", ")
            );
        }
        for j in self.jobs.iter().filter(|j| j.status == Status::Failed) {
            s += &format!(
                "{} failed: {} (log: {})\n",
                j.id,
                j.error.as_deref().unwrap_or("unknown error"),
                self.out.join(&j.log).display()
            );
        }
        let counts: Vec<String> = self
            .counts
            .iter()
            .map(|(k, v)| format!("{v} {k}"))
            .collect();
        s += &format!(
            "{} jobs: {}; {:.0} s of jobs, peak {} MiB; summary: {}\n",
            self.jobs.len(),
            counts.join(", "),
            self.job_seconds,
            self.peak_rss_mib,
            self.out.join("summary.json").display()
        );
        s
    }
}

/// A score as a person reads it: counts whole, the rest to two decimals.
fn short(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e9 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

/// The key figures and warnings of a finished job's stage reports, read from the job's folder.
pub fn stage_scores(
    job_dir: &Path,
    stage: &str,
    scores: &mut BTreeMap<String, f64>,
    warnings: &mut Vec<Value>,
) -> Result<()> {
    let report = |name: &str| -> Result<Value> {
        let p = job_dir.join(stage).join(name);
        let text = std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?;
        serde_json::from_str(&text).map_err(|e| Error::json(&p, e))
    };
    let mut put = |key: String, v: &Value| {
        if let Some(x) = v.as_f64() {
            scores.insert(key, x);
        }
    };
    let r = match stage {
        "extract" => {
            let r = report("report.json")?;
            for o in r["objects"].as_array().into_iter().flatten() {
                let name = o["name"].as_str().unwrap_or("object");
                put(
                    format!("extract.{name}.ok_views"),
                    &o["segmentation"]["num_ok"],
                );
                put(
                    format!("extract.{name}.train_psnr"),
                    &o["train"]["run"]["final_psnr"],
                );
                put(
                    format!("extract.{name}.heldout_psnr"),
                    &o["held_out_check"]["psnr"],
                );
                put(
                    format!("extract.{name}.mesh_vertices"),
                    &o["mesh"]["vertices"],
                );
            }
            r
        }
        "remove" => {
            let r = report("report.json")?;
            put("remove.fit_psnr".into(), &r["train"]["scene_fit"]["psnr"]);
            put("remove.truth_psnr".into(), &r["scores"]["psnr"]);
            r
        }
        "export" => {
            let t = report("transforms.json")?;
            let frames = t["frames"].as_array().map_or(0, |f| f.len());
            scores.insert("export.frames".into(), frames as f64);
            return Ok(());
        }
        _ => return Ok(()),
    };
    for w in r["warnings"].as_array().into_iter().flatten() {
        let mut w = w.clone();
        w["job_stage"] = Value::String(stage.to_string());
        warnings.push(w);
    }
    Ok(())
}
