//! Running COLMAP's programs: finding the executable and its version (which decides some option
//! names), building each program's command line, running one program at a time with its output
//! logged and reported as progress, and the ids COLMAP gave the images in its database.

use super::StageTime;
use crate::error::{Error, Result};
use crate::util::{Detail, Progress};
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Find the `colmap` program, or say how to install it.
pub fn colmap_program() -> Result<PathBuf> {
    let candidates = std::env::var_os("OBJNERF_COLMAP")
        .map(PathBuf::from)
        .into_iter()
        .chain(std::env::var_os("PATH").into_iter().flat_map(|p| {
            std::env::split_paths(&p)
                .map(|d| d.join("colmap"))
                .collect::<Vec<_>>()
        }));
    for c in candidates {
        if c.is_file() {
            return Ok(c);
        }
    }
    Err(Error::external(
        "colmap",
        "not found on PATH: install it with `sudo apt-get install -y colmap` (Debian/Ubuntu) or set OBJNERF_COLMAP to the program",
    ))
}

/// A COLMAP release number, as `colmap help` prints it ("COLMAP 3.8 -- ...",
/// "COLMAP 3.13.0 -- ...", "COLMAP 4.1.1 (Commit ...)").
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct ColmapVersion {
    pub major: u32,
    pub minor: u32,
    pub patch: u32,
}

impl ColmapVersion {
    pub const fn new(major: u32, minor: u32, patch: u32) -> Self {
        ColmapVersion {
            major,
            minor,
            patch,
        }
    }

    /// The version in the first "COLMAP X.Y[.Z]" of `colmap help`'s output.
    pub fn from_help(text: &str) -> Option<Self> {
        text.match_indices("COLMAP ").find_map(|(i, m)| {
            let rest = &text[i + m.len()..];
            let token: String = rest
                .chars()
                .take_while(|c| c.is_ascii_digit() || *c == '.')
                .collect();
            let mut parts = token.split('.').filter(|p| !p.is_empty());
            let major = parts.next()?.parse().ok()?;
            let minor = parts.next()?.parse().ok()?;
            let patch = parts.next().and_then(|p| p.parse().ok()).unwrap_or(0);
            Some(ColmapVersion::new(major, minor, patch))
        })
    }

    /// The option section of feature extraction's GPU and thread options: `SiftExtraction` up to
    /// 3.12, `FeatureExtraction` from 3.13.0 (colmap PR 3465 renamed them and dropped the old
    /// names; `SiftExtraction.max_num_features` kept its name).
    pub(super) fn extraction(self) -> &'static str {
        if self >= RENAMED_FEATURE_OPTIONS {
            "FeatureExtraction"
        } else {
            "SiftExtraction"
        }
    }

    /// The matchers' counterpart of [`Self::extraction`]: `SiftMatching` / `FeatureMatching`.
    pub(super) fn matching(self) -> &'static str {
        if self >= RENAMED_FEATURE_OPTIONS {
            "FeatureMatching"
        } else {
            "SiftMatching"
        }
    }
}

impl std::fmt::Display for ColmapVersion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{}.{}", self.major, self.minor, self.patch)
    }
}

/// The first release with the FeatureExtraction / FeatureMatching option names.
const RENAMED_FEATURE_OPTIONS: ColmapVersion = ColmapVersion::new(3, 13, 0);

/// The installed COLMAP: its program and its version.
#[derive(Clone, Debug)]
pub struct Colmap {
    pub program: PathBuf,
    pub version: ColmapVersion,
}

impl Colmap {
    /// Find `colmap` ([`colmap_program`]) and read its version from `colmap help`.
    pub fn find() -> Result<Colmap> {
        let program = colmap_program()?;
        let out = Command::new(&program)
            .arg("help")
            .env("QT_QPA_PLATFORM", "offscreen")
            .output()
            .map_err(|e| {
                Error::external("colmap", format!("cannot run {}: {e}", program.display()))
            })?;
        let mut text = String::from_utf8_lossy(&out.stdout).to_string();
        text.push_str(&String::from_utf8_lossy(&out.stderr));
        let version = ColmapVersion::from_help(&text).ok_or_else(|| {
            Error::external(
                "colmap",
                format!(
                    "cannot tell the version of {} from `colmap help`, which printed: {:?} (objnerf runs COLMAP 3.8 to 3.13)",
                    program.display(),
                    text.lines().next().unwrap_or("")
                ),
            )
        })?;
        Ok(Colmap { program, version })
    }
}

