//! Broken inputs make `objnerf info` fail with a message that names the broken file.

mod common;
mod support;

use objnerf::scene::formats::{colmap, nerfstudio};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Run `objnerf info` on `path`; it must fail, and its stderr must name `file` and contain every
/// word of `expect`. Returns stderr.
fn assert_info_fails(path: &Path, file: &str, expect: &[&str]) -> String {
    let out = Command::new(common::objnerf_bin())
        .arg("info")
        .arg(path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        !out.status.success(),
        "info succeeded on {}",
        path.display()
    );
    assert!(
        stderr.contains(file),
        "stderr does not name {file}: {stderr}"
    );
    for e in expect {
        assert!(stderr.contains(e), "stderr lacks '{e}': {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    eprintln!("{stderr}");
    stderr
}

/// A tiny COLMAP model in `tmp/model` (images in `tmp/images`).
fn colmap_model(tmp: &Path, format: colmap::ModelFormat) -> PathBuf {
    let scene = support::tiny_scene(tmp);
    let dir = tmp.join("model");
    colmap::write_model(&scene, &dir, format).unwrap();
    // The model is good before we break it.
    let ok = Command::new(common::objnerf_bin())
        .arg("info")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    dir
}

fn edit(path: &Path, f: impl FnOnce(&mut Vec<u8>)) {
    let mut bytes = std::fs::read(path).unwrap();
    f(&mut bytes);
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn colmap_cameras_bin_truncated() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Binary);
    edit(&dir.join("cameras.bin"), |b| b.truncate(b.len() - 5));
    assert_info_fails(&dir, "cameras.bin", &["truncated"]);
}

#[test]
fn colmap_images_bin_truncated() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Binary);
    edit(&dir.join("images.bin"), |b| b.truncate(b.len() - 30));
    assert_info_fails(&dir, "images.bin", &["truncated"]);
}

#[test]
fn colmap_unknown_camera_model_id() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Binary);
    // u64 count, i32 camera id, then the i32 model id.
    edit(&dir.join("cameras.bin"), |b| {
        b[12..16].copy_from_slice(&99i32.to_le_bytes())
    });
    assert_info_fails(&dir, "cameras.bin", &["unknown camera model id 99"]);
}

#[test]
fn colmap_points3d_bin_garbage() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Binary);
    edit(&dir.join("points3D.bin"), |b| {
        for (i, v) in b.iter_mut().enumerate() {
            *v = (i as u8).wrapping_mul(151).wrapping_add(17);
        }
    });
    assert_info_fails(&dir, "points3D.bin", &[]);
}

#[test]
fn colmap_cameras_txt_bad_number() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = colmap_model(tmp.path(), colmap::ModelFormat::Text);
    let p = dir.join("cameras.txt");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace(" 9.5 ", " 9.x5 ");
    std::fs::write(&p, text).unwrap();
    assert_info_fails(&dir, "cameras.txt", &["9.x5", "not a valid number"]);
}

/// A good transforms.json for the tiny scene, as a JSON value to break.
fn transforms(tmp: &Path) -> (PathBuf, Value) {
    let mut scene = support::tiny_scene(tmp);
    scene.cameras.truncate(1);
    for im in &mut scene.images {
        im.camera = 0;
        im.features.clear();
    }
    scene.points.clear();
    let path = tmp.join("transforms.json");
    nerfstudio::write(&scene, &path).unwrap();
    let v = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    (path, v)
}

fn save(path: &Path, v: &Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

#[test]
fn transforms_invalid_json() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, _) = transforms(tmp.path());
    std::fs::write(&path, "{ \"frames\": [ {\"file_path\": \"images/a.png\", ").unwrap();
    assert_info_fails(&path, "transforms.json", &["invalid JSON"]);
}

