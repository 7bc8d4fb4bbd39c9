//! The demo scene: exact tracks, determinism, and truth that agrees with the geometry.

mod common;

use glam::{DVec2, DVec3};
use objnerf::demo::{read_truth, write_demo_scene, DemoOptions, World};
use objnerf::Scene;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

fn small(seed: u64) -> DemoOptions {
    DemoOptions {
        seed,
        views: 12,
        width: 160,
        height: 120,
        ..DemoOptions::default()
    }
}

/// One small scene shared by the tests that only read it.
fn shared_scene() -> &'static Path {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &DIR.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("demo");
        write_demo_scene(&small(7), &out).unwrap();
        (tmp, out)
    })
    .1
}

/// Truth depth in metres from the EXR.
fn read_exr_depth(path: &Path) -> (u32, u32, Vec<f32>) {
    let d = objnerf::scene::io::read_depth(path, 1000.0).unwrap();
    (d.width, d.height, d.metres)
}

#[test]
fn tracks_project_onto_their_features() {
    let out = shared_scene();
    let scene = Scene::load(out).unwrap();
    assert_eq!(scene.images.len(), 12);
    assert!(scene.points.len() > 1000, "{} points", scene.points.len());
    let mut worst: f64 = 0.0;
    let mut n = 0;
    for p in &scene.points {
        assert!(p.track.len() >= 2);
        for t in &p.track {
            let im = &scene.images[t.image];
            let px = scene
                .camera_of(im)
                .project(im.pose.world_to_camera(p.xyz))
                .unwrap();
            worst = worst.max((px - im.features[t.feature].xy).length());
            n += 1;
        }
    }
    eprintln!("{n} observations, worst reprojection {worst:.2e} px");
    assert!(worst < 0.5);
    // Real SIFT leaves features unmatched: so does the demo.
    let unmatched = scene.images[0]
        .features
        .iter()
        .filter(|f| f.point.is_none());
    assert!(unmatched.count() > 0);
}

#[test]
fn pixel_ray_point_pixel_round_trip() {
    let out = shared_scene();
    let scene = Scene::load(out).unwrap();
    let mut worst: f64 = 0.0;
    for im in scene.images.iter().step_by(4) {
        let cam = scene.camera_of(im);
        let stem = im.name.trim_end_matches(".png");
        let (w, h, depth) = read_exr_depth(&out.join(format!("truth/depth/{stem}.exr")));
        for k in 0..200u32 {
            let (col, row) = ((k * 37) % w, (k * 53) % h);
            let z = depth[(row * w + col) as usize] as f64;
            assert!(z > 0.0, "every pixel sees a surface");
            let px = DVec2::new(col as f64 + 0.5, row as f64 + 0.5);
            let p_world = im.pose.c2w_matrix().transform_point3(cam.unproject(px) * z);
            let back = cam.project(im.pose.world_to_camera(p_world)).unwrap();
            worst = worst.max((back - px).length());
        }
    }
    assert!(worst < 1e-4, "round trip off by {worst} px");
}

#[test]
fn truth_depth_at_masks_lies_on_the_objects() {
    let out = shared_scene();
    let scene = Scene::load(out).unwrap();
    let world = World::demo();
    for im in scene.images.iter().step_by(3) {
        let cam = scene.camera_of(im);
        let stem = im.name.trim_end_matches(".png");
        let (w, _, depth) = read_exr_depth(&out.join(format!("truth/depth/{stem}.exr")));
        for obj in &world.objects {
            let mask = image::open(out.join(format!("truth/masks/{}/{}", obj.name, im.name)))
                .unwrap()
                .to_luma8();
            let mut worst: f64 = 0.0;
            for (i, m) in mask.pixels().enumerate() {
                if m[0] == 0 {
                    continue;
                }
                assert_eq!(m[0], 255);
                let (col, row) = (i as u32 % w, i as u32 / w);
                let px = DVec2::new(col as f64 + 0.5, row as f64 + 0.5);
                let z = depth[i] as f64;
                let p = im.pose.c2w_matrix().transform_point3(cam.unproject(px) * z);
                worst = worst.max(obj.distance(p));
            }
            assert!(worst < 1e-3, "{} in {}: {worst} m off", obj.name, im.name);
        }
    }
}

