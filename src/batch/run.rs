//! Running jobs: each stage is a child `objnerf` process run in the job's folder (so a crash or
//! an out-of-memory kill ends that job alone, and its peak memory is the child's rusage), the
//! folder built under a temporary name and renamed into place when every stage succeeded.

use super::manifest::{Job, Manifest};
use super::record::{
    log_path, record_path, stage_scores, BatchSummary, JobOutput, JobRecord, StageRecord, Status,
};
use crate::error::{Error, Result};
use crate::util::{write_atomic, AtomicDir, Detail, Progress};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Read, Seek, Write};
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

/// A finished job's record of itself, inside its folder.
pub const JOB_FILE: &str = "job.json";

/// Run every job of `manifest` into `out` one after the other with the `objnerf` binary `exe`:
/// a job whose folder is complete is skipped, a failed one is recorded and the next one runs.
/// Writes `summary.json` and returns it.
pub fn run_batch(
    exe: &Path,
    manifest: &Manifest,
    out: &Path,
    progress: &dyn Progress,
) -> Result<BatchSummary> {
    progress.begin("batch", manifest.jobs.len() as u64);
    for (i, job) in manifest.jobs.iter().enumerate() {
        progress.advance(i as u64, Detail::Item(&job.id));
        let r = run_job(exe, job, out)?;
        let err = r
            .error
            .as_deref()
            .map(|e| format!(": {e}"))
            .unwrap_or_default();
        progress.note(&format!(
            "{}: {} in {:.0} s, peak {} MiB{err}",
            r.id,
            r.status.name(),
            r.seconds,
            r.peak_rss_mib
        ));
    }
    progress.advance(manifest.jobs.len() as u64, Detail::None);
    progress.end();
    summarize(manifest, out)
}

/// Gather the jobs' records in `out` (a job without one is "not run") into `summary.json`.
pub fn summarize(manifest: &Manifest, out: &Path) -> Result<BatchSummary> {
    let out = &std::path::absolute(out).map_err(|e| Error::io(out, e))?;
    let mut jobs = Vec::new();
    for job in &manifest.jobs {
        let p = out.join(record_path(&job.id));
        let r = match std::fs::read_to_string(&p) {
            Ok(text) => serde_json::from_str(&text).map_err(|e| Error::json(&p, e))?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                JobRecord::not_run(&job.id, job.line)
            }
            Err(e) => return Err(Error::io(&p, e)),
        };
        jobs.push(r);
    }
    let summary = BatchSummary::new(&manifest.path, out, jobs);
    summary.write(&out.join("summary.json"))?;
    Ok(summary)
}

/// Run one job into `out/<id>/` unless it is complete there, and write its record
/// (`out/records/<id>.json`). A failed stage is a failed record, not an error; an error is
/// what stops the batch itself (an output folder it cannot write).
pub fn run_job(exe: &Path, job: &Job, out: &Path) -> Result<JobRecord> {
    let out = std::path::absolute(out).map_err(|e| Error::io(out, e))?;
    let dest = out.join(&job.id);
    let done = dest.join(JOB_FILE);
    let record = if done.is_file() {
        let text = std::fs::read_to_string(&done).map_err(|e| Error::io(&done, e))?;
        let output: JobOutput = serde_json::from_str(&text).map_err(|e| Error::json(&done, e))?;
        JobRecord::from_output(job.line, Status::Skipped, output)
    } else {
        run_stages(exe, job, &out)?
    };
    let path = out.join(record_path(&job.id));
    let json = serde_json::to_string_pretty(&record).map_err(|e| Error::json(&path, e))?;
    write_atomic(&path, |w| w.write_all(json.as_bytes()))?;
    Ok(record)
}

fn run_stages(exe: &Path, job: &Job, out: &Path) -> Result<JobRecord> {
    let log_file = out.join(log_path(&job.id));
    if let Some(dir) = log_file.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let mut log = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(&log_file)
        .map_err(|e| Error::io(&log_file, e))?;
    let failed = |stages: Vec<StageRecord>, error: String| {
        let mut r = JobRecord::not_run(&job.id, job.line);
        r.status = Status::Failed;
        r.seconds = stages.iter().map(|s| s.seconds).sum();
        r.peak_rss_mib = stages.iter().map(|s| s.peak_rss_mib).max().unwrap_or(0);
        r.stages = stages;
        r.error = Some(error);
        r
    };
    // Another process on this job, or a folder in the way, is this job's failure.
    let dir = match AtomicDir::new(&out.join(&job.id), false) {
        Ok(d) => d,
        Err(e) => return Ok(failed(vec![], e.to_string())),
    };
    let mut stages = Vec::new();
    for s in &job.stages {
        let (record, error) = run_stage(exe, &s.stage, &s.args, dir.path(), &mut log, &log_file)?;
        stages.push(record);
        if let Some(e) = error {
            return Ok(failed(stages, format!("{}: {e}", s.stage)));
        }
    }
    let mut scores = BTreeMap::new();
    let mut warnings = Vec::new();
    for s in &job.stages {
        if let Err(e) = stage_scores(dir.path(), &s.stage, &mut scores, &mut warnings) {
            return Ok(failed(stages, format!("{}: its report: {e}", s.stage)));
        }
    }
    let output = JobOutput {
        id: job.id.clone(),
        stages,
        scores,
        warnings,
    };
    let path = dir.path().join(JOB_FILE);
    let json = serde_json::to_string_pretty(&output).map_err(|e| Error::json(&path, e))?;
    write_atomic(&path, |w| w.write_all(json.as_bytes()))?;
    dir.commit()?;
    Ok(JobRecord::from_output(job.line, Status::Ok, output))
}

