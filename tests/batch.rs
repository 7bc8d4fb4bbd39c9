//! `objnerf batch` (issue 57): an 8-job manifest on demo scenes (three seeds; extract, remove,
//! export; one object or two; a click or a click and a box) run locally, every job's output and
//! the summary checked; a rerun does nothing; a broken line stops everything before it starts;
//! a failed job is recorded and the others run. `scripts/ray_batch.py` on the same manifest on a
//! local Ray head, one Ray worker killed mid-job: ignored by default (see the README).

mod common;

use objnerf::demo::{read_truth, write_demo_scene, DemoOptions};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::SystemTime;

/// Small and fast, as the other tests on the demo scene: 8 views at 160x120, step budgets (the
/// same result on any machine and at any load).
fn extract_options(seed: u64) -> Value {
    json!({"steps": 200, "time-budget": "none", "frames": 2, "seed": seed})
}

fn remove_options() -> Value {
    json!({"steps": 50, "time-budget": "none", "downscale": 2})
}

/// The box around `object`'s true mask in `view`, grown by 4 pixels.
fn true_box(scene: &Path, object: &str, view: &str) -> [f64; 4] {
    let m = image::open(scene.join("truth/masks").join(object).join(view))
        .unwrap()
        .to_luma8();
    let (mut lo, mut hi) = ([u32::MAX; 2], [0u32; 2]);
    for (x, y, p) in m.enumerate_pixels() {
        if p.0[0] > 127 {
            lo = [lo[0].min(x), lo[1].min(y)];
            hi = [hi[0].max(x + 1), hi[1].max(y + 1)];
        }
    }
    let (w, h) = (m.width() as f64, m.height() as f64);
    [
        (lo[0] as f64 - 4.0).max(0.0),
        (lo[1] as f64 - 4.0).max(0.0),
        (hi[0] as f64 + 4.0).min(w),
        (hi[1] as f64 + 4.0).min(h),
    ]
}

/// Three demo scenes (seeds 1, 2, 3) in `dir/scenes/` and the 8-job manifest `dir/jobs.jsonl`
/// on them (relative paths: the manifest's folder is their base).
fn eight_job_manifest(dir: &Path) -> PathBuf {
    let mut truth = BTreeMap::new();
    for seed in 1..=3u64 {
        let scene = dir.join(format!("scenes/s{seed}"));
        let opts = DemoOptions {
            seed,
            views: 8,
            width: 160,
            height: 120,
            ..Default::default()
        };
        write_demo_scene(&opts, &scene).unwrap();
        let t: BTreeMap<String, (String, [f64; 2])> = read_truth(&scene)
            .unwrap()
            .into_iter()
            .map(|o| (o.name.clone(), (o.view, o.click)))
            .collect();
        truth.insert(seed, t);
    }
    let object = |seed: u64, name: &str| {
        let (_, click) = &truth[&seed][name];
        json!({"name": name, "points": [click]})
    };
    let view = |seed: u64, name: &str| truth[&seed][name].0.clone();
    let extract = |seed: u64, objects: Vec<Value>, first: &str| json!({"view": view(seed, first), "objects": objects, "options": extract_options(seed)});
    let mut torus = object(1, "torus");
    torus["box"] = json!(true_box(&dir.join("scenes/s1"), "torus", &view(1, "torus")));
    let jobs = vec![
        json!({"id": "mug_s1", "scene": "scenes/s1",
               "extract": extract(1, vec![object(1, "mug")], "mug"),
               "remove": {"options": remove_options()},
               "export": {"object": "mug"},
               "resources": {"cpus": 1, "memory_mb": 1500}}),
        json!({"id": "torus_box_s1", "scene": "scenes/s1",
               "extract": extract(1, vec![torus], "torus"),
               "export": {"background": true}}),
        json!({"id": "sphere_s2", "scene": "scenes/s2",
               "extract": extract(2, vec![object(2, "sphere")], "sphere")}),
        json!({"id": "box_s2", "scene": "scenes/s2",
               "extract": extract(2, vec![object(2, "box")], "box"),
               "remove": {"options": remove_options()}}),
        json!({"id": "scene_s2", "scene": "scenes/s2", "export": {"options": {"downscale": 2}}}),
        json!({"id": "mug_s3", "scene": "scenes/s3",
               "extract": extract(3, vec![object(3, "mug")], "mug"),
               "export": {"object": "mug"}}),
        json!({"id": "mug_torus_s3", "scene": "scenes/s3",
               "extract": extract(3, vec![object(3, "mug"), object(3, "torus")], "mug"),
               "remove": {"objects": ["torus"], "options": remove_options()}}),
        json!({"id": "sphere_s3", "scene": "scenes/s3",
               "extract": extract(3, vec![object(3, "sphere")], "sphere"),
               "export": {"object": "sphere"}}),
    ];
    let path = dir.join("jobs.jsonl");
    let text: Vec<String> = jobs.iter().map(|j| j.to_string()).collect();
    std::fs::write(&path, text.join("\n") + "\n").unwrap();
    path
}