#[test]
fn transforms_nan_matrix() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, v) = transforms(tmp.path());
    // Python's json module writes NaN, which is not JSON.
    let text = serde_json::to_string_pretty(&v).unwrap();
    let m = v["frames"][1]["transform_matrix"][0][0].to_string();
    std::fs::write(&path, text.replacen(&m, "NaN", 1)).unwrap();
    assert_info_fails(&path, "transforms.json", &["invalid JSON", "NaN"]);
}

#[test]
fn transforms_scaled_matrix() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, mut v) = transforms(tmp.path());
    for r in 0..3 {
        for c in 0..3 {
            let x = v["frames"][1]["transform_matrix"][r][c].as_f64().unwrap();
            v["frames"][1]["transform_matrix"][r][c] = (2.0 * x).into();
        }
    }
    save(&path, &v);
    assert_info_fails(
        &path,
        "transforms.json",
        &["frame 1 ('images/b.png')", "not rigid"],
    );
}

#[test]
fn transforms_missing_image() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, mut v) = transforms(tmp.path());
    v["frames"][2]["file_path"] = "images/gone.png".into();
    save(&path, &v);
    assert_info_fails(
        &path,
        "transforms.json",
        &["frame 2", "images/gone.png", "missing"],
    );
}

#[test]
fn transforms_mask_for_some_frames_only() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, mut v) = transforms(tmp.path());
    v["frames"][0]["mask_path"] = "images/a.png".into();
    save(&path, &v);
    assert_info_fails(&path, "transforms.json", &["mask_path", "1 of 3 frames"]);
}

#[test]
fn transforms_size_disagrees_with_image() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, mut v) = transforms(tmp.path());
    v["w"] = 16.into();
    save(&path, &v);
    assert_info_fails(&path, "transforms.json", &["16x8", "8x8"]);
}

#[test]
fn llff_wrong_shape() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    support::tiny_scene(dir);
    let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 15), }";
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    bytes.extend(vec![0u8; 3 * 15 * 8]);
    std::fs::write(dir.join("poses_bounds.npy"), bytes).unwrap();
    assert_info_fails(dir, "poses_bounds.npy", &["(N, 17)", "(3, 15)"]);
}

// ---------------------------------------------------------------------------------------------
// The corpus of corrupt inputs: `tests/data/corrupt/<reader>/<file>`, one folder per fuzz target
// (fuzz/fuzz_targets/<reader>.rs). Each file is put in place of that reader's file in a good
// capture and run through the command that reads it: the command must fail, name the file, not
// panic, and write nothing. Files named `crash-*` are inputs the fuzzers found; the others were
// made by hand (`write_corrupt_corpus` below).

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A 16-bit depth PNG (millimetres) or EXR (metres) of the tiny scene's 8x8 size.
fn write_depth(path: &Path) {
    let d = objnerf::scene::io::DepthMap {
        width: 8,
        height: 8,
        metres: (0..64).map(|i| 1.0 + i as f32 * 0.01).collect(),
    };
    if path.extension().is_some_and(|e| e == "exr") {
        objnerf::scene::io::write_depth_exr(path, &d).unwrap();
    } else {
        objnerf::scene::io::write_depth_png_mm(path, &d).unwrap();
    }
}

