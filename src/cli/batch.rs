//! `objnerf batch`: every job of a manifest, here one after the other; or one job (`--job`,
//! `--line`: what a Ray task or a Slurm array index runs); or the summary of a folder that
//! another engine filled (`--summary`).

use super::progress_bars::Bars;
use super::Cli;
use clap::{Args, Parser};
use objnerf::batch::{self, Manifest, Status};
use objnerf::{Error, Result};
use std::path::PathBuf;

#[derive(Args)]
pub struct BatchCmd {
    /// The manifest: JSON Lines, one job a line (docs/batch.md).
    manifest: PathBuf,
    /// Output folder: a folder per job, logs/, records/, summary.json.
    #[arg(long, required_unless_present = "check")]
    out: Option<PathBuf>,
    /// Run only the job with this id (and write its record, not the summary).
    #[arg(long, conflicts_with_all = ["line", "summary", "check"])]
    job: Option<String>,
    /// Run only the job on this line of the manifest (1-based: a Slurm array index).
    #[arg(long, conflicts_with_all = ["summary", "check"])]
    line: Option<usize>,
    /// Run nothing: gather the jobs' records into summary.json and print the table.
    #[arg(long, conflicts_with = "check")]
    summary: bool,
    /// Run nothing: check the manifest and print each job (id, line, resources, command lines)
    /// as one JSON line.
    #[arg(long)]
    check: bool,
}

impl BatchCmd {
    pub fn run(self) -> Result<()> {
        let manifest = read_checked(&self.manifest)?;
        if self.check {
            for job in &manifest.jobs {
                println!("{}", serde_json::to_string(job).expect("jobs serialise"));
            }
            return Ok(());
        }
        let out = self.out.expect("clap requires --out without --check");
        let one = match (&self.job, self.line) {
            (Some(id), _) => Some(manifest.job(id)?),
            (None, Some(line)) => Some(manifest.job_on_line(line)?),
            (None, None) => None,
        };
        if let Some(job) = one {
            // Run for an engine: end with the worker that started us.
            batch::die_with_parent()?;
            let r = batch::run_job(&exe()?, job, &out)?;
            println!("{}", serde_json::to_string(&r).expect("records serialise"));
            return match r.status {
                Status::Failed => Err(Error::invalid(format!(
                    "job {} failed: {}",
                    r.id,
                    r.error.as_deref().unwrap_or("")
                ))),
                _ => Ok(()),
            };
        }
        let summary = if self.summary {
            batch::summarize(&manifest, &out)?
        } else {
            batch::run_batch(&exe()?, &manifest, &out, &Bars::default())?
        };
        print!("{}", summary.table());
        let failed = summary.count(Status::Failed) + summary.count(Status::NotRun);
        if failed > 0 {
            return Err(Error::invalid(format!(
                "{failed} of {} jobs failed or did not run (summary.json has each error)",
                summary.jobs.len()
            )));
        }
        Ok(())
    }
}

/// The manifest, with every stage's command line checked by the command's own parser, so a bad
/// option is an error naming its line before any job runs.
fn read_checked(path: &std::path::Path) -> Result<Manifest> {
    let manifest = Manifest::read(path)?;
    for job in &manifest.jobs {
        for s in &job.stages {
            let argv = std::iter::once("objnerf").chain(s.args.iter().map(String::as_str));
            if let Err(e) = Cli::try_parse_from(argv) {
                let text = e.to_string();
                let first = text.lines().next().unwrap_or_default();
                return Err(Error::invalid(format!(
                    "{}:{}: {}: {} (objnerf {})",
                    manifest.path.display(),
                    job.line,
                    s.stage,
                    first.trim_start_matches("error: "),
                    s.args.join(" ")
                )));
            }
        }
    }
    Ok(manifest)
}

/// This binary, which runs each stage.
fn exe() -> Result<PathBuf> {
    std::env::current_exe()
        .map_err(|e| Error::invalid(format!("cannot find the objnerf binary: {e}")))
}
