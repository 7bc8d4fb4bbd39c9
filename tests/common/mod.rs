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