/// A Redwood folder: intrinsics, three colour and depth images, and `trajectory.log`.
fn redwood(dir: &Path) -> PathBuf {
    for sub in ["color", "depth"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    std::fs::write(
        dir.join("camera_intrinsic.json"),
        r#"{"width": 8, "height": 8, "intrinsic_matrix": [9, 0, 0, 0, 9, 0, 3.5, 3.5, 1]}"#,
    )
    .unwrap();
    let mut log = String::new();
    for i in 0..3 {
        image::RgbImage::from_pixel(8, 8, image::Rgb([i * 60, 90, 30]))
            .save(dir.join(format!("color/{i:05}.jpg")))
            .unwrap();
        write_depth(&dir.join(format!("depth/{i:05}.png")));
        log += &format!(
            "{i} {i} 3\n1 0 0 {}\n0 1 0 0.5\n0 0 1 -2\n0 0 0 1\n",
            i as f64 * 0.25
        );
    }
    let path = dir.join("trajectory.log");
    std::fs::write(&path, log).unwrap();
    path
}

/// An LLFF poses_bounds.npy for the tiny scene's three 8x8 images.
fn llff_npy() -> Vec<u8> {
    let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 17), }";
    let mut header = header.to_string();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    for i in 0..3 {
        // [R | t | hwf] with R's columns in LLFF's [down, right, back] order, then near, far.
        let row: [f64; 17] = [
            0.0,
            1.0,
            0.0,
            i as f64 * 0.3,
            8.0, //
            -1.0,
            0.0,
            0.0,
            0.1,
            8.0, //
            0.0,
            0.0,
            1.0,
            4.0,
            10.0, //
            0.5,
            9.0,
        ];
        for v in row {
            bytes.extend(v.to_le_bytes());
        }
    }
    bytes
}

/// A small model file, with its optimiser state.
fn objf(path: &Path) {
    use objnerf::field::{io, model::Field, model::FieldConfig};
    let config = FieldConfig {
        sh_degree: 0,
        alpha_init: 0.01,
        base_voxel: 0.5,
    };
    let mut f = Field::new(
        config,
        glam::Vec3::splat(-1.0),
        glam::Vec3::splat(1.0),
        [3, 3, 3],
    );
    for (i, v) in f.grid.data.iter_mut().enumerate() {
        *v = (i % 7) as f32 - 3.0;
    }
    let zeros = vec![0.0f32; f.grid.data.len()];
    io::save(
        path,
        &io::ModelParts {
            field: &f,
            final_dims: [3, 3, 3],
            world_transform: io::IDENTITY,
            train: None,
            step: 1,
            adam: Some((io::Moments::F32(&zeros), io::Moments::F32(&zeros), 1)),
            net_adam: None,
            notes: serde_json::json!({}),
        },
    )
    .unwrap();
}

/// A case: the capture in `tmp` with the reader's file replaced by `bytes`; the command line to
/// run and the file's name as the error must give it.
struct Case {
    args: Vec<PathBuf>,
    file: String,
}

