//! Object removal and scene fields (issue 14): the space each capture layout gets, the demo's
//! forward-facing layout and removal truth, `objnerf remove`'s errors; and (ignored, slow: see
//! the README) removals, scene fields and a forward-facing extract scored against the truth.

mod common;

use objnerf::demo::{read_truth, write_demo_scene, DemoLayout, DemoOptions};
use objnerf::space::layout::choose_space;
use objnerf::space::SpaceChoice;
use objnerf::Scene;
use std::path::{Path, PathBuf};
use std::process::Command;

fn demo(dir: &Path, layout: DemoLayout, views: usize) -> PathBuf {
    let out = dir.join(format!("demo_{layout}"));
    let opts = DemoOptions {
        views,
        layout,
        ..Default::default()
    };
    write_demo_scene(&opts, &out).unwrap();
    out
}

/// Turntables show the sides the photos saw: all the way round the ring demo's mug; on the
/// forward demo, a sweep whose every frame looks from within the cameras' span of directions
/// (before, a forward capture's turntable spent most frames on sides no photo saw), at their
/// elevation.
#[test]
fn turntables_follow_the_cameras_of_each_layout() {
    use glam::DVec3;
    use objnerf::render::{turntable_views, Orbit, TurntableOptions};
    let dir = tempfile::tempdir().unwrap();
    for layout in [DemoLayout::Ring, DemoLayout::Forward] {
        let path = demo(dir.path(), layout, 12);
        let scene = Scene::load(&path).unwrap();
        let truth = read_truth(&path).unwrap();
        let mug = truth.iter().find(|t| t.name == "mug").unwrap();
        let (lo, hi) = (
            DVec3::from_array(mug.bbox_min),
            DVec3::from_array(mug.bbox_max),
        );
        let centre = 0.5 * (lo + hi);
        let (up, _) = scene.up();
        let cameras: Vec<DVec3> = scene.images.iter().map(|im| im.pose.center()).collect();
        let orbit = Orbit::following(centre, up, &cameras, None);
        // Directions about up, as angles from the cameras' mean direction (no wrap for a
        // forward capture, whose cameras all face one side).
        let flat = |c: DVec3| {
            let d = c - centre;
            (d - up * d.dot(up)).normalize()
        };
        let mean = cameras.iter().map(|c| flat(*c)).sum::<DVec3>().normalize();
        let angle = |c: DVec3| {
            let d = flat(c);
            up.dot(mean.cross(d)).atan2(mean.dot(d)).to_degrees()
        };
        let spans = cameras.iter().map(|c| angle(*c));
        let (min, max) = spans.fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
        let views = turntable_views(lo, hi, up, &orbit, &TurntableOptions::default());
        println!("{layout}: {orbit:?}, cameras {min:.1}..{max:.1} deg");
        match layout {
            DemoLayout::Ring => assert_eq!(orbit.arc_deg, 360.0, "{orbit:?}"),
            _ => {
                assert!(orbit.arc_deg < 180.0, "{orbit:?}");
                for v in &views {
                    let a = angle(v.pose.center());
                    assert!(
                        (min - 1e-6..=max + 1e-6).contains(&a),
                        "{} looks from {a:.1} deg, outside the cameras' {min:.1}..{max:.1}",
                        v.name
                    );
                }
            }
        }
        let elevations: Vec<f64> = cameras
            .iter()
            .map(|c| (*c - centre).normalize().dot(up).asin().to_degrees())
            .collect();
        let (lo_e, hi_e) = elevations
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        assert!(
            (lo_e..=hi_e).contains(&orbit.elevation_deg),
            "{layout}: elevation {} outside the cameras' {lo_e:.1}..{hi_e:.1}",
            orbit.elevation_deg
        );
    }
}

