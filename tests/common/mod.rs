//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod browser;

use std::path::{Path, PathBuf};

/// The crate's root folder.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Print why a test returns early without checking anything, and record it in the file
/// `$OBJNERF_SKIP_LOG` names (scripts/test lists them at the end, so CI's log shows every test
/// that skipped and why).
pub fn skip(reason: &str) {
    eprintln!("SKIP: {reason}");
    let Some(log) = std::env::var_os("OBJNERF_SKIP_LOG") else {
        return;
    };
    let test = std::thread::current().name().unwrap_or("?").to_string();
    let bin = std::env::args()
        .next()
        .map(|a| {
            let stem = Path::new(&a)
                .file_stem()
                .unwrap_or_default()
                .to_string_lossy()
                .to_string();
            // cargo names test binaries `<name>-<hash>`.
            stem.rsplit_once('-')
                .map_or(stem.clone(), |(n, _)| n.to_string())
        })
        .unwrap_or_default();
    append_line(&log, &format!("{bin}::{test}: {reason}"));
}

/// Append one line to a log a script gathers after the tests (best effort: a test never fails
/// for its log).
fn append_line(log: &std::ffi::OsStr, line: &str) {
    use std::io::Write;
    if let Ok(mut f) = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
    {
        let _ = writeln!(f, "{line}");
    }
}

/// Record a figure a test checks (its value, the floor it is held to, whether it holds) in the
/// file `$OBJNERF_QUALITY_LOG` names, one JSON object a line: `scripts/quality` gathers them
/// into `examples/results/quality.json`. `higher`: the figure must be at least the floor (else
/// at most).
pub fn figure(id: &str, value: f64, floor: f64, higher: bool) {
    let Some(log) = std::env::var_os("OBJNERF_QUALITY_LOG") else {
        return;
    };
    let test = std::thread::current().name().unwrap_or("?").to_string();
    let pass = if higher {
        value >= floor
    } else {
        value <= floor
    };
    let line = serde_json::json!({
        "test": test, "figure": id, "value": value, "floor": floor,
        "higher_is_better": higher, "pass": pass,
    });
    append_line(&log, &line.to_string());
}

/// `../shared/data/<name>` beside the checkout, or `None` with a printed reason (the test then
/// returns early: CI always has the data).
pub fn shared_data(name: &str) -> Option<PathBuf> {
    let p = repo_root().join("../shared/data").join(name);
    if p.exists() {
        Some(p)
    } else {
        skip(&format!(
            "{} is absent (the shared data sits beside the checkout in CI)",
            p.display()
        ));
        None
    }
}

/// `../shared/models/<name>`, or `None` with a printed reason.
pub fn shared_model(name: &str) -> Option<PathBuf> {
    let p = repo_root().join("../shared/models").join(name);
    if p.exists() {
        Some(p)
    } else {
        skip(&format!("{} is absent", p.display()));
        None
    }
}

/// The built `objnerf` binary (cargo builds it for integration tests).
pub fn objnerf_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_objnerf"))
}

/// Run the validator (scripts/setup installs node and the npm package) and return its report.
pub fn validate_gltf(path: &std::path::Path) -> serde_json::Value {
    let script = repo_root().join("tools/gltf-validator/validate.mjs");
    if !repo_root()
        .join("tools/gltf-validator/node_modules/gltf-validator")
        .exists()
    {
        panic!("glTF-Validator is not installed: run `npm install --prefix tools/gltf-validator` (scripts/setup does)");
    }
    let out = std::process::Command::new("node")
        .arg(&script)
        .arg(path)
        .output()
        .expect("node runs (scripts/setup installs it)");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "validator output is not JSON ({e}): {}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// lego triangulated with its known poses (`objnerf sfm transforms_train.json --downscale 2
/// --max-features 4096`, about 3 minutes), built once per build of the binary into the target
/// directory and shared by the tests that need it. `None` (with a printed reason) without lego
/// or COLMAP.
pub fn lego_sfm_model() -> Option<PathBuf> {
    static BUILDING: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one_at_a_time = BUILDING.lock().unwrap_or_else(|e| e.into_inner());
    let lego = shared_data("lego")?;
    if objnerf::scene::sfm::colmap_program().is_err() {
        skip("colmap is not installed (scripts/setup installs it)");
        return None;
    }
    // Keyed by the binary, so that a model from older code is never reused.
    let meta = std::fs::metadata(objnerf_bin()).unwrap();
    let modified = meta
        .modified()
        .unwrap()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos();
    let tmp = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let name = format!("lego_sfm-{}-{modified}", meta.len());
    let out = tmp.join(&name);
    if out.join("sparse/0/points3D.bin").is_file() {
        return Some(out);
    }
    for old in std::fs::read_dir(&tmp).into_iter().flatten().flatten() {
        if old.file_name().to_string_lossy().starts_with("lego_sfm-") {
            let _ = std::fs::remove_dir_all(old.path());
        }
    }
    sfm(&lego.join("transforms_train.json"), &out);
    Some(out)
}

/// `objnerf sfm INPUT --out OUT --downscale 2 --max-features 4096` (the settings the README and
/// the tests use for the shared captures); panics with COLMAP's stderr when it fails.
pub fn sfm(input: &std::path::Path, out: &std::path::Path) {
    objnerf_ok(&[
        "sfm",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--overwrite",
        "--downscale",
        "2",
        "--max-features",
        "4096",
    ]);
}

/// Run `objnerf ARGS`; panics with its stderr unless it succeeds.
pub fn objnerf_ok(args: &[&str]) -> std::process::Output {
    let out = std::process::Command::new(objnerf_bin())
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "objnerf {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Whether SAM (models and ONNX Runtime) is installed; prints a SKIP line when not.
pub fn sam_installed() -> bool {
    let ok = objnerf::models::ModelsDir::from_env()
        .map(|d| d.require_sam().is_ok() && d.require_library().is_ok())
        .unwrap_or(false);
    if !ok {
        skip("SAM models are not installed (scripts/setup runs `objnerf models install`)");
    }
    ok
}

/// Every `.rs` file under `dir`, appended to `out`.
pub fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}