fn setup_case(reader: &str, tmp: &Path, bytes: &[u8]) -> Case {
    use colmap::ModelFormat::{Binary, Text};
    let info = |p: PathBuf| vec![PathBuf::from("info"), p];
    let colmap_case = |format, name: &str| {
        let dir = colmap_model(tmp, format);
        std::fs::write(dir.join(name), bytes).unwrap();
        Case {
            args: info(dir),
            file: name.to_string(),
        }
    };
    // transforms.json with masks, depth or a point cloud for every frame: `kind` names the
    // key, `ext` the files' extension; frame 0's file is the corrupt one.
    let with_files = |key: &str, folder: &str, ext: &str| -> (PathBuf, String) {
        let (path, mut v) = transforms(tmp);
        std::fs::create_dir_all(tmp.join(folder)).unwrap();
        for (i, n) in support::NAMES.iter().enumerate() {
            let rel = format!("{folder}/{}.{ext}", n.trim_end_matches(".png"));
            let p = tmp.join(&rel);
            match (i, folder) {
                (0, _) => std::fs::write(&p, bytes).unwrap(),
                (_, "masks") => image::GrayImage::from_pixel(8, 8, image::Luma([255]))
                    .save(&p)
                    .unwrap(),
                _ => write_depth(&p),
            }
            v["frames"][i][key] = rel.clone().into();
        }
        save(&path, &v);
        (path, format!("{folder}/a.{ext}"))
    };
    let train = |scene: PathBuf, masks: &str, depth: &str| {
        vec![
            PathBuf::from("train"),
            scene,
            "--masks".into(),
            masks.into(),
            "--depth".into(),
            depth.into(),
            "--steps".into(),
            "2".into(),
            "--out".into(),
            tmp.join("model.objf"),
        ]
    };
    match reader {
        "colmap_cameras_bin" => colmap_case(Binary, "cameras.bin"),
        "colmap_images_bin" => colmap_case(Binary, "images.bin"),
        "colmap_points3d_bin" => colmap_case(Binary, "points3D.bin"),
        "colmap_cameras_txt" => colmap_case(Text, "cameras.txt"),
        "colmap_images_txt" => colmap_case(Text, "images.txt"),
        "colmap_points3d_txt" => colmap_case(Text, "points3D.txt"),
        "transforms_json" => {
            let (path, _) = transforms(tmp);
            std::fs::write(&path, bytes).unwrap();
            Case {
                args: info(path),
                file: "transforms.json".into(),
            }
        }
        "llff_npy" => {
            support::tiny_scene(tmp);
            std::fs::write(tmp.join("poses_bounds.npy"), bytes).unwrap();
            Case {
                args: info(tmp.to_path_buf()),
                file: "poses_bounds.npy".into(),
            }
        }
        "redwood_trajectory" => {
            let log = redwood(tmp);
            std::fs::write(log, bytes).unwrap();
            Case {
                args: info(tmp.to_path_buf()),
                file: "trajectory.log".into(),
            }
        }
        "ply" => {
            let (path, mut v) = transforms(tmp);
            v["ply_file_path"] = "sparse_pc.ply".into();
            save(&path, &v);
            std::fs::write(tmp.join("sparse_pc.ply"), bytes).unwrap();
            Case {
                args: info(path),
                file: "sparse_pc.ply".into(),
            }
        }
        "objf" => {
            let model = tmp.join("model.objf");
            std::fs::write(&model, bytes).unwrap();
            Case {
                args: vec!["mesh".into(), model, "--out".into(), tmp.join("mesh.glb")],
                file: "model.objf".into(),
            }
        }
        "mask_png" => {
            let (path, file) = with_files("mask_path", "masks", "png");
            Case {
                args: train(path, "scene", "none"),
                file,
            }
        }
        "depth_png" | "depth_exr" => {
            let ext = &reader[6..];
            let (path, file) = with_files("depth_file_path", "depth", ext);
            Case {
                args: train(path, "alpha", "dense"),
                file,
            }
        }
        "photo_jpeg" => {
            let (path, mut v) = transforms(tmp);
            std::fs::write(tmp.join("images/a.jpg"), bytes).unwrap();
            v["frames"][0]["file_path"] = "images/a.jpg".into();
            save(&path, &v);
            Case {
                args: train(path, "alpha", "none"),
                file: "images/a.jpg".into(),
            }
        }
        "sam_checkpoint" => {
            let ckpt = tmp.join("mobile_sam.pt");
            std::fs::write(&ckpt, bytes).unwrap();
            Case {
                args: vec![
                    "models".into(),
                    "convert".into(),
                    "--checkpoint".into(),
                    ckpt,
                    "--out".into(),
                    tmp.join("onnx"),
                ],
                file: "mobile_sam.pt".into(),
            }
        }
        // An edit over a model and a path, one of the two corrupt, through `render-edit`.
        "edit_json" | "camera_path_json" => {
            objf(&tmp.join("m.objf"));
            let (edit, path) = (tmp.join("edit.json"), tmp.join("camera_path.json"));
            std::fs::write(&edit, edit_seed()).unwrap();
            std::fs::write(&path, camera_path_seed()).unwrap();
            let file = if reader == "edit_json" { &edit } else { &path };
            std::fs::write(file, bytes).unwrap();
            let name = file.file_name().unwrap().to_string_lossy().to_string();
            Case {
                args: vec![
                    "render-edit".into(),
                    edit,
                    "--path".into(),
                    path,
                    "--out".into(),
                    tmp.join("out"),
                ],
                file: name,
            }
        }
        other => panic!("tests/data/corrupt/{other}: no reader of that name"),
    }
}