/// `--space auto` picks box for the ring demo, forward for the forward-facing demo (COLMAP and
/// its LLFF file alike), unbounded for fox (a room, every camera facing the wall).
#[test]
fn each_layout_gets_its_space() {
    let dir = tempfile::tempdir().unwrap();
    let ring = demo(dir.path(), DemoLayout::Ring, 12);
    let fwd = demo(dir.path(), DemoLayout::Forward, 12);
    let pick = |p: &Path| {
        let s = choose_space(&Scene::load(p).unwrap(), SpaceChoice::Auto, 1).unwrap();
        (s.space.name(), s.why)
    };
    let (name, why) = pick(&ring);
    assert_eq!(name, "box", "{why}");
    let (name, why) = pick(&fwd);
    assert_eq!(name, "forward", "{why}");
    let (name, why) = pick(&fwd.join("poses_bounds.npy"));
    assert_eq!(name, "forward", "LLFF: {why}");
    if let Some(fox) = common::shared_data("fox") {
        let (name, why) = pick(&fox.join("transforms.json"));
        assert_eq!(name, "unbounded", "fox: {why}");
        println!("fox: {why}");
    }
}

/// `scene` with its cameras alone: no tracked points, depth images or depth bounds.
fn poses_alone(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    s.points.clear();
    for im in &mut s.images {
        im.features.clear();
        im.depth_path = None;
        im.depth_bounds = None;
    }
    s
}

/// A capture with poses alone (no tracked points, depth images or bounds) still keeps its grid
/// clear near the cameras: half the way to the cameras' focus (without it fox from
/// `transforms.json` grew fog in front of its cameras, held out 11.7 dB;
/// examples/results/scene_field.md).
#[test]
fn a_capture_with_poses_alone_has_a_near_clip() {
    let dir = tempfile::tempdir().unwrap();
    let ring = demo(dir.path(), DemoLayout::Ring, 12);
    let with_points = Scene::load(&ring).unwrap();
    let poses_alone = poses_alone(&with_points);
    let clip = |s: &Scene| choose_space(s, SpaceChoice::Auto, 1).unwrap().near_clip;
    let (a, b) = (clip(&with_points), clip(&poses_alone));
    assert!(a > 0.0, "near clip from the points: {a}");
    // The ring's cameras stand ~2 m from the objects at its centre.
    assert!(b > 0.3 && b < 1.5, "near clip from the cameras' focus: {b}");
    if let Some(fox) = common::shared_data("fox") {
        let s = Scene::load(&fox.join("transforms.json")).unwrap();
        assert!(s.points.is_empty());
        assert!(clip(&s) > 0.0, "fox from transforms.json");
    }
}

/// A capture with poses alone still gets stereo depth (swept around the depth its cameras look
/// at, there being no points or bounds to say where), and it is right: the ring demo stripped of
/// its points, depth images and bounds, against its exact depth.
#[test]
fn a_capture_with_poses_alone_gets_stereo_depth() {
    use objnerf::field::{load_views, MaskSource};
    use objnerf::supervision::{add_depth_targets, DepthMode};
    let dir = tempfile::tempdir().unwrap();
    let ring = demo(dir.path(), DemoLayout::Ring, 12);
    let poses_alone = poses_alone(&Scene::load(&ring).unwrap());
    // The same cameras from the demo's transforms.json, which names the exact depth images.
    let with_depth = Scene::load(&ring.join("transforms.json")).unwrap();
    let mut truth = load_views(&with_depth, &MaskSource::Opaque, 2).unwrap();
    add_depth_targets(&mut truth, &with_depth, DepthMode::Dense, 2).unwrap();
    let mut stereo = load_views(&poses_alone, &MaskSource::Opaque, 2).unwrap();
    let n = add_depth_targets(&mut stereo, &poses_alone, DepthMode::Stereo, 2).unwrap();
    let (mut close, mut total) = (0usize, 0usize);
    for (s, t) in stereo.iter().zip(&truth) {
        assert!(t.name.ends_with(&s.name), "{} / {}", s.name, t.name);
        let (Some(sd), Some(td)) = (&s.depth, &t.depth) else {
            continue;
        };
        for (a, b) in sd.iter().zip(td) {
            if *a > 0.0 && *b > 0.0 {
                total += 1;
                close += usize::from((a - b).abs() <= 0.02 * b);
            }
        }
    }
    let pixels: usize = stereo.iter().map(|v| (v.width * v.height) as usize).sum();
    let share = close as f64 / total.max(1) as f64;
    println!(
        "stereo targets {n} of {pixels} pixels; within 2% of the true depth: {:.1}%",
        100.0 * share
    );
    // Before, none (no range to sweep); 12 views 30 degrees apart leave few pixels that two
    // neighbours see alike, so the share is small here and larger on denser captures.
    assert!(n * 100 >= pixels, "stereo depth on {n} of {pixels} pixels");
    assert!(share >= 0.9, "{:.1}% within 2% of the truth", 100.0 * share);
}