fn batch(args: &[&Path], extra: &[&str]) -> Output {
    let out = Command::new(common::objnerf_bin())
        .arg("batch")
        .args(args)
        .args(extra)
        .output()
        .unwrap();
    println!("{}", String::from_utf8_lossy(&out.stdout));
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    out
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// Every file under `dir` (relative path) with its size and modification time.
fn files(dir: &Path) -> BTreeMap<PathBuf, (u64, SystemTime)> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            let m = std::fs::symlink_metadata(&p).unwrap();
            if m.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_path_buf();
                out.insert(rel, (m.len(), m.modified().unwrap()));
            }
        }
    }
    out
}

/// The object names of a .glb's meshes, read with `gltf::import`.
fn glb_meshes(path: &Path) -> Vec<String> {
    let (doc, buffers, _) =
        gltf::import(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut names = Vec::new();
    for m in doc.meshes() {
        let prim = m.primitives().next().unwrap();
        let r = prim.reader(|b| Some(&buffers[b.index()]));
        assert!(
            r.read_positions().unwrap().count() > 100,
            "{}",
            path.display()
        );
        names.push(m.name().unwrap_or_default().to_string());
    }
    names
}

/// What each job of the manifest should have written, checked on `out`.
fn check_outputs(out: &Path, summary: &Value) {
    let jobs = summary["jobs"].as_array().unwrap();
    let ids: Vec<&str> = jobs.iter().map(|j| j["id"].as_str().unwrap()).collect();
    assert_eq!(
        ids,
        [
            "mug_s1",
            "torus_box_s1",
            "sphere_s2",
            "box_s2",
            "scene_s2",
            "mug_s3",
            "mug_torus_s3",
            "sphere_s3"
        ]
    );
    let extracted: BTreeMap<&str, Vec<&str>> = [
        ("mug_s1", vec!["mug"]),
        ("torus_box_s1", vec!["torus"]),
        ("sphere_s2", vec!["sphere"]),
        ("box_s2", vec!["box"]),
        ("mug_s3", vec!["mug"]),
        ("mug_torus_s3", vec!["mug", "torus"]),
        ("sphere_s3", vec!["sphere"]),
    ]
    .into();
    for j in jobs {
        let id = j["id"].as_str().unwrap();
        let dir = out.join(id);
        let scores = &j["scores"];
        assert!(j["peak_rss_mib"].as_u64().unwrap() > 0, "{id}");
        assert!(j["seconds"].as_f64().unwrap() > 0.0, "{id}");
        assert_eq!(read_json(&dir.join("job.json"))["scores"], *scores, "{id}");
        if let Some(objects) = extracted.get(id) {
            let report = read_json(&dir.join("extract/report.json"));
            // The stages ran in the job's folder: the report's paths hold in the finished one.
            assert_eq!(report["out"], "extract", "{id}");
            assert_eq!(glb_meshes(&dir.join("extract/mesh.glb")), *objects, "{id}");
            for o in objects {
                assert!(dir.join("extract").join(o).join("model.objf").is_file());
                let psnr = scores[format!("extract.{o}.train_psnr")].as_f64().unwrap();
                assert!(psnr > 20.0, "{id} {o}: training PSNR {psnr}");
                assert!(scores[format!("extract.{o}.ok_views")].as_f64().unwrap() >= 3.0);
            }
        } else {
            assert!(!dir.join("extract").exists(), "{id}");
        }
        let removes = ["mug_s1", "box_s2", "mug_torus_s3"].contains(&id);
        assert_eq!(
            dir.join("remove/background.objf").is_file(),
            removes,
            "{id}"
        );
        if removes {
            let renders = std::fs::read_dir(dir.join("remove/renders"))
                .unwrap()
                .count();
            assert_eq!(renders, 8, "{id}: one render a view");
            assert!(scores["remove.truth_psnr"].as_f64().unwrap() > 8.0, "{id}");
        }
        let exports = ["mug_s1", "torus_box_s1", "scene_s2", "mug_s3", "sphere_s3"].contains(&id);
        assert_eq!(
            dir.join("export/transforms.json").is_file(),
            exports,
            "{id}"
        );
        if exports {
            let t = read_json(&dir.join("export/transforms.json"));
            let frames = t["frames"].as_array().unwrap().len();
            assert_eq!(
                scores["export.frames"].as_f64(),
                Some(frames as f64),
                "{id}"
            );
            assert!(frames >= 3, "{id}: {frames} frames");
        }
    }
    // The background export has every view, each with a mask.
    let t = read_json(&out.join("torus_box_s1/export/transforms.json"));
    assert_eq!(t["frames"].as_array().unwrap().len(), 8);
    assert!(out.join("torus_box_s1/export/masks").is_dir());
    // Nothing half-written or locked is left beside the jobs.
    for e in std::fs::read_dir(out).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        assert!(!name.starts_with('.'), "left behind: {name}");
    }
}