#[test]
fn visibility_truth() {
    let out = shared_scene();
    let truth = read_truth(out).unwrap();
    let names: Vec<&str> = truth.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["mug", "sphere", "box", "torus"]);
    let mut min_any: f64 = 1.0;
    for o in &truth {
        let v0 = o.visible["view_000.png"];
        assert!(v0 > 0.7, "{} is only {v0:.2} visible in view 0", o.name);
        let mask = image::open(out.join(format!("truth/masks/{}/view_000.png", o.name)))
            .unwrap()
            .to_luma8();
        let [x, y] = o.click;
        assert_eq!(
            mask.get_pixel(x as u32, y as u32)[0],
            255,
            "{} click",
            o.name
        );
        for v in o.visible.values() {
            min_any = min_any.min(*v);
        }
        let c = (DVec3::from_array(o.bbox_min) + DVec3::from_array(o.bbox_max)) * 0.5;
        assert!(c.length() < 1.0);
    }
    assert!(min_any < 0.5, "no view occludes any object much: {min_any}");
}

fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(files_under(&p));
        } else {
            out.push(p);
        }
    }
    out.sort();
    out
}

#[test]
fn same_seed_same_bytes_other_seed_differs() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b, c) = (
        tmp.path().join("a"),
        tmp.path().join("b"),
        tmp.path().join("c"),
    );
    let mut opts = small(3);
    opts.views = 6;
    opts.noise_px = 0.7;
    opts.outlier_fraction = 0.05;
    write_demo_scene(&opts, &a).unwrap();
    // Another thread count: the output must not depend on scheduling.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    pool.install(|| write_demo_scene(&opts, &b)).unwrap();
    opts.seed = 4;
    write_demo_scene(&opts, &c).unwrap();
    let fa = files_under(&a);
    assert_eq!(
        fa.iter()
            .map(|p| p.strip_prefix(&a).unwrap())
            .collect::<Vec<_>>(),
        files_under(&b)
            .iter()
            .map(|p| p.strip_prefix(&b).unwrap())
            .collect::<Vec<_>>()
    );
    let mut checked = 0;
    for p in &fa {
        let rel = p.strip_prefix(&a).unwrap();
        let s = rel.to_string_lossy();
        if s.starts_with("images/") || s.starts_with("sparse/") || s.starts_with("truth/") {
            assert_eq!(
                std::fs::read(p).unwrap(),
                std::fs::read(b.join(rel)).unwrap(),
                "{s}"
            );
            checked += 1;
        }
    }
    assert!(checked > 6 * 7);
    for rel in [
        "images/view_000.png",
        "sparse/0/points3D.bin",
        "sparse/0/images.bin",
    ] {
        assert_ne!(
            std::fs::read(a.join(rel)).unwrap(),
            std::fs::read(c.join(rel)).unwrap(),
            "{rel} does not depend on the seed"
        );
    }
}

#[test]
fn bad_options_are_errors_and_leave_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("x");
    for opts in [
        DemoOptions {
            views: 0,
            ..small(1)
        },
        DemoOptions {
            width: 0,
            ..small(1)
        },
        DemoOptions {
            noise_px: f64::NAN,
            ..small(1)
        },
        DemoOptions {
            outlier_fraction: 1.5,
            ..small(1)
        },
    ] {
        let e = write_demo_scene(&opts, &out).unwrap_err();
        assert!(matches!(e, objnerf::Error::Invalid(_)), "{e}");
        assert!(!out.exists());
    }
    assert!(objnerf::demo::parse_size("320x").is_err());
    assert_eq!(objnerf::demo::parse_size("320x240").unwrap(), (320, 240));
}

