//! ONNX Runtime, loaded once per process from the shared library `objnerf models install` puts in
//! the models directory (the `ort` crate with `load-dynamic`: nothing is linked at build time).

use super::INSTALL_HINT;
use crate::error::{Error, Result};
use ort::environment::Environment;
use std::path::Path;
use std::sync::{Mutex, OnceLock};

/// ONNX Runtime allows one environment per process, and the library can be loaded only once, so
/// both live here for the life of the process.
static ENV: OnceLock<Environment> = OnceLock::new();
static ENV_LOCK: Mutex<()> = Mutex::new(());

/// Load ONNX Runtime from `lib` (once per process) and return the environment.
pub fn runtime(lib: &Path) -> Result<Environment> {
    // Checked on every call, even once a library is loaded: a caller naming a library that does
    // not exist has a broken setup and should hear about it.
    if !lib.is_file() {
        return Err(Error::external(
            "ONNX Runtime library",
            format!("{} not found; run `{INSTALL_HINT}`", lib.display()),
        ));
    }
    if let Some(env) = ENV.get() {
        return Ok(env.clone());
    }
    let _guard = ENV_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(env) = ENV.get() {
        return Ok(env.clone());
    }
    // Load the library explicitly rather than through ORT_DYLIB_PATH: setting environment
    // variables in a running (possibly multi-threaded) process is racy, and this way a bad library
    // is an error rather than ort's panic.
    let builder = ort::init_from(lib).map_err(|e| {
        Error::external(
            "ONNX Runtime library",
            format!("{e}; reinstall it with `{INSTALL_HINT}`"),
        )
    })?;
    let env = builder
        .with_name("objnerf")
        .with_telemetry(false)
        .build()
        .map_err(|e| Error::external("ONNX Runtime", e.to_string()))?;
    let _ = ENV.set(env.clone());
    Ok(env)
}