#[test]
fn eight_jobs_run_resume_and_a_broken_line_runs_nothing() {
    if !common::sam_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let manifest = eight_job_manifest(dir.path());
    let out = dir.path().join("out");

    let run = batch(&[&manifest], &["--out", out.to_str().unwrap()]);
    assert!(run.status.success(), "the batch failed");
    let summary = read_json(&out.join("summary.json"));
    assert_eq!(summary["counts"], json!({"ok": 8}), "{summary}");
    check_outputs(&out, &summary);
    let table = String::from_utf8_lossy(&run.stdout).to_string();
    for j in summary["jobs"].as_array().unwrap() {
        let id = j["id"].as_str().unwrap();
        assert!(
            table
                .lines()
                .any(|l| l.starts_with(id) && l.contains(" ok ")),
            "{id} not in the table:\n{table}"
        );
    }
    assert_eq!(std::fs::read_dir(out.join("records")).unwrap().count(), 8);

    // A rerun does nothing: every job skipped, every file of the jobs and their logs untouched.
    let before: Vec<_> = ["mug_s1", "mug_torus_s3", "scene_s2", "logs"]
        .iter()
        .map(|d| files(&out.join(d)))
        .collect();
    let again = batch(&[&manifest], &["--out", out.to_str().unwrap()]);
    assert!(again.status.success());
    let summary2 = read_json(&out.join("summary.json"));
    assert_eq!(summary2["counts"], json!({"skipped": 8}), "{summary2}");
    for (j1, j2) in summary["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(summary2["jobs"].as_array().unwrap())
    {
        assert_eq!(j1["scores"], j2["scores"]);
        assert_eq!(
            j1["seconds"], j2["seconds"],
            "a skipped job keeps the time of its run"
        );
    }
    let after: Vec<_> = ["mug_s1", "mug_torus_s3", "scene_s2", "logs"]
        .iter()
        .map(|d| files(&out.join(d)))
        .collect();
    assert_eq!(before, after, "a rerun touched a job's files");

    // One broken line: an error naming the file and the line, and nothing runs.
    let text = std::fs::read_to_string(&manifest).unwrap();
    for (bad_line, want) in [
        (
            r#"{"id": "x", "scene": "scenes/s1", "extract": {"view": "view_000.png""#,
            "not a job",
        ),
        (
            r#"{"id": "x", "scene": "scenes/s1", "extract": {"view": "view_000.png", "objects": [{"name": "mug", "points": [[50, 50]]}], "options": {"stepz": 5}}}"#,
            "--stepz",
        ),
        (
            r#"{"id": "x", "scene": "scenes/nowhere", "export": {}}"#,
            "does not exist",
        ),
        (
            r#"{"id": "mug_s1", "scene": "scenes/s1", "export": {}}"#,
            "used twice",
        ),
    ] {
        let mut lines: Vec<&str> = text.lines().collect();
        lines.insert(4, bad_line);
        let broken = dir.path().join("broken.jsonl");
        std::fs::write(&broken, lines.join("\n")).unwrap();
        let out2 = dir.path().join("out_broken");
        let o = batch(&[&broken], &["--out", out2.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        let at = format!("{}:5: ", broken.display());
        assert!(
            err.contains(&at) && err.contains(want),
            "'{at}' and '{want}' not in: {err}"
        );
        assert!(!out2.exists(), "a broken manifest wrote {}", out2.display());
    }
}

/// A job that fails is recorded with its error and does not stop the others; the rerun tries
/// it again and skips the rest. (No SAM: export of a scene, removal with a folder that is no
/// segmentation.)
#[test]
fn a_failed_job_is_recorded_and_the_others_run() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    let opts = DemoOptions {
        views: 4,
        width: 64,
        height: 48,
        ..Default::default()
    };
    write_demo_scene(&opts, &scene).unwrap();
    let manifest = dir.path().join("jobs.jsonl");
    let jobs = [
        json!({"id": "bad_remove", "scene": "scene", "remove": {"segment": "scene", "objects": ["mug"]}}),
        json!({"id": "export", "scene": "scene", "export": {}}),
    ];
    let text: Vec<String> = jobs.iter().map(|j| j.to_string()).collect();
    std::fs::write(&manifest, text.join("\n")).unwrap();
    let out = dir.path().join("out");
    for (pass, want) in [
        (1, json!({"failed": 1, "ok": 1})),
        (2, json!({"failed": 1, "skipped": 1})),
    ] {
        let o = batch(&[&manifest], &["--out", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(1), "pass {pass}");
        let s = read_json(&out.join("summary.json"));
        assert_eq!(s["counts"], want, "pass {pass}");
        let failed = &s["jobs"][0];
        assert_eq!(failed["status"], "failed");
        let error = failed["error"].as_str().unwrap();
        assert!(
            error.starts_with("remove: ") && error.contains("scene/report.json"),
            "{error}"
        );
        assert!(
            !out.join("bad_remove").exists(),
            "a failed job left a folder"
        );
        let log = std::fs::read_to_string(out.join("logs/bad_remove.log")).unwrap();
        assert!(
            log.contains("$ objnerf remove") && log.contains("error: "),
            "{log}"
        );
        assert!(String::from_utf8_lossy(&o.stdout).contains("bad_remove failed: remove: "));
    }
    assert!(out.join("export/export/transforms.json").is_file());
    // One job by id, as an engine runs it: the record comes back on stdout.
    let one = batch(
        &[&manifest],
        &["--out", out.to_str().unwrap(), "--job", "export"],
    );
    assert!(one.status.success());
    let r: Value = serde_json::from_slice(&one.stdout).unwrap();
    assert_eq!(r["status"], "skipped");
    let line = batch(
        &[&manifest],
        &["--out", out.to_str().unwrap(), "--line", "3"],
    );
    assert!(String::from_utf8_lossy(&line.stderr).contains(":3: no job on this line"));
}

/// Every process: (pid, parent pid, command line).
fn processes() -> Vec<(i32, i32, Vec<String>)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        let (Ok(stat), Ok(cmd)) = (
            std::fs::read_to_string(e.path().join("stat")),
            std::fs::read(e.path().join("cmdline")),
        ) else {
            continue;
        };
        // "pid (comm) state ppid ...": comm may hold spaces, so read after its last ')'.
        let after = &stat[stat.rfind(')').unwrap() + 2..];
        let ppid = after.split(' ').nth(1).unwrap().parse().unwrap();
        let args = cmd
            .split(|&b| b == 0)
            .filter(|a| !a.is_empty())
            .map(|a| String::from_utf8_lossy(a).to_string())
            .collect();
        out.push((pid, ppid, args));
    }
    out
}

/// Alive and not a zombie.
fn running(pid: i32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .map(|s| !s[s.rfind(')').unwrap() + 2..].starts_with('Z'))
        .unwrap_or(false)
}

/// A Ray head on loopback (`ray start --head --block`) in a process group of its own, ended
/// with the group when dropped.
struct RayHead {
    child: std::process::Child,
    address: String,
    temp: PathBuf,
}

impl RayHead {
    fn start(venv: &Path, log: &Path) -> RayHead {
        use std::os::unix::process::CommandExt;
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let temp = format!("/tmp/ray-objnerf-{}", std::process::id());
        let child = Command::new(venv.join("ray"))
            .args(["start", "--head", "--block", "--node-ip-address=127.0.0.1"])
            .arg(format!("--port={port}"))
            .arg(format!("--temp-dir={temp}"))
            .args(["--num-cpus=2", "--object-store-memory=200000000"])
            .args(["--include-dashboard=false", "--disable-usage-stats"])
            .env("RAY_USAGE_STATS_ENABLED", "0")
            .stdout(std::fs::File::create(log).unwrap())
            .stderr(std::fs::File::create(log.with_extension("err")).unwrap())
            .process_group(0)
            .spawn()
            .unwrap();
        let head = RayHead {
            child,
            address: format!("127.0.0.1:{port}"),
            temp: PathBuf::from(temp),
        };
        let t0 = std::time::Instant::now();
        while !std::fs::read_to_string(log)
            .unwrap_or_default()
            .contains("block forever")
        {
            assert!(
                t0.elapsed().as_secs() < 120,
                "the Ray head did not start: see {}",
                log.display()
            );
            std::thread::sleep(std::time::Duration::from_millis(200));
        }
        head
    }
}

impl Drop for RayHead {
    fn drop(&mut self) {
        let group = -(self.child.id() as i32);
        // SAFETY: signals to the process group this test started.
        unsafe { libc::kill(group, libc::SIGTERM) };
        let _ = self.child.wait();
        std::thread::sleep(std::time::Duration::from_secs(3));
        unsafe { libc::kill(group, libc::SIGKILL) };
        let _ = std::fs::remove_dir_all(&self.temp);
    }
}

/// A JSON file without what depends on the clock or the machine's state: times, rates, peak
/// memory, and SAM encoder runs (the embedding cache was warm for the second run).
fn without_timings(v: &mut Value) {
    match v {
        Value::Object(m) => {
            m.retain(|k, _| {
                !(k.contains("second")
                    || k.contains("peak_rss")
                    || k == "timings"
                    || k.ends_with("encoder_runs"))
            });
            m.values_mut().for_each(without_timings);
        }
        Value::Array(a) => a.iter_mut().for_each(without_timings),
        _ => {}
    }
}

/// A model file's header (timings dropped from its notes) and its arrays, byte for byte.
fn model_parts(path: &Path) -> (Value, Vec<u8>) {
    let b = std::fs::read(path).unwrap();
    let i = b.iter().position(|&c| c == b'{').unwrap();
    let n = u64::from_le_bytes(b[i - 8..i].try_into().unwrap()) as usize;
    let mut header: Value = serde_json::from_slice(&b[i..i + n]).unwrap();
    without_timings(&mut header);
    (header, b[i + n..].to_vec())
}

/// Each job's folder in `a` and `b` holds the same files with the same contents, but for times.
fn same_outputs(a: &Path, b: &Path, ids: &[&str]) {
    for id in ids {
        let (fa, fb) = (files(&a.join(id)), files(&b.join(id)));
        assert_eq!(
            fa.keys().collect::<Vec<_>>(),
            fb.keys().collect::<Vec<_>>(),
            "{id}"
        );
        for rel in fa.keys() {
            let (pa, pb) = (a.join(id).join(rel), b.join(id).join(rel));
            let what = format!("{id}/{}", rel.display());
            match rel.extension().and_then(|e| e.to_str()) {
                Some("json") => {
                    let (mut ja, mut jb) = (read_json(&pa), read_json(&pb));
                    without_timings(&mut ja);
                    without_timings(&mut jb);
                    assert_eq!(ja, jb, "{what}");
                }
                Some("objf") => assert!(model_parts(&pa) == model_parts(&pb), "{what}"),
                _ => assert!(
                    std::fs::read(&pa).unwrap() == std::fs::read(&pb).unwrap(),
                    "{what}"
                ),
            }
        }
    }
}

/// The 8-job manifest through `scripts/ray_batch.py` on a local Ray head (loopback only), with
/// the Ray worker running one job killed while the job is in its second stage: Ray retries the
/// task, the killed attempt's processes end with their worker, every job finishes once, and the
/// outputs are the local run's but for times.
#[test]
#[ignore = "Ray: bash scripts/setup-ray && cargo test --release --test batch -- --ignored (README)"]
fn ray_runs_the_manifest_and_a_killed_worker_is_retried() {
    if !common::sam_installed() {
        return;
    }
    let venv = common::repo_root().join(".venv-ray/bin");
    assert!(
        venv.join("python").is_file(),
        "no .venv-ray: run bash scripts/setup-ray"
    );
    let dir = tempfile::tempdir().unwrap();
    let manifest = eight_job_manifest(dir.path());
    let local = dir.path().join("local");
    assert!(batch(&[&manifest], &["--out", local.to_str().unwrap()])
        .status
        .success());

    let head = RayHead::start(&venv, &dir.path().join("ray_head.log"));
    let out = dir.path().join("ray");
    let t0 = std::time::Instant::now();
    let mut driver = Command::new(venv.join("python"))
        .arg(common::repo_root().join("scripts/ray_batch.py"))
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .args(["--address", &head.address])
        .arg("--objnerf")
        .arg(common::objnerf_bin())
        .env("RAY_USAGE_STATS_ENABLED", "0")
        .spawn()
        .unwrap();

    // The job mug_s1 in its second stage (remove): its supervisor `objnerf batch --job mug_s1`,
    // the stage under it, and the Ray worker above it.
    let out_arg = out.display().to_string();
    let (worker, supervisor, stage) = loop {
        let ps = processes();
        let found = ps.iter().find_map(|(pid, ppid, args)| {
            let sup = args.iter().any(|a| a == "--job")
                && args.iter().any(|a| a == "mug_s1")
                && args.contains(&out_arg);
            let stage = ps
                .iter()
                .find(|(_, parent, a)| parent == pid && a.get(1).is_some_and(|s| s == "remove"));
            (sup && stage.is_some()).then(|| (*ppid, *pid, stage.unwrap().0))
        });
        if let Some(f) = found {
            break f;
        }
        assert!(
            driver.try_wait().unwrap().is_none(),
            "the driver ended before mug_s1 was seen removing"
        );
        assert!(
            t0.elapsed().as_secs() < 600,
            "mug_s1 never reached its remove stage"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let worker_cmd = processes()
        .into_iter()
        .find(|p| p.0 == worker)
        .map(|p| p.2.join(" "));
    println!(
        "killing Ray worker {worker} ({worker_cmd:?}), which runs mug_s1's remove (pid {stage})"
    );
    // SAFETY: a process of the Ray head this test started.
    unsafe { libc::kill(worker, libc::SIGKILL) };
    let killed = std::time::Instant::now();
    while running(supervisor) || running(stage) {
        assert!(
            killed.elapsed().as_secs() < 10,
            "the killed worker's job processes live on (supervisor {supervisor}, stage {stage})"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let status = driver.wait().unwrap();
    println!("ray run: {:.0} s", t0.elapsed().as_secs_f64());
    drop(head);
    assert!(status.success(), "the Ray driver failed");

    let summary = read_json(&out.join("summary.json"));
    assert_eq!(summary["counts"], json!({"ok": 8}), "{summary}");
    check_outputs(&out, &summary);
    // mug_s1 ran again from its first stage after the kill, and once: its log is the retry's.
    let log = std::fs::read_to_string(out.join("logs/mug_s1.log")).unwrap();
    assert_eq!(log.matches("$ objnerf extract").count(), 1, "{log}");
    assert_eq!(log.matches("$ objnerf remove").count(), 1, "{log}");
    let local_summary = read_json(&local.join("summary.json"));
    for (l, r) in local_summary["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(summary["jobs"].as_array().unwrap())
    {
        assert_eq!(l["scores"], r["scores"], "{}", l["id"]);
    }
    let ids: Vec<&str> = summary["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["id"].as_str().unwrap())
        .collect();
    same_outputs(&local, &out, &ids);
}
