//! Interrupted runs (issue 18, part 5): `objnerf extract` killed with SIGKILL at 20 random
//! moments never leaves a half-written output; the same command run again completes; two runs
//! into one folder at once: the second is refused with a clear error while the first completes.
//!
//! Slow (a few minutes on 2 cores: 20 partial runs and their reruns), hence ignored by default:
//! `cargo test --release --test interrupted -- --ignored`.
mod common;

use objnerf::demo::{read_truth, write_demo_scene, DemoOptions};
use objnerf::models::ModelsDir;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn sam_installed() -> bool {
    let ok = ModelsDir::from_env()
        .map(|d| d.require_sam().is_ok() && d.require_library().is_ok())
        .unwrap_or(false);
    if !ok {
        common::skip("SAM models are not installed (scripts/setup installs them)");
    }
    ok
}

/// A small demo scene (12 views, 200 x 150) and the extract command for its mug.
fn setup(dir: &Path) -> (PathBuf, Vec<String>) {
    let scene = dir.join("scene");
    write_demo_scene(
        &DemoOptions {
            views: 12,
            width: 200,
            height: 150,
            ..Default::default()
        },
        &scene,
    )
    .unwrap();
    let mug = read_truth(&scene).unwrap().remove(0);
    let args = vec![
        "extract".to_string(),
        scene.display().to_string(),
        "--view".into(),
        mug.view.clone(),
        "--object".into(),
        "mug".into(),
        "--point".into(),
        format!("{},{}", mug.click[0], mug.click[1]),
        "--steps".into(),
        "300".into(),
        "--time-budget".into(),
        "100000".into(),
        "--frames".into(),
        "3".into(),
        "--overwrite".into(),
    ];
    (scene, args)
}

fn spawn(args: &[String], out: &Path) -> Child {
    Command::new(common::objnerf_bin())
        .args(args)
        .arg("--out")
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Every file of a finished run is whole: the report parses and names files that exist, images
/// decode, the glTF files import, the model loads; no temporary file is inside.
fn assert_complete(out: &Path) {
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let obj = &report["objects"][0];
    for key in ["model", "mesh_glb", "turntable_gif"] {
        let p = PathBuf::from(obj[key].as_str().unwrap());
        assert!(p.is_file(), "{key}: {} is missing", p.display());
    }
    objnerf::field::io::load_field(&out.join("mug/model.objf")).unwrap();
    for glb in ["mesh.glb", "mug/mesh.glb"] {
        gltf::import(out.join(glb)).unwrap_or_else(|e| panic!("{glb}: {e}"));
    }
    objnerf::mesh::io::read_ply(&out.join("mug/mesh.ply")).unwrap();
    let mut stack = vec![out.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            let name = e.file_name().to_string_lossy().to_string();
            assert!(
                !name.starts_with(".objnerf-") && !name.contains(".objnerf-"),
                "temporary file left in the output: {}",
                p.display()
            );
            if p.is_dir() {
                stack.push(p);
            } else if name.ends_with(".png") || name.ends_with(".gif") {
                image::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            } else if name.ends_with(".json") {
                let text = std::fs::read_to_string(&p).unwrap();
                serde_json::from_str::<serde_json::Value>(&text)
                    .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            }
        }
    }
}

/// What a run into `out` leaves beside it (hidden temporary folders, the lock).
fn leftovers(out: &Path) -> Vec<String> {
    let name = out.file_name().unwrap().to_string_lossy().to_string();
    std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with(&format!(".{name}.")))
        .collect()
}

#[test]
#[ignore = "slow: 20 killed runs and their reruns; cargo test --release --test interrupted -- --ignored"]
fn killed_runs_leave_nothing_half_written_and_a_second_run_is_refused() {
    if !sam_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (_, args) = setup(dir.path());
    let out = dir.path().join("run");

    // Two whole runs: the first fills SAM's embedding cache, the second times a run as the
    // killed ones will go.
    let mut full = Duration::ZERO;
    for _ in 0..2 {
        let t = Instant::now();
        let run = spawn(&args, &out).wait_with_output().unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        full = t.elapsed();
        assert_complete(&out);
    }
    println!("a whole run takes {:.1} s", full.as_secs_f64());

    // 20 kills at seeded random moments over a run's length, every other one into an empty
    // place and the others over a complete run (--overwrite replaces it); after each, the
    // output is a complete run or absent (never partial), and the same command run again
    // completes.
    let mut rng = objnerf::util::Rng::new(18);
    let mut outcomes = Vec::new();
    for k in 0..20 {
        if k % 2 == 0 && out.exists() {
            std::fs::remove_dir_all(&out).unwrap();
        }
        if k % 2 == 1 && !out.exists() {
            let run = spawn(&args, &out).wait_with_output().unwrap();
            assert!(
                run.status.success(),
                "{}",
                String::from_utf8_lossy(&run.stderr)
            );
        }
        let at = Duration::from_secs_f64(full.as_secs_f64() * rng.range(0.02, 0.98));
        let mut child = spawn(&args, &out);
        std::thread::sleep(at);
        let finished = child.try_wait().unwrap().is_some();
        child.kill().ok(); // SIGKILL on Unix
        child.wait().unwrap();
        let present = out.exists();
        if present {
            assert_complete(&out);
        }
        outcomes.push(format!(
            "kill {k} at {:.1} s: {}",
            at.as_secs_f64(),
            match (finished, present) {
                (true, _) => "had finished",
                (false, true) => "a whole output",
                (false, false) => "no output",
            }
        ));
        if k % 4 == 3 {
            // The same command again completes (and clears what the killed run left).
            let again = spawn(&args, &out).wait_with_output().unwrap();
            assert!(
                again.status.success(),
                "rerun after kill {k}: {}",
                String::from_utf8_lossy(&again.stderr)
            );
            assert_complete(&out);
            assert!(leftovers(&out).is_empty(), "{:?}", leftovers(&out));
        }
    }
    println!("{}", outcomes.join("\n"));

    // Two runs into one folder at once: the second is refused while the first holds the lock.
    let mut a = spawn(&args, &out);
    let lock = dir.path().join(".run.objnerf-lock");
    let t = Instant::now();
    while !lock.exists() {
        assert!(
            t.elapsed() < Duration::from_secs(120),
            "the first run never took the lock"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let b = spawn(&args, &out).wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&b.stderr);
    assert!(!b.status.success(), "the second run was not refused");
    assert!(
        err.contains("another objnerf run") && err.contains(&out.display().to_string()),
        "{err}"
    );
    println!("second run: {}", err.trim());
    let a = a.wait().unwrap();
    assert!(a.success(), "the first run failed");
    assert_complete(&out);
    assert!(leftovers(&out).is_empty(), "{:?}", leftovers(&out));
}