/// Run `exe args` in `cwd` with its output appended to `log`; the child dies with this process.
/// Returns its record and, when it failed, why (its last `error:` line, or the signal).
fn run_stage(
    exe: &Path,
    stage: &str,
    args: &[String],
    cwd: &Path,
    log: &mut File,
    log_path: &Path,
) -> Result<(StageRecord, Option<String>)> {
    let io = |e| Error::io(log_path, e);
    writeln!(log, "$ objnerf {}", args.join(" ")).map_err(io)?;
    let start = log.stream_position().map_err(io)?;
    let mut cmd = Command::new(exe);
    cmd.args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(log.try_clone().map_err(io)?)
        .stderr(log.try_clone().map_err(io)?);
    // SAFETY: prctl is async-signal-safe and touches only the child's own state.
    unsafe {
        cmd.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
            Ok(())
        });
    }
    let t0 = Instant::now();
    let child = cmd
        .spawn()
        .map_err(|e| Error::external("objnerf", format!("{}: {e}", exe.display())))?;
    let (status, rusage) = wait_with_rusage(child.id() as libc::pid_t)
        .map_err(|e| Error::external("objnerf", format!("waiting for {stage}: {e}")))?;
    let seconds = t0.elapsed().as_secs_f64();
    // Linux gives ru_maxrss in KiB.
    let peak_rss_mib = ((rusage.ru_maxrss.max(0) as u64) + 512) >> 10;
    let (exit, error) = if libc::WIFEXITED(status) {
        let code = libc::WEXITSTATUS(status);
        let error = (code != 0).then(|| {
            last_error_line(log, start).unwrap_or_else(|| format!("exited with status {code}"))
        });
        (code.to_string(), error)
    } else {
        let sig = libc::WTERMSIG(status);
        let why = if sig == libc::SIGKILL {
            " (killed: out of memory, or by hand)"
        } else {
            ""
        };
        (
            format!("signal {sig}"),
            Some(format!("killed by signal {sig}{why}")),
        )
    };
    writeln!(
        log,
        "[{stage}: exit {exit} after {seconds:.1} s, peak {peak_rss_mib} MiB]"
    )
    .map_err(io)?;
    let record = StageRecord {
        stage: stage.to_string(),
        seconds,
        peak_rss_mib,
        exit,
    };
    Ok((record, error))
}

/// wait4(2): the child's exit status and its resource use (peak RSS included).
fn wait_with_rusage(pid: libc::pid_t) -> std::io::Result<(libc::c_int, libc::rusage)> {
    let mut status = 0;
    // SAFETY: a zeroed rusage is a valid value of the plain C struct wait4 fills in.
    let mut rusage: libc::rusage = unsafe { std::mem::zeroed() };
    loop {
        // SAFETY: both pointers are to live locals for the duration of the call.
        let r = unsafe { libc::wait4(pid, &mut status, 0, &mut rusage) };
        if r == pid {
            return Ok((status, rusage));
        }
        let e = std::io::Error::last_os_error();
        if e.kind() != std::io::ErrorKind::Interrupted {
            return Err(e);
        }
    }
}

/// The last `error: ...` line the command wrote after `start` (the CLI's one-line error).
fn last_error_line(log: &mut File, start: u64) -> Option<String> {
    let mut text = String::new();
    log.seek(std::io::SeekFrom::Start(start)).ok()?;
    log.read_to_string(&mut text).ok()?;
    text.lines()
        .rev()
        .find_map(|l| l.strip_prefix("error: "))
        .map(str::to_string)
}

/// This process dies when its parent does (Linux `PR_SET_PDEATHSIG`): a job run for an engine
/// (Ray, Slurm) ends with the worker that started it, so a retry never races a leftover.
pub fn die_with_parent() -> Result<()> {
    // SAFETY: prctl with PR_SET_PDEATHSIG only sets this process's own parent-death signal.
    unsafe {
        libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
    }
    // The parent may have gone before the call: then init adopted us.
    // SAFETY: getppid has no preconditions.
    if unsafe { libc::getppid() } == 1 {
        return Err(Error::invalid(
            "the process that started this job has ended: not running it",
        ));
    }
    Ok(())
}
