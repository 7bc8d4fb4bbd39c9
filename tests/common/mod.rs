//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The crate's root folder.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `../shared/data/<name>` beside the checkout, or `None` with a printed reason (the test then
/// returns early: CI always has the data).
pub fn shared_data(name: &str) -> Option<PathBuf> {
    let p = repo_root().join("../shared/data").join(name);
    if p.exists() {
        Some(p)
    } else {
        eprintln!(
            "SKIP: {} is absent (the shared data sits beside the checkout in CI)",
            p.display()
        );
        None
    }
}

/// `../shared/models/<name>`, or `None` with a printed reason.
pub fn shared_model(name: &str) -> Option<PathBuf> {
    let p = repo_root().join("../shared/models").join(name);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIP: {} is absent", p.display());
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