/// The forward-facing demo's LLFF `poses_bounds.npy` gives the COLMAP model's cameras, every
/// camera faces the scene, and its bounds enclose what the views see.
#[test]
fn forward_demo_writes_llff_poses_of_the_same_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let fwd = demo(dir.path(), DemoLayout::Forward, 10);
    let colmap = Scene::load(&fwd).unwrap();
    let llff = Scene::load(&fwd.join("poses_bounds.npy")).unwrap();
    assert_eq!(colmap.images.len(), llff.images.len());
    for (a, b) in colmap.images.iter().zip(&llff.images) {
        assert_eq!(a.name, b.name);
        let (ma, mb) = (a.pose.c2w_matrix(), b.pose.c2w_matrix());
        assert!(ma.abs_diff_eq(mb, 1e-9), "{}: {ma:?} vs {mb:?}", a.name);
        assert_eq!(colmap.camera_of(a), llff.camera_of(b));
        // Facing +y (towards the scene), within 30 degrees.
        let axis = a.pose.camera_to_world_dir(glam::DVec3::Z);
        assert!(
            axis.y > 30f64.to_radians().cos() * axis.length() * 0.9,
            "{axis:?}"
        );
    }
    let (_, bounds) =
        objnerf::scene::formats::llff::read_npy_f64(&fwd.join("poses_bounds.npy")).unwrap();
    for row in bounds.chunks(17) {
        assert!(
            row[15] > 0.5 && row[16] > row[15] && row[16] < 10.0,
            "bounds {:?}",
            &row[15..]
        );
    }
}

/// An LLFF capture is its poses and bounds alone (no sparse model): a scene field still trains
/// on it at the defaults, its NDC near plane and its stereo depth ranges from the bounds, and
/// it is coloured by a network ([`objnerf::field::session::scene_net_default`]).
#[test]
fn llff_poses_alone_train_a_scene_field() {
    let dir = tempfile::tempdir().unwrap();
    let fwd = demo(dir.path(), DemoLayout::Forward, 10);
    let llff = Scene::load(&fwd.join("poses_bounds.npy")).unwrap();
    assert!(llff.points.is_empty());
    let mut opts = objnerf::fit::SceneFitOptions::default();
    opts.fit.downscale = 4;
    opts.fit.steps = 20;
    let mut fit = objnerf::fit::SceneFit::new(&llff, &opts).unwrap();
    assert!(
        fit.space_choice().contains("forward") && fit.space_choice().contains("depth bound"),
        "{}",
        fit.space_choice()
    );
    fit.train(&opts.fit.stop_rule(), &mut |_| {});
    let fitted = fit.finish();
    let report = fitted.report;
    assert!(report.depth_targets > 0, "no stereo depth without points");
    assert_eq!(report.run.steps, 20);
    // A forward capture's default colour: a network of 9 features (SH on a ring).
    let net = fitted.trainer.field.net.map_or(0, |n| n.features);
    assert_eq!(net, 9, "forward capture's colour network features");
}

/// A scene field asked for a colour network (`--colour-net N` with `--scene-field`) is coloured
/// by one of N features and trains; asked for 0 the ring (box space) takes SH colour.
#[test]
fn a_scene_field_takes_a_colour_network_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let ring = Scene::load(&demo(dir.path(), DemoLayout::Ring, 6)).unwrap();
    for features in [0, 4] {
        let mut opts = objnerf::fit::SceneFitOptions::default();
        opts.fit.downscale = 4;
        opts.fit.steps = 20;
        opts.fit.setup.scene_net_features = Some(features);
        let mut fit = objnerf::fit::SceneFit::new(&ring, &opts).unwrap();
        let stats = fit.train(&opts.fit.stop_rule(), &mut |_| {});
        assert_eq!(stats.steps, 20);
        let net = fit.finish().trainer.field.net;
        assert_eq!(net.map_or(0, |n| n.features), features);
    }
}

