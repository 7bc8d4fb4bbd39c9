//! `objnerf render-edit`, `edit-template`, `mesh --recolour` and the demo's exact truth of an
//! edit (`demo-scene --edit`): conventions checked against the truth with a quickly trained demo
//! object, the truth checked against the demo's own render, and bad inputs refused. The quality
//! checks with a background field (slow) are in `tests/render_edit_quality.rs`.

mod common;

use common::{objnerf_bin, objnerf_ok};
use glam::Vec3;
use objnerf::demo::edit_truth::demo_orbit;
use objnerf::demo::fields::{write_object_field, DemoFieldOptions};
use objnerf::demo::{write_demo_scene, DemoOptions};
use objnerf::field::io::{save, IDENTITY};
use objnerf::field::{Field, FieldConfig};
use objnerf::scene::camera_path::{CameraPath, PathFrame};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

/// The default demo scene and the mug's field trained from its true masks (600 steps), made
/// once for this file.
fn fixture() -> &'static (tempfile::TempDir, PathBuf, PathBuf) {
    static F: OnceLock<(tempfile::TempDir, PathBuf, PathBuf)> = OnceLock::new();
    F.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let scene = tmp.path().join("demo");
        write_demo_scene(&DemoOptions::default(), &scene).unwrap();
        let mug = tmp.path().join("mug.objf");
        let opts = DemoFieldOptions::steps(600);
        write_object_field(&scene, "mug", &opts, &mug).unwrap();
        (tmp, scene, mug)
    })
}

/// A tiny valid model file (a 5^3 grid), for edits whose fields do not matter.
fn tiny_model(path: &Path) {
    let f = Field::new(
        FieldConfig {
            sh_degree: 0,
            alpha_init: 0.01,
            base_voxel: 0.1,
        },
        Vec3::splat(-0.2),
        Vec3::splat(0.2),
        [5, 5, 5],
    );
    save(
        path,
        &objnerf::field::io::ModelParts {
            field: &f,
            final_dims: [5, 5, 5],
            world_transform: IDENTITY,
            train: None,
            step: 0,
            adam: None,
            net_adam: None,
            notes: serde_json::json!({"kind": "object"}),
        },
    )
    .unwrap();
}

