//! The 8-job manifest of the batch tests (`tests/batch.rs` runs it here, `tests/batch_ray.rs`
//! on Ray) and the checks of what its jobs wrote.
#![allow(dead_code)]

use objnerf::demo::{read_truth, write_demo_scene, DemoOptions};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::SystemTime;

/// Small and fast, as the other tests on the demo scene: 8 views at 160x120, step budgets (the
/// same result on any machine and at any load).
pub fn extract_options(seed: u64) -> Value {
    json!({"steps": 200, "time-budget": "none", "frames": 2, "seed": seed})
}

pub fn remove_options() -> Value {
    json!({"steps": 50, "time-budget": "none", "downscale": 2})
}

/// The box around `object`'s true mask in `view`, grown by 4 pixels.
pub fn true_box(scene: &Path, object: &str, view: &str) -> [f64; 4] {
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
pub fn eight_job_manifest(dir: &Path) -> PathBuf {
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
    let jobs = [
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

pub fn batch(args: &[&Path], extra: &[&str]) -> Output {
    let out = Command::new(crate::common::objnerf_bin())
        .arg("batch")
        .args(args)
        .args(extra)
        .output()
        .unwrap();
    println!("{}", String::from_utf8_lossy(&out.stdout));
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    out
}

pub fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// Every file under `dir` (relative path) with its size and modification time.
pub fn files(dir: &Path) -> BTreeMap<PathBuf, (u64, SystemTime)> {
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
pub fn glb_meshes(path: &Path) -> Vec<String> {
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
pub fn check_outputs(out: &Path, summary: &Value) {
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
