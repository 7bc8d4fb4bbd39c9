//! Running COLMAP's programs: finding the executable, one program at a time with its output
//! logged and reported as progress, feature extraction and matching, and the ids COLMAP gave the
//! images in its database.

use super::SfmOptions;
use crate::error::{Error, Result};
use crate::util::{Detail, Progress};
use std::path::{Path, PathBuf};
use std::process::Command;

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

/// COLMAP's programs as one progress stage of three steps (features, matching, mapping or
/// triangulation).
pub(super) struct Steps<'a> {
    progress: &'a dyn Progress,
    done: std::cell::Cell<u64>,
}

impl<'a> Steps<'a> {
    pub(super) fn new(progress: &'a dyn Progress) -> Self {
        progress.begin("colmap", 3);
        Steps {
            progress,
            done: std::cell::Cell::new(0),
        }
    }

    fn finished(&self, program: &str) {
        self.done.set(self.done.get() + 1);
        self.progress
            .advance(self.done.get(), Detail::Item(program));
    }
}

impl Drop for Steps<'_> {
    fn drop(&mut self) {
        self.progress.end();
    }
}

pub(super) fn run_colmap(program: &Path, args: &[String], log: &Path, steps: &Steps) -> Result<()> {
    let stage = args.first().cloned().unwrap_or_default();
    let out = Command::new(program)
        .args(args)
        .env("QT_QPA_PLATFORM", "offscreen")
        .output()
        .map_err(|e| Error::external("colmap", format!("cannot run {}: {e}", program.display())))?;
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
            format!("failed ({}); log {}:\n{tail}", out.status, log.display()),
        ));
    }
    steps.finished(&stage);
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

/// Where the features of the staged images get matched.
pub(super) struct MatchPlan<'a> {
    /// Pairs (indices into `staged`) for a posed scene, or None.
    pub pairs: Option<&'a [(usize, usize)]>,
    pub staged: &'a [String],
}

pub(super) fn extract_and_match(
    program: &Path,
    work: &Path,
    opts: &SfmOptions,
    camera_args: &[String],
    plan: MatchPlan,
    log: &Path,
    steps: &Steps,
) -> Result<()> {
    let db = work.join("database.db");
    let mut args = vec![
        s("feature_extractor"),
        s("--database_path"),
        db.display().to_string(),
        s("--image_path"),
        work.join("images").display().to_string(),
        s("--SiftExtraction.use_gpu"),
        s("0"),
        s("--SiftExtraction.max_num_features"),
        opts.max_features.to_string(),
        s("--SiftExtraction.num_threads"),
        opts.threads.to_string(),
    ];
    args.extend_from_slice(camera_args);
    run_colmap(program, &args, log, steps)?;
    let mut args = match (opts.matcher.as_str(), plan.pairs) {
        ("auto" | "pairs", Some(pairs)) => {
            let list = work.join("pairs.txt");
            let text: String = pairs
                .iter()
                .map(|&(i, j)| format!("{} {}\n", plan.staged[i], plan.staged[j]))
                .collect();
            std::fs::write(&list, text).map_err(|e| Error::io(&list, e))?;
            vec![
                s("matches_importer"),
                s("--match_list_path"),
                list.display().to_string(),
                s("--match_type"),
                s("pairs"),
            ]
        }
        ("pairs", None) => {
            return Err(Error::invalid(
                "--matcher pairs needs a posed scene (pairs are chosen from the poses)",
            ))
        }
        ("auto" | "exhaustive", _) => vec![s("exhaustive_matcher")],
        ("sequential", _) => vec![s("sequential_matcher")],
        (m, _) => {
            return Err(Error::invalid(format!(
                "unknown matcher '{m}': use auto, exhaustive, sequential or pairs"
            )))
        }
    };
    args.extend([
        s("--database_path"),
        db.display().to_string(),
        s("--SiftMatching.use_gpu"),
        s("0"),
        s("--SiftMatching.num_threads"),
        opts.threads.to_string(),
    ]);
    run_colmap(program, &args, log, steps)
}

/// Run the mapper (full reconstruction) or the point triangulator (known poses) on the staged
/// images' database, writing into `output`; `input` is the known model to triangulate.
pub(super) fn map_points(
    program: &Path,
    work: &Path,
    input: Option<&Path>,
    output: &Path,
    opts: &SfmOptions,
    steps: &Steps,
) -> Result<()> {
    std::fs::create_dir_all(output).map_err(|e| Error::io(output, e))?;
    let mut args = vec![
        s(if input.is_some() {
            "point_triangulator"
        } else {
            "mapper"
        }),
        s("--database_path"),
        work.join("database.db").display().to_string(),
        s("--image_path"),
        work.join("images").display().to_string(),
    ];
    if let Some(input) = input {
        args.extend([s("--input_path"), input.display().to_string()]);
    }
    args.extend([
        s("--output_path"),
        output.display().to_string(),
        s("--Mapper.num_threads"),
        opts.threads.to_string(),
    ]);
    run_colmap(program, &args, &work.join("colmap.log"), steps)
}