/// COLMAP's programs as one progress stage of three steps (features, matching, mapping or
/// triangulation), each program's time kept for the report.
pub(super) struct Steps<'a> {
    progress: &'a dyn Progress,
    done: std::cell::Cell<u64>,
    times: RefCell<Vec<StageTime>>,
}

impl<'a> Steps<'a> {
    pub(super) fn new(progress: &'a dyn Progress) -> Self {
        progress.begin("colmap", 3);
        Steps {
            progress,
            done: std::cell::Cell::new(0),
            times: RefCell::new(Vec::new()),
        }
    }

    fn finished(&self, program: &str, seconds: f64) {
        self.done.set(self.done.get() + 1);
        self.progress
            .advance(self.done.get(), Detail::Item(program));
        self.times.borrow_mut().push(StageTime {
            stage: stage_name(program).to_string(),
            seconds,
        });
    }

    /// The time each finished program took, in order.
    pub(super) fn times(&self) -> Vec<StageTime> {
        self.times.borrow().clone()
    }
}

impl Drop for Steps<'_> {
    fn drop(&mut self) {
        self.progress.end();
    }
}

/// The report's name for what a COLMAP program does.
fn stage_name(program: &str) -> &str {
    match program {
        "feature_extractor" => "features",
        "exhaustive_matcher" | "sequential_matcher" | "matches_importer" => "matching",
        "mapper" => "mapping",
        "point_triangulator" => "triangulation",
        other => other,
    }
}

pub(super) fn run_colmap(
    colmap: &Colmap,
    args: &[String],
    log: &Path,
    steps: &Steps,
) -> Result<()> {
    let stage = args.first().cloned().unwrap_or_default();
    let start = Instant::now();
    let out = Command::new(&colmap.program)
        .args(args)
        .env("QT_QPA_PLATFORM", "offscreen")
        .output()
        .map_err(|e| {
            Error::external(
                "colmap",
                format!("cannot run {}: {e}", colmap.program.display()),
            )
        })?;
    let mut text = String::from_utf8_lossy(&out.stdout).to_string();
    text.push_str(&String::from_utf8_lossy(&out.stderr));
    use std::io::Write;
    if let Ok(mut f) = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
    {
        let _ = writeln!(f, "$ colmap {}\n{text}", args.join(" "));
    }
    if !out.status.success() {
        let tail: String = text
            .lines()
            .rev()
            .take(15)
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect::<Vec<_>>()
            .join("\n");
        return Err(Error::external(
            format!("colmap {stage}"),
            format!(
                "failed ({}; COLMAP {}); log {}:\n{tail}",
                out.status,
                colmap.version,
                log.display()
            ),
        ));
    }
    steps.finished(&stage, start.elapsed().as_secs_f64());
    Ok(())
}

/// A COLMAP argument.
pub(super) fn s(x: impl ToString) -> String {
    x.to_string()
}

/// Image name → (image id, camera id) from a COLMAP database.
pub(super) fn database_ids(db: &Path) -> Result<std::collections::HashMap<String, (u32, u32)>> {
    let err = |e: rusqlite::Error| Error::format(db, format!("cannot read COLMAP's database: {e}"));
    let conn =
        rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .map_err(err)?;
    let mut stmt = conn
        .prepare("SELECT image_id, name, camera_id FROM images")
        .map_err(err)?;
    let rows = stmt
        .query_map([], |r| {
            Ok((
                r.get::<_, String>(1)?,
                (r.get::<_, u32>(0)?, r.get::<_, u32>(2)?),
            ))
        })
        .map_err(err)?;
    rows.collect::<std::result::Result<_, _>>().map_err(err)
}