/// `truth/removed/mug` is the photo wherever the mug is not seen, and differs where it is;
/// the pair folders exist.
#[test]
fn removal_truth_differs_from_the_photo_only_around_the_object() {
    let dir = tempfile::tempdir().unwrap();
    let ring = demo(dir.path(), DemoLayout::Ring, 6);
    assert!(ring.join("truth/removed/mug+torus").is_dir());
    for v in 0..6 {
        let name = format!("view_{v:03}.png");
        let photo = image::open(ring.join("images").join(&name))
            .unwrap()
            .to_rgb8();
        let removed = image::open(ring.join("truth/removed/mug").join(&name))
            .unwrap()
            .to_rgb8();
        let mask = objnerf::util::mask::dilate(
            &objnerf::scene::io::read_mask(&ring.join("truth/masks/mug").join(&name)).unwrap(),
            1,
        );
        let (mut inside_changed, mut inside) = (0, 0);
        for ((p, q), m) in photo.pixels().zip(removed.pixels()).zip(mask.pixels()) {
            if m.0[0] > 127 {
                inside += 1;
                inside_changed += (p != q) as usize;
            } else {
                assert_eq!(p, q, "{name}: a pixel away from the mug changed");
            }
        }
        assert!(
            inside == 0 || inside_changed * 2 > inside,
            "{name}: only {inside_changed} of the mug's {inside} pixels changed"
        );
    }
}

/// A hand-made segment run of `scene` with the mug's true masks (what `objnerf segment`
/// writes: report.json naming the scene and each view's status, masks/<object>/).
fn fake_segment_run(scene: &Path, out: &Path, mask_size: Option<(u32, u32)>) -> PathBuf {
    let s = Scene::load(scene).unwrap();
    let views: Vec<serde_json::Value> = s
        .images
        .iter()
        .map(|im| serde_json::json!({"view": im.name, "status": "ok"}))
        .collect();
    let report = serde_json::json!({"scene": scene, "objects": [{"name": "mug", "views": views}]});
    std::fs::create_dir_all(out.join("masks/mug")).unwrap();
    std::fs::write(out.join("report.json"), report.to_string()).unwrap();
    for im in &s.images {
        let mut m = image::open(scene.join("truth/masks/mug").join(&im.name))
            .unwrap()
            .to_luma8();
        if let Some((w, h)) = mask_size {
            m = image::imageops::resize(&m, w, h, image::imageops::FilterType::Nearest);
        }
        m.save(out.join("masks/mug").join(&im.name)).unwrap();
    }
    out.to_path_buf()
}

fn remove_cmd(scene: &Path, seg: &Path, objects: &[&str], out: &Path) -> std::process::Output {
    let mut cmd = Command::new(common::objnerf_bin());
    cmd.arg("remove").arg(scene).arg("--segment").arg(seg);
    for o in objects {
        cmd.args(["--object", o]);
    }
    cmd.arg("--out")
        .arg(out)
        .args(["--steps", "50", "--time-budget", "1000"]);
    cmd.output().unwrap()
}

/// Bad requests are errors naming the file and the problem, and write nothing.
#[test]
fn bad_removals_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let ring = demo(dir.path(), DemoLayout::Ring, 6);
    let seg = fake_segment_run(&ring, &dir.path().join("seg"), None);
    let out = dir.path().join("out");
    let check = |o: std::process::Output, want: &[&str]| {
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert_eq!(o.status.code(), Some(1), "{err}");
        for w in want {
            assert!(err.contains(w), "'{w}' not in: {err}");
        }
        assert!(!out.exists(), "something was written");
    };
    // An object the run does not hold.
    check(
        remove_cmd(&ring, &seg, &["teapot"], &out),
        &["report.json", "no object 'teapot'", "mug"],
    );
    // Masks of another size than the images.
    let small = fake_segment_run(&ring, &dir.path().join("small"), Some((100, 80)));
    check(
        remove_cmd(&ring, &small, &["mug"], &out),
        &["view_000.png", "mask is 100x80", "320x240"],
    );
    // A removal that leaves a view no pixel.
    let full = dir.path().join("full");
    fake_segment_run(&ring, &full, None);
    image::GrayImage::from_pixel(320, 240, image::Luma([255]))
        .save(full.join("masks/mug/view_002.png"))
        .unwrap();
    check(
        remove_cmd(&ring, &full, &["mug"], &out),
        &["view_002.png", "cover every pixel"],
    );
    // A segmentation of another scene.
    let other = demo(&dir.path().join("other"), DemoLayout::Ring, 5);
    check(
        remove_cmd(&other, &seg, &["mug"], &out),
        &["report.json", "not on"],
    );
}

