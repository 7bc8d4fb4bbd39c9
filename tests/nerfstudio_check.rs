//! nerfstudio's own code on objnerf's exports and camera paths: its `NerfstudioDataParserConfig`
//! must see our cameras (camera-to-world, intrinsics, distortion, sizes), our image, mask and
//! depth files and our points, to 1e-5 (relative above 1); `get_path_from_json` must see our
//! paths, in the data frame and in the viewer's; nerfacto trains a few steps on CPU on the mug.
//!
//! Ignored: it needs nerfstudio (a venv of about 8 GB) and runs of the demo and fox.
//! `scripts/check-nerfstudio` makes them and runs this with OBJNERF_NERFSTUDIO_PYTHON set.

mod common;

use glam::DVec3;
use objnerf::export::nerfstudio::{export, ExportOptions};
use objnerf::scene::camera_path::{CameraPath, DataparserTransform, Orbit, PathFrame};
use objnerf::scene::io::{read_depth, read_mask};
use objnerf::scene::{Camera, CameraModel, Scene};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

fn python() -> PathBuf {
    std::env::var_os("OBJNERF_NERFSTUDIO_PYTHON")
        .map(PathBuf::from)
        .expect("set OBJNERF_NERFSTUDIO_PYTHON to a python with nerfstudio: run scripts/check-nerfstudio")
}

fn runs() -> PathBuf {
    std::env::var_os("OBJNERF_NS_RUNS")
        .map(PathBuf::from)
        .unwrap_or_else(|| common::repo_root().join("runs"))
}