#[test]
fn cli_writes_a_scene_that_info_reads() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("cli");
    let run = |extra: &[&str]| {
        std::process::Command::new(common::objnerf_bin())
            .args(["demo-scene", "--out"])
            .arg(&out)
            .args(["--views", "4", "--size", "64x48"])
            .args(extra)
            .output()
            .unwrap()
    };
    let r = run(&[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // A second run refuses to replace the folder without --overwrite.
    assert!(!run(&[]).status.success());
    assert!(run(&["--overwrite"]).status.success());
    let bad = std::process::Command::new(common::objnerf_bin())
        .args(["demo-scene", "--views", "0", "--out"])
        .arg(tmp.path().join("bad"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--views"));
    let info = std::process::Command::new(common::objnerf_bin())
        .arg("info")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
}

#[test]
fn outliers_and_noise_are_as_asked() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let opts = DemoOptions {
        views: 6,
        outlier_fraction: 0.1,
        ..small(5)
    };
    write_demo_scene(&opts, &out).unwrap();
    let scene = Scene::load(&out).unwrap();
    let mut bad = 0;
    for p in &scene.points {
        let errs: Vec<f64> = p
            .track
            .iter()
            .map(|t| {
                let im = &scene.images[t.image];
                let px = scene.camera_of(im).project(im.pose.world_to_camera(p.xyz));
                (px.unwrap() - im.features[t.feature].xy).length()
            })
            .collect();
        let mean = errs.iter().sum::<f64>() / errs.len() as f64;
        assert!(
            (mean - p.error).abs() < 1e-9,
            "stored error is the reprojection error"
        );
        // Exactly one wrong observation per outlier point, at least 15 px off; the rest exact.
        let wrong = errs.iter().filter(|&&e| e >= 15.0).count();
        assert!(wrong <= 1 && errs.iter().all(|&e| !(1e-6..15.0).contains(&e)));
        bad += wrong;
    }
    let want = (0.1 * scene.points.len() as f64).round() as usize;
    assert_eq!(bad, want);

    let noisy = tmp.path().join("n");
    write_demo_scene(
        &DemoOptions {
            noise_px: 1.0,
            ..opts.clone()
        },
        &noisy,
    )
    .unwrap();
    let scene = Scene::load(&noisy).unwrap();
    let errs: Vec<f64> = scene.reprojection_errors();
    let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
    // Inliers only: 2D Gaussian with sigma 1 px has RMS length sqrt(2).
    let inl: Vec<f64> = errs.iter().copied().filter(|&e| e < 8.0).collect();
    let rms_in = (inl.iter().map(|e| e * e).sum::<f64>() / inl.len() as f64).sqrt();
    assert!(
        (rms_in - 2f64.sqrt()).abs() < 0.1,
        "inlier RMS {rms_in}, all {rms}"
    );
}

#[test]
fn transforms_json_has_the_colmap_poses() {
    let out = shared_scene();
    let colmap = Scene::load(out).unwrap();
    let ns = Scene::load(&out.join("transforms.json")).unwrap();
    assert_eq!(ns.images.len(), colmap.images.len());
    for im in &colmap.images {
        let other = &ns.images[ns.find_image(&im.name).unwrap()];
        assert!(other.path.is_file());
        let (a, b) = (im.pose.c2w_opencv(), other.pose.c2w_opencv());
        for (ra, rb) in a.iter().zip(&b) {
            for (x, y) in ra.iter().zip(rb) {
                assert!((x - y).abs() < 1e-9, "{}: {a:?} vs {b:?}", im.name);
            }
        }
        let (ca, cb) = (colmap.camera_of(im), ns.camera_of(other));
        assert_eq!((ca.width, ca.height), (cb.width, cb.height));
        for (x, y) in ca.params.iter().zip(&cb.params) {
            assert!((x - y).abs() < 1e-9);
        }
        // Depth comes along as the truth millimetre PNGs.
        let depth = other.depth_path.as_ref().expect("depth_file_path");
        let d = objnerf::scene::io::read_depth(depth, ns.depth_scale).unwrap();
        assert_eq!((d.width, d.height), (ca.width, ca.height));
    }
}

/// A reader that closes the pipe early (`objnerf info ... | head -1`) ends the command quietly,
/// by SIGPIPE as other command-line tools end, not with a panic.
#[test]
fn a_closed_stdout_pipe_ends_the_command_without_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::{Command, Stdio};
    let mut child = Command::new(common::objnerf_bin())
        .args(["info", "--json"])
        .arg(shared_scene())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        out.status.success() || out.status.signal() == Some(libc::SIGPIPE),
        "{:?}: {stderr}",
        out.status
    );
}