/// A good edit file: a model `m.objf` beside it, moved, turned, scaled, recoloured, duplicated.
fn edit_seed() -> Vec<u8> {
    use std::f64::consts::FRAC_1_SQRT_2;
    let v = serde_json::json!({"version": 1, "metres_per_unit": 1.0,
        "background": {"color": "#ffffff"},
        "objects": [
            {"name": "mug", "model": "m.objf", "pivot": [0.1, 0.2, 0.0],
             "translation": [0.15, 0.0, 0.0], "rotation": {"w": FRAC_1_SQRT_2, "x": 0.0, "y": 0.0, "z": FRAC_1_SQRT_2},
             "scale": 1.5, "recolour": {"target": "#2050ff", "strength": 1.0}},
            {"name": "mug.001", "model": "m.objf", "visible": false, "metres_per_unit": 0.25,
             "recolour": {"hue_degrees": 90}}]});
    serde_json::to_vec_pretty(&v).unwrap()
}

/// A good camera_path.json: three cameras on a ring, 16x12.
fn camera_path_seed() -> Vec<u8> {
    use objnerf::scene::camera_path::{CameraPath, Orbit, PathFrame};
    let p = CameraPath::orbit(&Orbit {
        center: glam::DVec3::ZERO,
        radius: 2.0,
        elevation: 0.5,
        up: glam::DVec3::Z,
        views: 3,
        fov_y_deg: 40.0,
        width: 16,
        height: 12,
        fps: 24.0,
    })
    .unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("camera_path.json");
    p.write(&file, &PathFrame::Data).unwrap();
    std::fs::read(file).unwrap()
}

/// Every file under `dir`, relative, with its size: what a command wrote shows as a difference.
fn listing(dir: &Path) -> Vec<(PathBuf, u64)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p.clone());
            }
            let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
            out.push((p.strip_prefix(dir).unwrap().to_path_buf(), len));
        }
    }
    out.sort();
    out
}