/// The click on `object` suggested by the demo's truth, as `--point X,Y`.
fn click(scene: &Path, object: &str) -> (String, String) {
    let t = read_truth(scene).unwrap();
    let o = t.iter().find(|o| o.name == object).unwrap();
    (o.view.clone(), format!("{},{}", o.click[0], o.click[1]))
}

/// `objnerf segment` from one click on each of `objects` (SAM must be installed).
fn segment(scene: &Path, objects: &[&str], out: &Path) {
    let mut args: Vec<String> = vec!["segment".into(), scene.display().to_string()];
    for o in objects {
        let (view, point) = click(scene, o);
        args.extend([
            "--view".into(),
            view,
            "--object".into(),
            o.to_string(),
            "--point".into(),
            point,
        ]);
    }
    args.extend(["--out".into(), out.display().to_string()]);
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    common::objnerf_ok(&a);
}

/// `objnerf remove` with every 6th view held out; its report.
fn remove_and_score(
    scene: &Path,
    seg: &Path,
    objects: &[&str],
    out: &Path,
    extra: &[&str],
) -> serde_json::Value {
    let mut args: Vec<String> = vec![
        "remove".into(),
        scene.display().to_string(),
        "--segment".into(),
    ];
    args.push(seg.display().to_string());
    for o in objects {
        args.extend(["--object".into(), o.to_string()]);
    }
    args.extend([
        "--out".into(),
        out.display().to_string(),
        "--hold-out-every".into(),
        "6".into(),
    ]);
    args.extend(extra.iter().map(|s| s.to_string()));
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = common::objnerf_ok(&a);
    println!("{}", String::from_utf8_lossy(&o.stdout));
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

/// The per-view Telea inpainting baseline over the same views and region
/// (examples/removal_telea.py in its own venv): PSNR inside each object's dilated true mask.
fn telea_inside(
    scene: &Path,
    seg: &Path,
    objects: &[&str],
    views: &[String],
    downscale: &str,
) -> serde_json::Value {
    let venv = common::repo_root().join("target/venv-opencv");
    let py = venv.join("bin/python");
    let ok = |py: &Path| {
        Command::new(py)
            .args(["-c", "import cv2"])
            .status()
            .is_ok_and(|s| s.success())
    };
    if !ok(&py) {
        assert!(Command::new("python3")
            .args(["-m", "venv"])
            .arg(&venv)
            .status()
            .unwrap()
            .success());
        let st = Command::new(&py)
            .args([
                "-m",
                "pip",
                "install",
                "--quiet",
                "opencv-python-headless",
                "numpy",
            ])
            .status()
            .unwrap();
        assert!(
            st.success() && ok(&py),
            "pip install opencv-python-headless failed"
        );
    }
    let out = Command::new(&py)
        .arg(common::repo_root().join("examples/removal_telea.py"))
        .arg(scene)
        .arg(seg)
        .args(["--objects", &objects.join(","), "--views", &views.join(",")])
        .args(["--downscale", downscale])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    v["psnr_inside"].clone()
}

/// Removal thresholds: full-frame PSNR >= 28 dB, inside each object's true mask (+4 px) >= 22 dB
/// and above the Telea baseline.
fn assert_removal(report: &serde_json::Value, telea: &serde_json::Value, objects: &[&str]) {
    let s = &report["scores"];
    let frame = s["psnr"].as_f64().unwrap();
    println!(
        "train {:.0} s, peak {} MiB; full-frame {frame:.2} dB; inside {}; telea {telea}",
        report["seconds"]["train"].as_f64().unwrap(),
        report["peak_rss_mib"],
        s["hole_psnr"]
    );
    let who = objects.join("+");
    common::figure(&format!("removal.{who}.psnr_full_db"), frame, 28.0, true);
    assert!(frame >= 28.0, "full-frame PSNR {frame:.2} < 28");
    // Outside the holes a held-out photo shows what the background should: the score any
    // capture gets, truth or not, held to the full frame's floor.
    let outside = &report["held_out_outside_holes"];
    assert_eq!(
        outside["views"].as_u64(),
        Some(s["views"].as_array().unwrap().len() as u64),
        "the held-out views outside the holes: {outside}"
    );
    let outside = outside["psnr"].as_f64().unwrap();
    println!("held out, outside the holes: {outside:.2} dB");
    common::figure(
        &format!("removal.{who}.heldout_outside_holes_db"),
        outside,
        28.0,
        true,
    );
    assert!(
        outside >= 28.0,
        "held out outside the holes {outside:.2} < 28"
    );
    for (k, o) in objects.iter().enumerate() {
        let ours = s["hole_psnr"][k][1].as_f64().unwrap();
        let base = telea[*o].as_f64().unwrap();
        common::figure(
            &format!("removal.{who}.{o}.psnr_inside_db"),
            ours,
            22.0,
            true,
        );
        assert!(ours >= 22.0, "{o}: PSNR inside its mask {ours:.2} < 22");
        assert!(
            ours > base,
            "{o}: {ours:.2} dB is not above Telea's {base:.2}"
        );
    }
}

/// The removal tests' training: a step budget (the result must not depend on the machine's
/// load), `OBJNERF_REMOVAL_STEPS` (default 20 000, `objnerf remove`'s) steps at
/// `OBJNERF_REMOVAL_DOWNSCALE` (default 1), with a 2 GiB grid (`--memory-mb 2048`; the default
/// 1 GiB scores ~0.25 dB lower full frame, at the 28 dB line).
fn removal_training() -> (String, String) {
    let var = |k: &str, d: &str| std::env::var(k).unwrap_or_else(|_| d.to_string());
    (
        var("OBJNERF_REMOVAL_STEPS", "20000"),
        var("OBJNERF_REMOVAL_DOWNSCALE", "1"),
    )
}

/// The mug, segmented from one click, removed from the demo scene; then mug and torus together.
/// Slow (two scene fields): `cargo test --release --test removal -- --ignored --nocapture`
/// (`OBJNERF_REMOVAL_DEFAULTS=1`: `remove` at its defaults instead of 20 000 steps with 2 GiB).
#[test]
#[ignore = "slow (the removal suite, ~45 min in all): cargo test --release --test removal -- --ignored"]
fn demo_mug_and_mug_with_torus_removed_match_the_truth() {
    if !common::sam_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let ring = demo(dir.path(), DemoLayout::Ring, 36);
    let seg = dir.path().join("seg");
    segment(&ring, &["mug", "torus"], &seg);
    let (steps, downscale) = removal_training();
    let mut extra = vec![
        "--steps",
        &steps,
        "--time-budget",
        "1000000",
        "--downscale",
        &downscale,
        "--memory-mb",
        "2048",
    ];
    // `remove` as a user runs it (its own step cap, time budget and memory), for issue 53's
    // line on the defaults: OBJNERF_REMOVAL_DEFAULTS=1.
    if std::env::var_os("OBJNERF_REMOVAL_DEFAULTS").is_some() {
        extra.clear();
    }
    for objects in [&["mug"][..], &["mug", "torus"][..]] {
        let out = dir.path().join(objects.join("_"));
        let r = remove_and_score(&ring, &seg, objects, &out, &extra);
        let views: Vec<String> = r["scores"]["views"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap().to_string())
            .collect();
        assert_eq!(views.len(), 6, "every 6th of 36 views held out");
        let telea = telea_inside(&ring, &seg, objects, &views, &downscale);
        assert_removal(&r, &telea, objects);
    }
}

/// PSNR over the pixels of `views` inside each view's true mask of `object` (`None`: every
/// pixel), between `renders/<view>.png` and the photos.
fn psnr_inside(scene: &Path, renders: &Path, views: &[String], object: Option<&str>) -> f64 {
    let (mut sse, mut n) = (0.0f64, 0usize);
    for v in views {
        let photo = image::open(scene.join("images").join(v)).unwrap().to_rgb8();
        let render = image::open(renders.join(v)).unwrap().to_rgb8();
        let mask = object.map(|o| {
            objnerf::scene::io::read_mask(&scene.join("truth/masks").join(o).join(v)).unwrap()
        });
        for (i, (p, q)) in photo.pixels().zip(render.pixels()).enumerate() {
            let (x, y) = (i as u32 % photo.width(), i as u32 / photo.width());
            if mask.as_ref().is_some_and(|m| m.get_pixel(x, y).0[0] <= 127) {
                continue;
            }
            for c in 0..3 {
                sse += ((p.0[c] as f64 - q.0[c] as f64) / 255.0).powi(2);
            }
            n += 3;
        }
    }
    -10.0 * (sse / n.max(1) as f64).log10()
}

/// The held-out views of a demo scene of `n` views (every 6th: views 3, 9, ...).
fn held_out(n: usize) -> Vec<String> {
    (0..n)
        .filter(|i| i % 6 == 3)
        .map(|i| format!("view_{i:03}.png"))
        .collect()
}

/// Held-out PSNR under which a scene field must have flagged itself: its fit check warns under
/// 24 dB on its training views, and held-out views score a dB or two below those.
const SELF_CHECK_DB: f64 = 22.0;

/// The whole demo scene as a scene field (nothing removed), and the forward-facing demo in NDC
/// space: held-out PSNR >= 28 dB and >= 26 dB, and a poor field flagged by its own self-check.
/// Slow: `cargo test --release --test removal --
/// --ignored --nocapture`.
#[test]
#[ignore = "slow (the removal suite, ~45 min in all): cargo test --release --test removal -- --ignored"]
fn demo_scene_fields_render_held_out_views() {
    let dir = tempfile::tempdir().unwrap();
    for (layout, views, floor) in [
        (DemoLayout::Ring, 36, 28.0),
        (DemoLayout::Forward, 24, 26.0),
    ] {
        let scene = demo(dir.path(), layout, views);
        let model = dir.path().join(format!("{layout}.objf"));
        let (s, m) = (scene.display().to_string(), model.display().to_string());
        let t = std::time::Instant::now();
        let o = common::objnerf_ok(&[
            "train",
            &s,
            "--scene-field",
            "--out",
            &m,
            "--hold-out-every",
            "6",
        ]);
        let secs = t.elapsed().as_secs_f64();
        let log = String::from_utf8_lossy(&o.stderr);
        let want = if layout == DemoLayout::Ring {
            "box space"
        } else {
            "forward space"
        };
        assert!(log.contains(want), "{layout}: {log}");
        let renders = dir.path().join(format!("{layout}_renders"));
        common::objnerf_ok(&[
            "render",
            &m,
            "--scene",
            &s,
            "--out",
            &renders.display().to_string(),
        ]);
        let p = psnr_inside(&scene, &renders, &held_out(views), None);
        // A poor field must say so itself (its fit to its own training views): one held out
        // under SELF_CHECK_DB is blurred or foggy, not just short of the floor.
        let said = String::from_utf8_lossy(&o.stdout);
        let flagged =
            said.contains("scene_field_blurred") || said.contains("scene_field_see_through");
        println!("{layout}: held-out PSNR {p:.2} dB, trained in {secs:.0} s, self-check flagged: {flagged}");
        assert!(
            p >= SELF_CHECK_DB || flagged,
            "{layout}: held-out PSNR {p:.2} < {SELF_CHECK_DB} and no self-check fired"
        );
        common::figure(
            &format!("scene_field.{layout}.heldout_psnr_db"),
            p,
            floor,
            true,
        );
        assert!(p >= floor, "{layout}: held-out PSNR {p:.2} < {floor}");
    }
}

/// `objnerf extract` on the forward-facing demo (one click on the mug): the field's box holds the
/// mug's true box, and held-out PSNR inside its true mask >= 26 dB. Slow (ignored).
#[test]
#[ignore = "slow (the removal suite, ~45 min in all): cargo test --release --test removal -- --ignored"]
fn forward_facing_extract_holds_the_mug() {
    if !common::sam_installed() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = demo(dir.path(), DemoLayout::Forward, 24);
    let (view, point) = click(&scene, "mug");
    let run = dir.path().join("run");
    let (s, r) = (scene.display().to_string(), run.display().to_string());
    common::objnerf_ok(&[
        "extract",
        &s,
        "--view",
        &view,
        "--object",
        "mug",
        "--point",
        &point,
        "--out",
        &r,
        "--hold-out-every",
        "6",
        "--frames",
        "2",
    ]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("report.json")).unwrap()).unwrap();
    let setup = &report["objects"][0]["train"]["setup"];
    let truth = read_truth(&scene).unwrap();
    let mug = truth.iter().find(|t| t.name == "mug").unwrap();
    println!(
        "box {} .. {}: {}",
        setup["box_min"], setup["box_max"], setup["why"]
    );
    for a in 0..3 {
        let (lo, hi) = (
            setup["box_min"][a].as_f64().unwrap(),
            setup["box_max"][a].as_f64().unwrap(),
        );
        assert!(
            lo <= mug.bbox_min[a] && hi >= mug.bbox_max[a],
            "axis {a}: box {lo}..{hi} misses the mug's {:?}..{:?}",
            mug.bbox_min,
            mug.bbox_max
        );
    }
    let renders = dir.path().join("renders");
    let model = run.join("mug/model.objf").display().to_string();
    common::objnerf_ok(&[
        "render",
        &model,
        "--scene",
        &s,
        "--out",
        &renders.display().to_string(),
    ]);
    let on_white = psnr_inside(&scene, &renders, &held_out(24), Some("mug"));
    let [inside, ring] = psnr_over_removed(&scene, &renders, &held_out(24), "mug");
    println!(
        "held-out PSNR inside the mug's true mask: {inside:.2} dB over the scene without it \
         ({on_white:.2} on white); within 4 px outside the mask {ring:.2} dB"
    );
    common::figure("forward_extract.mug.inside_psnr_db", inside, 26.0, true);
    common::figure("forward_extract.mug.ring_psnr_db", ring, 26.0, true);
    assert!(
        inside >= 26.0,
        "held-out PSNR inside the mug {inside:.2} < 26"
    );
    // A fringe of floor colour around the object would show here.
    assert!(ring >= 26.0, "held-out PSNR around the mug {ring:.2} < 26");
}