/// Run `tests/nerfstudio/<script>` with nerfstudio's python; panics with its output on failure.
fn run_python(script: &str, args: &[&Path]) -> String {
    let out = std::process::Command::new(python())
        .arg(common::repo_root().join("tests/nerfstudio").join(script))
        .args(args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{script}: {text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// Run the jobs through tests/nerfstudio/ns_check.py and return its results.
fn nerfstudio_sees(jobs: Vec<Value>, tmp: &Path) -> Vec<Value> {
    let (jobs_file, results) = (tmp.join("jobs.json"), tmp.join("results.json"));
    std::fs::write(&jobs_file, json!({ "jobs": jobs }).to_string()).unwrap();
    run_python("ns_check.py", &[&jobs_file, &results]);
    let v: Value = serde_json::from_str(&std::fs::read_to_string(results).unwrap()).unwrap();
    v["results"].as_array().unwrap().clone()
}

/// Asserts nerfstudio's `a` is objnerf's `b` to 1e-5 (relative above 1); returns |a - b|.
fn close(a: f64, b: f64, what: &str) -> f64 {
    assert!(
        (a - b).abs() <= 1e-5 * b.abs().max(1.0),
        "{what}: nerfstudio {a}, objnerf {b}"
    );
    (a - b).abs()
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// nerfstudio's distortion vector (k1, k2, k3, k4, p1, p2) for our camera.
fn distortion(cam: &Camera) -> [f64; 6] {
    let p = &cam.params;
    match cam.model {
        CameraModel::SimplePinhole | CameraModel::Pinhole => [0.0; 6],
        CameraModel::OpenCv => [p[4], p[5], 0.0, 0.0, p[6], p[7]],
        m => panic!("no shared capture uses {m:?}"),
    }
}

/// One expected frame: what objnerf meant to export for a view.
struct Expected {
    file: PathBuf,
    c2w_gl: [[f64; 4]; 3],
    camera: Camera,
    mask_kept: Option<u64>,
    depth_sum_m: Option<f64>,
}

/// A dataset to export and what nerfstudio must see in it.
struct Case {
    name: &'static str,
    out: PathBuf,
    frames: Vec<Expected>,
    points: Vec<DVec3>,
}

/// The views an export should hold, from the source scene and the segment report (read here,
/// independently of the exporter).
fn expected_frames(
    scene: &Scene,
    out: &Path,
    run: Option<(&Value, bool)>,
    factor: u32,
) -> Vec<Expected> {
    let mut frames = Vec::new();
    for im in &scene.images {
        let stem = Path::new(&im.name).with_extension("");
        let stem = stem.strip_prefix("images").unwrap_or(&stem).to_path_buf();
        let status = run.map(|(obj, _)| {
            obj["views"]
                .as_array()
                .unwrap()
                .iter()
                .find(|v| v["view"] == im.name.as_str())
                .map(|v| v["status"].as_str().unwrap().to_string())
                .unwrap_or_default()
        });
        let background = run.is_some_and(|(_, bg)| bg);
        if status.as_deref().is_some_and(|s| s != "ok") && !background {
            continue;
        }
        let mask_kept = run.map(|(obj, bg)| {
            let seg = obj["_dir"].as_str().unwrap();
            // objnerf segment's mask names: the image name, extension off, folders joined by _.
            let flat = Path::new(&im.name)
                .with_extension("")
                .to_string_lossy()
                .replace('/', "_");
            let file = format!("{seg}/masks/{}/{flat}.png", obj["name"].as_str().unwrap());
            let on = if Path::new(&file).is_file() {
                read_mask(Path::new(&file))
                    .unwrap()
                    .pixels()
                    .filter(|p| p.0[0] > 127)
                    .count() as u64
            } else {
                0
            };
            let cam = scene.camera_of(im);
            if bg {
                (cam.width * cam.height) as u64 - on
            } else {
                on
            }
        });
        let depth_sum_m = im.depth_path.as_ref().map(|p| {
            let d = read_depth(p, scene.depth_scale).unwrap();
            d.metres
                .iter()
                .map(|&m| {
                    if m > 0.0 {
                        (m as f64 * 1000.0).round() / 1000.0
                    } else {
                        0.0
                    }
                })
                .sum()
        });
        let ext = if factor > 1 {
            "png".to_string()
        } else {
            Path::new(&im.name)
                .extension()
                .unwrap()
                .to_string_lossy()
                .to_string()
        };
        frames.push(Expected {
            file: out.join("images").join(stem.with_extension(ext)),
            c2w_gl: im.pose.c2w_opengl(),
            camera: scene.camera_of(im).downscaled(factor),
            mask_kept,
            depth_sum_m,
        });
    }
    frames
}

fn check_dataset(case: &Case, seen: &Value, mode: &str) {
    let what = |k: &str, i: usize| format!("{} ({mode}) frame {i} {k}", case.name);
    let files: Vec<&str> = seen["image_filenames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(files.len(), case.frames.len(), "{}: frame count", case.name);
    let masks = seen["mask_filenames"].as_array().unwrap();
    let depths = seen["depth_filenames"].as_array().unwrap();
    let (mut worst_pose, mut worst_k) = (0.0f64, 0.0f64);
    for (i, f) in files.iter().enumerate() {
        let e = case
            .frames
            .iter()
            .find(|e| e.file == Path::new(f))
            .unwrap_or_else(|| panic!("{}: nerfstudio lists {f}, not one of ours", case.name));
        for r in 0..3 {
            for c in 0..4 {
                worst_pose = worst_pose.max(close(
                    seen["c2w"][i][r][c].as_f64().unwrap(),
                    e.c2w_gl[r][c],
                    &what("c2w", i),
                ));
            }
        }
        let (fx, fy) = e.camera.focal();
        let (cx, cy) = e.camera.principal_point();
        for (k, want) in [("fx", fx), ("fy", fy), ("cx", cx), ("cy", cy)] {
            worst_k = worst_k.max(close(seen[k][i].as_f64().unwrap(), want, &what(k, i)));
        }
        assert_eq!(
            seen["width"][i].as_u64(),
            Some(e.camera.width as u64),
            "{}",
            what("width", i)
        );
        assert_eq!(
            seen["height"][i].as_u64(),
            Some(e.camera.height as u64),
            "{}",
            what("height", i)
        );
        for (a, b) in f64s(&seen["distortion"][i])
            .iter()
            .zip(distortion(&e.camera))
        {
            close(*a, b, &what("distortion", i));
        }
        let stem = e
            .file
            .strip_prefix(&case.out)
            .unwrap()
            .strip_prefix("images")
            .unwrap()
            .with_extension("png");
        match e.mask_kept {
            Some(kept) => {
                assert_eq!(
                    masks[i].as_str().map(PathBuf::from),
                    Some(case.out.join("masks").join(&stem))
                );
                assert_eq!(
                    seen["mask_kept"][i].as_u64(),
                    Some(kept),
                    "{}",
                    what("mask pixels", i)
                );
            }
            None => assert!(masks.is_empty()),
        }
        match e.depth_sum_m {
            Some(sum) => {
                assert_eq!(
                    depths[i].as_str().map(PathBuf::from),
                    Some(case.out.join("depth").join(&stem))
                );
                close(
                    seen["depth_sum_m"][i].as_f64().unwrap(),
                    sum,
                    &what("depth sum", i),
                );
            }
            None => assert!(depths.is_empty()),
        }
    }
    assert_eq!(
        seen["points"].as_u64(),
        Some(case.points.len() as u64),
        "{}: points",
        case.name
    );
    if mode == "raw" && !case.points.is_empty() {
        let mean = case.points.iter().sum::<DVec3>() / case.points.len() as f64;
        for (a, b) in f64s(&seen["points_mean"]).iter().zip(mean.to_array()) {
            close(*a, b, &format!("{}: mean point", case.name));
        }
    }
    println!(
        "{} ({mode}): nerfstudio sees our {} frames, {} masks, {} depth maps, {} points; max |c2w diff| {worst_pose:.1e}, max |intrinsic diff| {worst_k:.1e} px",
        case.name,
        files.len(),
        masks.len(),
        depths.len(),
        case.points.len()
    );
}

/// Export `input` into `tmp/name` and describe what nerfstudio must see.
fn export_case(name: &'static str, input: &Path, opts: ExportOptions, tmp: &Path) -> Case {
    let out = tmp.join(name);
    let report = export(input, &out, &opts).unwrap();
    println!("{name}: {}", report.summary().replace('\n', "\n    "));
    let run = objnerf::segment::saved::SegmentRun::find(input);
    let (scene, points, frames) = match run {
        None => {
            let scene = Scene::load(input).unwrap();
            let pts = scene.points.iter().map(|p| p.xyz).collect();
            let frames = expected_frames(&scene, &out, None, opts.downscale);
            (scene, pts, frames)
        }
        Some(dir) => {
            let mut report: Value =
                serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap())
                    .unwrap();
            let scene = objnerf::segment::saved::SegmentRun::open(&dir)
                .unwrap()
                .scene;
            let obj = &mut report["objects"][0];
            obj["_dir"] = json!(dir);
            let ply = dir.join(format!("{}_points.ply", obj["name"].as_str().unwrap()));
            let object: Vec<DVec3> = objnerf::scene::formats::ply::read_points(&ply)
                .unwrap()
                .into_iter()
                .map(|p| p.0)
                .collect();
            let key = |p: DVec3| p.as_vec3().to_array().map(f32::to_bits);
            let taken: std::collections::HashSet<_> = object.iter().map(|&p| key(p)).collect();
            let pts = if opts.background {
                scene
                    .points
                    .iter()
                    .map(|p| p.xyz)
                    .filter(|&p| !taken.contains(&key(p)))
                    .collect()
            } else {
                object
            };
            let frames =
                expected_frames(&scene, &out, Some((obj, opts.background)), opts.downscale);
            (scene, pts, frames)
        }
    };
    assert!(!scene.images.is_empty());
    Case {
        name,
        out,
        frames,
        points,
    }
}

fn dataset_job(case: &Case, mode: &str, save: Option<&Path>) -> Value {
    json!({"kind": "dataset", "data": case.out, "mode": mode, "save_transform": save})
}

fn check_path(name: &str, ours: &CameraPath, seen: &Value) {
    let n = ours.cameras.len();
    let mut worst = 0.0f64;
    assert_eq!(seen["c2w"].as_array().unwrap().len(), n, "{name}");
    for (i, c) in ours.cameras.iter().enumerate() {
        let m = c.pose.c2w_opengl();
        for r in 0..3 {
            for k in 0..4 {
                worst = worst.max(close(
                    seen["c2w"][i][r][k].as_f64().unwrap(),
                    m[r][k],
                    &format!("{name} camera {i} c2w"),
                ));
            }
        }
        let (f, _) = c.camera.focal();
        close(seen["fx"][i].as_f64().unwrap(), f, &format!("{name} fx"));
        close(seen["fy"][i].as_f64().unwrap(), f, &format!("{name} fy"));
        close(
            seen["cx"][i].as_f64().unwrap(),
            ours.width as f64 / 2.0,
            "cx",
        );
        close(
            seen["cy"][i].as_f64().unwrap(),
            ours.height as f64 / 2.0,
            "cy",
        );
        assert_eq!(seen["width"][i].as_u64(), Some(ours.width as u64));
        assert_eq!(seen["height"][i].as_u64(), Some(ours.height as u64));
    }
    println!("{name}: get_path_from_json sees our {n} cameras; max |c2w diff| {worst:.1e}");
}

#[test]
#[ignore = "needs nerfstudio: run scripts/check-nerfstudio"]
fn nerfstudio_loads_our_exports_and_paths() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let runs = runs();
    let one = ExportOptions {
        downscale: 1,
        ..Default::default()
    };
    let mut cases = vec![
        export_case("mug", &runs.join("ns_demo/run"), one.clone(), t),
        export_case(
            "demo_scene_depth",
            &runs.join("ns_demo/scene/transforms.json"),
            one.clone(),
            t,
        ),
    ];
    if let Some(fox) = common::shared_data("fox").map(|_| runs.join("fox_seg")) {
        cases.push(export_case(
            "fox_background",
            &fox,
            ExportOptions {
                background: true,
                ..one.clone()
            },
            t,
        ));
    }
    if let Some(lego) = common::shared_data("lego") {
        cases.push(export_case(
            "lego_downscale2",
            &lego.join("transforms_train.json"),
            ExportOptions {
                downscale: 2,
                ..one.clone()
            },
            t,
        ));
    }
    let dpt = t.join("mug_dataparser_transforms.json");
    let mut jobs = vec![dataset_job(&cases[0], "default", Some(&dpt))];
    jobs.extend(cases.iter().map(|c| dataset_job(c, "raw", None)));
    jobs.extend(
        cases
            .iter()
            .skip(2)
            .map(|c| dataset_job(c, "default", None)),
    );
    let seen = nerfstudio_sees(jobs, t);
    check_dataset(&cases[0], &seen[0], "default");
    for (c, s) in cases.iter().zip(&seen[1..]) {
        check_dataset(c, s, "raw");
    }
    for (c, s) in cases.iter().skip(2).zip(&seen[1 + cases.len()..]) {
        check_dataset(c, s, "default");
    }
    check_camera_paths(&runs, &dpt, t);
    smoke_train(&cases[0].out, t);
}

/// Our paths through get_path_from_json: an orbit round the mug and the demo's views in the data
/// frame, and the orbit in the viewer frame of nerfstudio's own dataparser transform for the mug.
fn check_camera_paths(runs: &Path, dpt: &Path, t: &Path) {
    let orbit = CameraPath::orbit(&Orbit {
        center: DVec3::new(-0.42, 0.32, 0.1),
        radius: 1.2,
        elevation: 0.6,
        up: DVec3::Z,
        views: 24,
        fov_y_deg: 40.0,
        width: 320,
        height: 240,
        fps: 24.0,
    })
    .unwrap();
    let views = CameraPath::from_scene_views(
        &Scene::load(&runs.join("ns_demo/scene/transforms.json")).unwrap(),
        10.0,
    )
    .unwrap();
    let viewer = PathFrame::Viewer(DataparserTransform::read(dpt, None).unwrap());
    let files = [
        t.join("orbit.json"),
        t.join("views.json"),
        t.join("orbit_viewer.json"),
    ];
    orbit.write(&files[0], &PathFrame::Data).unwrap();
    views.write(&files[1], &PathFrame::Data).unwrap();
    orbit.write(&files[2], &viewer).unwrap();
    let jobs = vec![
        json!({"kind": "path", "file": files[0]}),
        json!({"kind": "path", "file": files[1]}),
        json!({"kind": "path", "file": files[2], "to_original": dpt}),
    ];
    let seen = nerfstudio_sees(jobs, t);
    check_path("orbit (data frame)", &orbit, &seen[0]);
    check_path("demo views (data frame)", &views, &seen[1]);
    check_path(
        "orbit (viewer frame, nerfstudio's transform undone by nerfstudio)",
        &orbit,
        &seen[2],
    );
}

fn smoke_train(data: &Path, t: &Path) {
    let steps = std::env::var("OBJNERF_NS_STEPS").unwrap_or_else(|_| "10".into());
    let out = run_python(
        "ns_train_smoke.py",
        &[data, &t.join("train"), Path::new(&steps)],
    );
    println!("{}", out.trim_end());
}