#[test]
fn corrupt_corpus() {
    let root = repo().join("tests/data/corrupt");
    let mut readers: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    readers.sort();
    let mut count = 0;
    let mut failures = Vec::new();
    for dir in readers {
        let reader = dir.file_name().unwrap().to_string_lossy().to_string();
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        for file in files {
            let bytes = std::fs::read(&file).unwrap();
            let tmp = tempfile::tempdir().unwrap();
            let case = setup_case(&reader, tmp.path(), &bytes);
            let before = listing(tmp.path());
            let out = Command::new(common::objnerf_bin())
                .args(&case.args)
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&out.stderr).to_string();
            let after = listing(tmp.path());
            let name = format!("{reader}/{}", file.file_name().unwrap().to_string_lossy());
            let problem = if out.status.success() {
                Some("the command succeeded".to_string())
            } else if out.status.code() != Some(1) {
                Some(format!("exit status {:?}, not 1", out.status))
            } else if stderr.contains("panicked") {
                Some("it panicked".to_string())
            } else if !stderr.contains(&case.file) {
                Some(format!("the error does not name {}", case.file))
            } else if before != after {
                Some(format!(
                    "it wrote files: {:?}",
                    after
                        .iter()
                        .filter(|f| !before.contains(f))
                        .collect::<Vec<_>>()
                ))
            } else {
                None
            };
            match problem {
                Some(p) => failures.push(format!("{name}: {p}\n  stderr: {}", stderr.trim())),
                None => eprintln!("{name}: {}", stderr.trim()),
            }
            count += 1;
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(count >= 40, "the corpus holds {count} files, fewer than 40");
}

/// Write the fuzzers' seeds (`fuzz/seeds/<target>/`: one good file each, and the good files a
/// target reads beside its input). Run once by hand; the seeds are committed:
/// `cargo test --release --test corrupt_inputs -- --ignored write_fuzz_seeds`
#[test]
#[ignore = "writes fuzz/seeds/ (not a check): cargo test --release --test corrupt_inputs write_fuzz_seeds -- --ignored"]
fn write_fuzz_seeds() {
    let seeds = repo().join("fuzz/seeds");
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let put = |target: &str, name: &str, bytes: &[u8]| {
        let d = seeds.join(target);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join(name), bytes).unwrap();
    };
    let read = |p: &Path| std::fs::read(p).unwrap();
    let bin = colmap_model(&t.join("bin"), colmap::ModelFormat::Binary);
    let txt = colmap_model(&t.join("txt"), colmap::ModelFormat::Text);
    for (target, dir, file) in [
        ("colmap_cameras_bin", &bin, "cameras.bin"),
        ("colmap_images_bin", &bin, "images.bin"),
        ("colmap_points3d_bin", &bin, "points3D.bin"),
        ("colmap_cameras_txt", &txt, "cameras.txt"),
        ("colmap_images_txt", &txt, "images.txt"),
        ("colmap_points3d_txt", &txt, "points3D.txt"),
    ] {
        put(target, file, &read(&dir.join(file)));
    }
    for n in support::NAMES {
        put("_scene/images", n, &read(&t.join("bin/images").join(n)));
    }
    let (path, mut v) = transforms(&t.join("tf"));
    put("transforms_json", "transforms.json", &read(&path));
    v["ply_file_path"] = "sparse_pc.ply".into();
    v["camera_model"] = "OPENCV".into();
    v["k1"] = 0.01.into();
    put(
        "transforms_json",
        "transforms_ply.json",
        serde_json::to_string_pretty(&v).unwrap().as_bytes(),
    );
    put("llff_npy", "poses_bounds.npy", &llff_npy());
    put(
        "redwood_trajectory",
        "trajectory.log",
        &read(&redwood(&t.join("rw"))),
    );
    let pts: Vec<_> = (0..4)
        .map(|i| (glam::DVec3::new(i as f64, 0.5, -0.25), [i as u8 * 50, 7, 9]))
        .collect();
    objnerf::scene::formats::ply::write_points(&t.join("pc.ply"), &pts).unwrap();
    put("ply", "sparse_pc.ply", &read(&t.join("pc.ply")));
    put(
        "ply",
        "mesh_ascii.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
          property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
          element face 1\nproperty list uchar int vertex_indices\nend_header\n\
          0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n3 0 1 2\n",
    );
    objf(&t.join("m.objf"));
    put("objf", "model.objf", &read(&t.join("m.objf")));
    put("edit_json", "edit.json", &edit_seed());
    put("camera_path_json", "camera_path.json", &camera_path_seed());
    let grey = image::GrayImage::from_fn(8, 8, |x, y| image::Luma([((x + y) % 2 * 255) as u8]));
    grey.save(t.join("m.png")).unwrap();
    put("mask_png", "mask.png", &read(&t.join("m.png")));
    let rgba = image::RgbaImage::from_fn(8, 8, |x, _| image::Rgba([9, 9, 9, (x * 30) as u8]));
    rgba.save(t.join("m4.png")).unwrap();
    put("mask_png", "mask_rgba.png", &read(&t.join("m4.png")));
    write_depth(&t.join("d.png"));
    put("depth_png", "depth.png", &read(&t.join("d.png")));
    write_depth(&t.join("d.exr"));
    put("depth_exr", "depth.exr", &read(&t.join("d.exr")));
    let photo =
        image::RgbImage::from_fn(16, 16, |x, y| image::Rgb([x as u8 * 16, y as u8 * 16, 80]));
    photo.save(t.join("p.jpg")).unwrap();
    put("photo_jpeg", "photo.jpg", &read(&t.join("p.jpg")));
}