/// PSNR of an object field's renders (`renders`: RGB on white and `_alpha`) composited over the
/// demo's exact render of the scene without the object, against the photos: inside the
/// object's true mask, and in the band 4 px outside it. This is what the photo is (the object
/// over what lies behind it); on white, the mask's edge pixels hold the floor's colour in the
/// photo and none in the render, which caps even a field trained on the true masks at 27.5 dB
/// there and rewards a floor-coloured fringe.
fn psnr_over_removed(scene: &Path, renders: &Path, views: &[String], object: &str) -> [f64; 2] {
    let mut sse = [0.0f64; 2];
    let mut n = [0usize; 2];
    for v in views {
        let load = |p: PathBuf| image::open(p).unwrap().to_rgb8();
        let photo = load(scene.join("images").join(v));
        let render = load(renders.join(v));
        let stem = v.trim_end_matches(".png");
        let alpha = image::open(renders.join(format!("{stem}_alpha.png")))
            .unwrap()
            .to_luma8();
        let behind = load(scene.join("truth/removed").join(object).join(v));
        let mask =
            objnerf::scene::io::read_mask(&scene.join("truth/masks").join(object).join(v)).unwrap();
        let near = objnerf::util::mask::dilate(&mask, 4);
        for (x, y, p) in photo.enumerate_pixels() {
            let region = if mask.get_pixel(x, y).0[0] > 127 {
                0
            } else if near.get_pixel(x, y).0[0] > 127 {
                1
            } else {
                continue;
            };
            let a = alpha.get_pixel(x, y).0[0] as f64 / 255.0;
            for c in 0..3 {
                // The render on white is c + (1 - a): over the true background it is
                // c + (1 - a) * b.
                let on_white = render.get_pixel(x, y).0[c] as f64 / 255.0;
                let b = behind.get_pixel(x, y).0[c] as f64 / 255.0;
                let composite = on_white - (1.0 - a) * (1.0 - b);
                sse[region] += (p.0[c] as f64 / 255.0 - composite).powi(2);
            }
            n[region] += 3;
        }
    }
    [0, 1].map(|r| -10.0 * (sse[r] / n[r].max(1) as f64).log10())
}
