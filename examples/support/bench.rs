//! What every benchmark records: timing statistics, the machine, the commit, CPU time, and the
//! Python venv a reference implementation runs in. Shared by the examples through
//! `#[path = "support/bench.rs"] mod bench;` (each uses a part, hence the allow).
#![allow(dead_code)]

use objnerf::{Error, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The `objnerf` binary built beside the running example (`target/release/objnerf`).
pub fn objnerf_exe() -> PathBuf {
    let exe = std::env::current_exe().expect("own path");
    exe.parent()
        .and_then(|p| p.parent())
        .expect("target/release")
        .join("objnerf")
}

/// Run `objnerf args`; panic with its stderr when it fails (a benchmark stops on a failed run).
pub fn run_objnerf(args: &[String]) -> std::process::Output {
    let out = Command::new(objnerf_exe())
        .args(args)
        .output()
        .expect("run objnerf");
    if !out.status.success() {
        panic!(
            "objnerf {} failed:\n{}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    out
}

/// Summary of a list of timings, in seconds.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Stats {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub p25: f64,
    pub p75: f64,
    pub mean: f64,
    pub runs: Vec<f64>,
}

impl Stats {
    pub fn of(v: &[f64]) -> Stats {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        let q = |p: f64| {
            if s.is_empty() {
                return f64::NAN;
            }
            let x = p * (s.len() - 1) as f64;
            let (i, f) = (x.floor() as usize, x.fract());
            s[i] + (s[(i + 1).min(s.len() - 1)] - s[i]) * f
        };
        Stats {
            median: q(0.5),
            min: s.first().copied().unwrap_or(f64::NAN),
            max: s.last().copied().unwrap_or(f64::NAN),
            p25: q(0.25),
            p75: q(0.75),
            mean: s.iter().sum::<f64>() / s.len().max(1) as f64,
            runs: v.to_vec(),
        }
    }
}

#[allow(unused_imports)] // each example uses a part
pub use objnerf::util::machine::{cpu_seconds, git_commit, machine, Machine};

/// A Python venv's interpreter for a benchmark's reference side: created (and `packages`
/// pip-installed) when missing or when `check` (Python code) fails in it.
pub fn ensure_venv(venv: &Path, check: &str, packages: &[&str]) -> Result<PathBuf> {
    let py = venv.join("bin").join("python");
    let ok = |py: &Path| {
        Command::new(py)
            .args(["-c", check])
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if py.is_file() && ok(&py) {
        return Ok(py);
    }
    eprintln!(
        "setting up the benchmark's Python venv in {} ...",
        venv.display()
    );
    let status = Command::new(objnerf::models::python())
        .args(["-m", "venv"])
        .arg(venv)
        .status()
        .map_err(|e| Error::external("python3 -m venv", e.to_string()))?;
    if !status.success() {
        return Err(Error::external(
            "python3 -m venv",
            format!("failed: {status}"),
        ));
    }
    let out = Command::new(&py)
        .args(["-m", "pip", "install", "--quiet"])
        .args(packages)
        .output()
        .map_err(|e| Error::external("pip install", e.to_string()))?;
    if !out.status.success() || !ok(&py) {
        return Err(Error::external(
            format!("pip install {}", packages.join(" ")),
            String::from_utf8_lossy(&out.stderr).trim().to_string(),
        ));
    }
    Ok(py)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats() {
        let s = Stats::of(&[3.0, 1.0, 2.0, 4.0, 5.0]);
        assert_eq!(
            (s.median, s.min, s.max, s.p25, s.p75),
            (3.0, 1.0, 5.0, 2.0, 4.0)
        );
        assert_eq!(s.mean, 3.0);
    }
}