fn objnerf(args: &[&str]) -> Output {
    Command::new(objnerf_bin()).args(args).output().unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn write_json(path: &Path, v: &serde_json::Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

fn gray(dir: &Path, kind: &str, k: usize) -> image::GrayImage {
    image::open(dir.join(format!("{kind}_{k:05}.png")))
        .unwrap()
        .to_luma8()
}

/// IoU of the pixels equal to `value` in two object-index images.
fn index_iou(a: &image::GrayImage, b: &image::GrayImage, value: u8) -> f64 {
    let (mut i, mut u) = (0usize, 0usize);
    for (p, q) in a.pixels().zip(b.pixels()) {
        let (x, y) = (p[0] == value, q[0] == value);
        i += (x && y) as usize;
        u += (x || y) as usize;
    }
    if u == 0 {
        1.0
    } else {
        i as f64 / u as f64
    }
}

/// The mug moved and turned, scaled, and duplicated over a plain background: in every frame of
/// an orbit, the object-index pass of `render-edit` (the trained field under the edit's
/// transform) and of the exact truth (`demo-scene --edit`, the analytic mug under the same
/// transform) agree with IoU >= 0.9 per object, and the colour agrees (PSNR >= 22 dB over the
/// frame). This is the test that the renderer and the truth read the edit file alike (pivot,
/// rotation, scale, duplicates, object indices, image rows).
#[test]
fn edits_of_a_demo_object_match_the_exact_truth() {
    let (_, _, mug) = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("camera_path.json");
    demo_orbit(6, 160, 120)
        .unwrap()
        .write(&path, &PathFrame::Data)
        .unwrap();
    // The mug's base centre: rotation and scale keep it standing on the floor.
    let pivot = [-0.42, 0.32, 0.0];
    let q90 = serde_json::json!({"w": 0.5f64.sqrt(), "x": 0.0, "y": 0.0, "z": 0.5f64.sqrt()});
    let cases = [
        (
            "moved",
            serde_json::json!([{"name": "mug", "model": s(mug), "pivot": pivot,
                "translation": [0.15, 0.0, 0.0], "rotation": q90}]),
        ),
        (
            "scaled",
            serde_json::json!([{"name": "mug", "model": s(mug), "pivot": pivot, "scale": 1.5}]),
        ),
        (
            "duplicated",
            serde_json::json!([{"name": "mug", "model": s(mug), "pivot": pivot},
                {"name": "mug.001", "model": s(mug), "pivot": pivot, "translation": [0.3, -0.3, 0.0],
                 "rotation": q90}]),
        ),
    ];
    for (name, objects) in cases {
        let edit = tmp.path().join(format!("{name}.json"));
        let n_objects = objects.as_array().unwrap().len();
        write_json(
            &edit,
            &serde_json::json!({"version": 1, "background": {"color": "#ffffff"}, "objects": objects}),
        );
        let (ours, truth) = (
            tmp.path().join(name),
            tmp.path().join(format!("{name}_truth")),
        );
        objnerf_ok(&[
            "render-edit",
            s(&edit),
            "--path",
            s(&path),
            "--out",
            s(&ours),
            "--passes",
            "rgb,alpha,depth,index",
        ]);
        objnerf_ok(&[
            "demo-scene",
            "--edit",
            s(&edit),
            "--path",
            s(&path),
            "--out",
            s(&truth),
        ]);
        let mut worst = 1.0f64;
        let (mut se, mut n) = (0.0f64, 0.0f64);
        for k in 0..6 {
            let (a, b) = (gray(&ours, "index", k), gray(&truth, "index", k));
            for obj in 1..=n_objects as u8 {
                worst = worst.min(index_iou(&a, &b, obj));
            }
            let fa = image::open(ours.join(format!("frame_{k:05}.png")))
                .unwrap()
                .to_rgb8();
            let fb = image::open(truth.join(format!("frame_{k:05}.png")))
                .unwrap()
                .to_rgb8();
            for (p, q) in fa.pixels().zip(fb.pixels()) {
                for c in 0..3 {
                    se += ((p[c] as f64 - q[c] as f64) / 255.0).powi(2);
                    n += 1.0;
                }
            }
            assert!(ours.join(format!("depth_{k:05}.exr")).is_file());
        }
        let psnr = -10.0 * (se / n).log10();
        eprintln!("{name}: min object-index IoU {worst:.3}, PSNR {psnr:.2} dB over 6 frames");
        assert!(worst >= 0.9, "{name}: IoU {worst:.3}");
        assert!(psnr >= 22.0, "{name}: PSNR {psnr:.2}");
    }
}

/// Every demo object in place over a background model: the truth of this edit is the demo
/// scene's own render of the same cameras (so the edited world, its placements and textures are
/// the demo's).
#[test]
fn the_truth_of_an_identity_edit_is_the_demo_render() {
    let (_, scene, _) = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("tiny.objf");
    tiny_model(&model);
    let world = objnerf::demo::World::demo();
    let objects: Vec<serde_json::Value> = world
        .objects
        .iter()
        .map(
            |o| serde_json::json!({"name": o.name, "model": "tiny.objf", "pivot": [0.1, 0.2, 0.0]}),
        )
        .collect();
    let edit = tmp.path().join("edit.json");
    write_json(
        &edit,
        &serde_json::json!({"version": 1, "background": {"model": "tiny.objf"}, "objects": objects}),
    );
    let sc = objnerf::Scene::load(scene).unwrap();
    let views = CameraPath::from_scene_views(&sc, 24.0).unwrap();
    let few = CameraPath {
        cameras: [0, 9, 20].map(|i| views.cameras[i].clone()).to_vec(),
        ..views.clone()
    };
    let path = tmp.path().join("views.json");
    few.write(&path, &PathFrame::Data).unwrap();
    let out = tmp.path().join("truth");
    objnerf_ok(&[
        "demo-scene",
        "--edit",
        s(&edit),
        "--path",
        s(&path),
        "--out",
        s(&out),
    ]);
    for (k, i) in [0, 9, 20].into_iter().enumerate() {
        let a = image::open(out.join(format!("frame_{k:05}.png")))
            .unwrap()
            .to_rgb8();
        let b = image::open(scene.join("images").join(format!("view_{i:03}.png")))
            .unwrap()
            .to_rgb8();
        let differ = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
        let frac = differ as f64 / (a.width() * a.height()) as f64;
        eprintln!("view {i}: {differ} pixels differ");
        assert!(
            frac < 0.002,
            "view {i}: {:.2}% of the pixels differ",
            100.0 * frac
        );
        // Every object keeps the index of its place in the edit file.
        let idx = gray(&out, "index", k);
        for (j, o) in world.objects.iter().enumerate() {
            let m = objnerf::scene::io::read_mask(
                &scene
                    .join("truth/masks")
                    .join(o.name)
                    .join(format!("view_{i:03}.png")),
            )
            .unwrap();
            let truth_count = m.pixels().filter(|p| p[0] > 127).count();
            let ours = idx.pixels().filter(|p| p[0] == j as u8 + 1).count();
            assert!(
                (truth_count as i64 - ours as i64).abs() <= 2,
                "view {i}, {}: {ours} vs {truth_count}",
                o.name
            );
        }
    }
}

/// Bad edit files and camera paths are errors naming the file and the field, exit 1, and leave
/// no output folder.
#[test]
fn bad_edits_and_paths_are_clear_errors_and_nothing_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    tiny_model(&t.join("m.objf"));
    let good_edit = serde_json::json!({"version": 1, "background": {"model": "m.objf"},
        "objects": [{"name": "mug", "model": "m.objf", "scale": 1.0}]});
    let path = t.join("path.json");
    demo_orbit(2, 32, 24)
        .unwrap()
        .write(&path, &PathFrame::Data)
        .unwrap();
    let good_path: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    // The good pair renders.
    write_json(&t.join("edit.json"), &good_edit);
    objnerf_ok(&[
        "render-edit",
        s(&t.join("edit.json")),
        "--path",
        s(&path),
        "--out",
        s(&t.join("ok")),
        "--no-video",
    ]);
    type Change = Box<dyn Fn(&mut serde_json::Value)>;
    let edit_cases: Vec<(&str, Change, &str)> = vec![
        (
            "missing model",
            Box::new(|e| e["objects"][0]["model"] = "gone.objf".into()),
            "objects[0].model",
        ),
        (
            "zero scale",
            Box::new(|e| e["objects"][0]["scale"] = 0.into()),
            "objects[0].scale: 0 is not a positive number",
        ),
        (
            "zero rotation",
            Box::new(|e| {
                e["objects"][0]["rotation"] = serde_json::json!({"w": 0, "x": 0, "y": 0, "z": 0})
            }),
            "objects[0].rotation",
        ),
        (
            "unknown key",
            Box::new(|e| e["objects"][0]["colour"] = "red".into()),
            "objects[0].colour: unknown key",
        ),
        (
            "version",
            Box::new(|e| e["version"] = 7.into()),
            "version: 7",
        ),
        (
            "missing background model",
            Box::new(|e| e["background"]["model"] = "nope.objf".into()),
            "background.model",
        ),
    ];
    let path_cases: Vec<(&str, Change, &str)> = vec![
        (
            "unknown camera type",
            Box::new(|p| p["camera_type"] = "orthographic".into()),
            "unknown camera_type 'orthographic'",
        ),
        (
            "zero fov",
            Box::new(|p| p["camera_path"][1]["fov"] = 0.into()),
            "camera_path[1]: fov = 0",
        ),
        (
            "negative fov",
            Box::new(|p| p["camera_path"][0]["fov"] = (-30).into()),
            "camera_path[0]: fov = -30",
        ),
        (
            "matrix not rigid",
            Box::new(|p| p["camera_path"][0]["camera_to_world"][0] = 2.into()),
            "camera_path[0]",
        ),
    ];
    let edit = t.join("edit.json");
    // Each case breaks a copy of the good edit or the good path; render-edit refuses it.
    let cases = edit_cases
        .into_iter()
        .map(|c| ("edit", c))
        .chain(path_cases.into_iter().map(|c| ("path", c)));
    for (kind, (what, change, want)) in cases {
        let mut doc = if kind == "edit" {
            good_edit.clone()
        } else {
            good_path.clone()
        };
        change(&mut doc);
        let file = t.join(format!("{kind}_{}.json", what.replace(' ', "_")));
        write_json(&file, &doc);
        let (e, p) = if kind == "edit" {
            (&file, &path)
        } else {
            (&edit, &file)
        };
        let out = t.join(format!("out_{}", what.replace(' ', "_")));
        let r = objnerf(&["render-edit", s(e), "--path", s(p), "--out", s(&out)]);
        let name = file.file_name().unwrap().to_str().unwrap();
        check_refused(&r, what, name, want, &out);
    }
    // A NaN in a matrix, as Python's json module writes it: the error says where.
    let text = serde_json::to_string_pretty(&good_path).unwrap();
    let m = good_path["camera_path"][0]["camera_to_world"][3].to_string();
    let file = t.join("path_nan.json");
    std::fs::write(&file, text.replacen(&format!("{m},"), "NaN,", 1)).unwrap();
    let out = t.join("out_nan");
    let r = objnerf(&[
        "render-edit",
        s(&edit),
        "--path",
        s(&file),
        "--out",
        s(&out),
    ]);
    check_refused(
        &r,
        "NaN",
        "path_nan.json",
        "camera_path[0].camera_to_world[3] is NaN",
        &out,
    );
    // demo-scene --edit refuses objects the demo does not have, and writes nothing.
    let mut e = good_edit.clone();
    e["objects"][0]["name"] = "lego".into();
    let file = t.join("edit_lego.json");
    write_json(&file, &e);
    let out = t.join("truth_lego");
    let r = objnerf(&[
        "demo-scene",
        "--edit",
        s(&file),
        "--path",
        s(&path),
        "--out",
        s(&out),
    ]);
    check_refused(
        &r,
        "not a demo object",
        "edit_lego.json",
        "objects[0].name: 'lego'",
        &out,
    );
}

fn check_refused(r: &Output, what: &str, file: &str, want: &str, out: &Path) {
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{what}: {err}");
    assert!(err.contains(file) && err.contains(want), "{what}: {err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
    assert!(!out.exists(), "{what}: {} was written", out.display());
    eprintln!("{what}: {}", err.trim());
}

/// A camera path as nerfstudio's viewer writes it (keyframes, crop, transition settings) and as
/// the Blender add-on writes it render unchanged: the path render-edit writes back holds the
/// same cameras. Also: --size scales a path keeping its field of view, the video is an MP4 when
/// ffmpeg is installed (else a GIF), and edit-template writes every object of a run in place over
/// the run's removal field.
#[test]
fn nerfstudio_and_blender_paths_render_unchanged() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    tiny_model(&t.join("m.objf"));
    let orbit = demo_orbit(3, 48, 36).unwrap();
    let entries: Vec<serde_json::Value> = orbit
        .cameras
        .iter()
        .map(|c| {
            let m = c.pose.c2w_opengl();
            let flat: Vec<f64> = m
                .iter()
                .flatten()
                .copied()
                .chain([0.0, 0.0, 0.0, 1.0])
                .collect();
            serde_json::json!({"camera_to_world": flat, "fov": 39.3, "aspect": 48.0 / 36.0})
        })
        .collect();
    let keyframes: Vec<serde_json::Value> = entries
        .iter()
        .map(|e| {
            serde_json::json!({"matrix": e["camera_to_world"], "fov": 39.3, "aspect": 1.333,
            "override_transition_enabled": false, "override_transition_sec": null})
        })
        .collect();
    let viewer = serde_json::json!({"default_fov": 75.0, "default_transition_sec": 2.0,
        "keyframes": keyframes, "camera_type": "perspective", "render_height": 36.0,
        "render_width": 48.0, "fps": 24.0, "seconds": 0.125, "is_cycle": false,
        "smoothness_value": 0.5, "camera_path": entries, "crop": null});
    let blender = serde_json::json!({"camera_type": "perspective", "render_width": 48,
        "render_height": 36, "fps": 24, "seconds": 0.125, "camera_path": entries});
    write_json(
        &t.join("edit.json"),
        &serde_json::json!({"version": 1, "background": {"color": "#203040"},
            "objects": [{"name": "a", "model": "m.objf"}]}),
    );
    for (name, doc) in [("viewer", viewer), ("blender", blender)] {
        let file = t.join(format!("{name}.json"));
        write_json(&file, &doc);
        let out = t.join(name);
        objnerf_ok(&[
            "render-edit",
            s(&t.join("edit.json")),
            "--path",
            s(&file),
            "--out",
            s(&out),
        ]);
        let given = CameraPath::read(&file, &PathFrame::Data).unwrap();
        let back = CameraPath::read(&out.join("camera_path.json"), &PathFrame::Data).unwrap();
        assert_eq!(given.cameras.len(), back.cameras.len());
        for (a, b) in given.cameras.iter().zip(&back.cameras) {
            let (ma, mb) = (a.pose.c2w_opengl(), b.pose.c2w_opengl());
            for r in 0..3 {
                for c in 0..4 {
                    assert!((ma[r][c] - mb[r][c]).abs() < 1e-9, "{name}");
                }
            }
            assert!((a.camera.focal().1 - b.camera.focal().1).abs() < 1e-9);
        }
        for k in 0..3 {
            let f = image::open(out.join(format!("frame_{k:05}.png"))).unwrap();
            assert_eq!((f.width(), f.height()), (48, 36), "{name}");
        }
        let has_ffmpeg = Command::new("ffmpeg")
            .arg("-version")
            .output()
            .is_ok_and(|o| o.status.success());
        let video = out.join(if has_ffmpeg { "video.mp4" } else { "video.gif" });
        assert!(video.is_file(), "{name}: no {}", video.display());
    }
    // --size: the same cameras at another size, vertical field of view kept.
    let out = t.join("sized");
    objnerf_ok(&[
        "render-edit",
        s(&t.join("edit.json")),
        "--path",
        s(&t.join("blender.json")),
        "--out",
        s(&out),
        "--size",
        "96x72",
        "--no-video",
    ]);
    let back = CameraPath::read(&out.join("camera_path.json"), &PathFrame::Data).unwrap();
    assert_eq!((back.width, back.height), (96, 72));
    let fy = back.cameras[0].camera.focal().1;
    assert!((2.0 * (36.0 / fy).atan().to_degrees() - 39.3).abs() < 1e-9);

    // edit-template on a run folder with a removal field.
    let run = t.join("run");
    for o in ["mug", "torus"] {
        std::fs::create_dir_all(run.join(o)).unwrap();
        tiny_model(&run.join(o).join("model.objf"));
    }
    std::fs::create_dir_all(run.join("removed")).unwrap();
    tiny_model(&run.join("removed/background.objf"));
    write_json(
        &run.join("report.json"),
        &serde_json::json!({"objects": [{"name": "mug"}, {"name": "torus"}]}),
    );
    let edit = t.join("edits/template.json");
    objnerf_ok(&["edit-template", s(&run), "--out", s(&edit)]);
    let e = objnerf::edit::EditFile::read(&edit).unwrap();
    assert_eq!(e.objects.len(), 2);
    assert_eq!(e.objects[1].model_given, "../run/torus/model.objf");
    assert!(
        matches!(&e.background, objnerf::edit::Background::Model { given, .. } if given == "../run/removed/background.objf"),
        "{:?}",
        e.background
    );
    // ... and it renders along a generated orbit.
    let out = t.join("orbit");
    objnerf_ok(&[
        "render-edit",
        s(&edit),
        "--orbit",
        "2",
        "--size",
        "40x30",
        "--out",
        s(&out),
        "--no-video",
    ]);
    assert!(out.join("frame_00001.png").is_file() && out.join("camera_path.json").is_file());
    // ... and along a scene's own views.
    let (_, scene, _) = fixture();
    let out = t.join("views");
    objnerf_ok(&[
        "render-edit",
        s(&edit),
        "--views",
        s(scene),
        "--size",
        "32x24",
        "--out",
        s(&out),
        "--no-video",
    ]);
    let back = CameraPath::read(&out.join("camera_path.json"), &PathFrame::Data).unwrap();
    assert_eq!(back.cameras.len(), 36);
    assert!(out.join("frame_00035.png").is_file());
    let colour = t.join("edits/colour.json");
    objnerf_ok(&[
        "edit-template",
        s(&run),
        "--background",
        "#102030",
        "--out",
        s(&colour),
    ]);
    let e = objnerf::edit::EditFile::read(&colour).unwrap();
    assert_eq!(
        e.background,
        objnerf::edit::Background::Color([16.0 / 255.0, 32.0 / 255.0, 48.0 / 255.0])
    );
}

/// `objnerf mesh --recolour`: vertex colours take the target's hue and keep their OKLab
/// lightness (compared on the mesh's colours before they are written); the flag is parsed and
/// checked before anything is written.
#[test]
fn mesh_recolour_moves_vertex_colours_to_the_target_hue() {
    use objnerf::mesh::from_field::{mesh_field, FieldMeshOptions};
    let (_, _, mug) = fixture();
    let field = objnerf::field::io::load_field(mug).unwrap().field;
    let plain = mesh_field(&field, "mug", &FieldMeshOptions::default(), None)
        .unwrap()
        .0;
    let blue = [0x20 as f32 / 255.0, 0x50 as f32 / 255.0, 1.0];
    let opts = FieldMeshOptions {
        recolour: Some(objnerf::edit::Recolour::Target {
            rgb: blue,
            strength: 1.0,
        }),
        ..Default::default()
    };
    let recoloured = mesh_field(&field, "mug", &opts, None).unwrap().0;
    let (ca, cb) = (plain.colors.unwrap(), recoloured.colors.unwrap());
    assert_eq!(ca.len(), cb.len());
    let lab = objnerf::edit::recolour::srgb_to_oklab;
    let t = lab(blue);
    let target = t.z.atan2(t.y);
    let mut worst_l = 0f32;
    let mut off_hue = 0;
    for (p, q) in ca.iter().zip(&cb) {
        let (a, b) = (lab(*p), lab(*q));
        worst_l = worst_l.max((a.x - b.x).abs());
        off_hue += ((b.z.atan2(b.y) - target).abs() > 0.02 && b.y.hypot(b.z) > 1e-3) as usize;
    }
    assert!(worst_l < 2e-3, "lightness moved by {worst_l}");
    assert_eq!(
        off_hue,
        0,
        "{off_hue} of {} vertices off the target hue",
        cb.len()
    );
    let tmp = tempfile::tempdir().unwrap();
    objnerf_ok(&[
        "mesh",
        s(mug),
        "--out",
        s(&tmp.path().join("b.ply")),
        "--up",
        "+z",
        "--recolour",
        "hue:120",
    ]);
    let bad = objnerf(&[
        "mesh",
        s(mug),
        "--out",
        s(&tmp.path().join("c.ply")),
        "--recolour",
        "blue",
    ]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--recolour"));
    assert!(!tmp.path().join("c.ply").exists());
}
