//! Edits of the demo scene rendered by `objnerf render-edit` against their exact truth (`objnerf
//! demo-scene --edit`), with fields trained on step budgets: the background without the mug and
//! the torus (`objnerf remove` with their true masks and the true depth), the mug and the torus
//! from their true masks, and lego from its alpha. Slow (the background trains for ~7
//! CPU-minutes, lego for ~2): ignored, run with
//!
//! ```sh
//! cargo test --release --test render_edit_quality -- --ignored --nocapture
//! ```
//!
//! `OBJNERF_EDIT_FIELDS=DIR` keeps the demo scene and the trained fields in DIR and reuses them.

mod common;

use common::objnerf_bin;
use glam::DVec3;
use objnerf::demo::edit_truth::demo_orbit;
use objnerf::pipeline::edit_fields::{ensure_edit_fields, EditFields};
use objnerf::scene::camera_path::PathFrame;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// lego trains from its alpha at 200x200 for this many steps.
const LEGO_STEPS: usize = 3000;

/// The demo scene and its fields in `OBJNERF_EDIT_FIELDS` (or a temporary folder), made once
/// for every test of this file (they run in parallel: the first makes them, the others wait).
fn fields() -> &'static EditFields {
    static F: OnceLock<(Option<tempfile::TempDir>, EditFields)> = OnceLock::new();
    &F.get_or_init(|| {
        let (tmp, dir) = match std::env::var_os("OBJNERF_EDIT_FIELDS") {
            Some(d) => (None, PathBuf::from(d)),
            None => {
                let t = tempfile::tempdir().unwrap();
                let d = t.path().to_path_buf();
                (Some(t), d)
            }
        };
        let f = ensure_edit_fields(&dir, &mut |m| eprintln!("{m}")).unwrap();
        (tmp, f)
    })
    .1
}

fn run(args: &[&str]) {
    let out = Command::new(objnerf_bin()).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "objnerf {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn rgb(dir: &Path, k: usize) -> image::RgbImage {
    image::open(dir.join(format!("frame_{k:05}.png")))
        .unwrap()
        .to_rgb8()
}

fn gray(dir: &Path, kind: &str, k: usize) -> image::GrayImage {
    image::open(dir.join(format!("{kind}_{k:05}.png")))
        .unwrap()
        .to_luma8()
}

/// PSNR from a sum of squared errors over `n` values.
fn psnr(se: f64, n: f64) -> f64 {
    -10.0 * (se / n.max(1.0)).log10()
}

/// Frames of the orbit the edits are scored on.
const ORBIT_FRAMES: usize = 24;

/// Render `objects` over `background` along a `frames`-frame orbit and its truth, in
/// `work`; returns (full-frame PSNR over all frames, PSNR inside the true masks of the objects
/// with index in `edited`, worst frame's full-frame PSNR).
fn score(
    work: &Path,
    background: &Path,
    frames: usize,
    objects: serde_json::Value,
    edited: &[u8],
) -> (f64, f64, f64) {
    std::fs::create_dir_all(work).unwrap();
    let edit = work.join("edit.json");
    let doc = json!({"version": 1, "background": {"model": s(background)},
        "objects": objects});
    std::fs::write(&edit, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    let path = work.join("camera_path.json");
    demo_orbit(frames, 320, 240)
        .unwrap()
        .write(&path, &PathFrame::Data)
        .unwrap();
    let (ours, truth) = (work.join("render"), work.join("truth"));
    run(&[
        "render-edit",
        s(&edit),
        "--path",
        s(&path),
        "--out",
        s(&ours),
        "--passes",
        "rgb,index",
        "--no-video",
    ]);
    let _ = std::fs::remove_dir_all(&truth);
    run(&[
        "demo-scene",
        "--edit",
        s(&edit),
        "--path",
        s(&path),
        "--out",
        s(&truth),
    ]);
    let (mut se, mut n, mut se_m, mut n_m, mut worst) = (0.0, 0.0, 0.0, 0.0, f64::INFINITY);
    for k in 0..frames {
        let (a, b, idx) = (rgb(&ours, k), rgb(&truth, k), gray(&truth, "index", k));
        let (mut fse, mut fn_) = (0.0, 0.0);
        for ((p, q), i) in a.pixels().zip(b.pixels()).zip(idx.pixels()) {
            let e: f64 = (0..3)
                .map(|c| ((p[c] as f64 - q[c] as f64) / 255.0).powi(2))
                .sum();
            fse += e;
            fn_ += 3.0;
            if edited.contains(&i[0]) {
                se_m += e;
                n_m += 3.0;
            }
        }
        worst = worst.min(psnr(fse, fn_));
        se += fse;
        n += fn_;
    }
    (psnr(se, n), psnr(se_m, n_m), worst)
}

/// Issue 16's edits (a)-(e) of the demo scene on a 24-frame orbit against the exact truth:
/// full-frame PSNR >= 26 dB and >= 24 dB inside the edited object's true mask.
#[test]
#[ignore = "slow (trains the demo fields): cargo test --release --test render_edit_quality -- --ignored"]
fn demo_edits_against_exact_truth() {
    let f = fields();
    let (mug, torus) = (s(&f.mug), s(&f.torus));
    // The mug's base centre: turning and scaling keep it standing on the floor.
    let pivot = [-0.42, 0.32, 0.0];
    let q90 = json!({"w": 0.5f64.sqrt(), "x": 0.0, "y": 0.0, "z": 0.5f64.sqrt()});
    let in_place = json!({"name": "torus", "model": torus});
    let cases: Vec<(&str, serde_json::Value, Vec<u8>)> = vec![
        (
            "a_nothing_edited",
            json!([{"name": "mug", "model": mug}, in_place]),
            vec![1, 2],
        ),
        (
            "b_moved_and_turned",
            json!([{"name": "mug", "model": mug, "pivot": pivot, "translation": [0.15, 0.0, 0.0],
                "rotation": q90}, in_place]),
            vec![1],
        ),
        (
            "c_scaled",
            json!([{"name": "mug", "model": mug, "pivot": pivot, "scale": 1.5}, in_place]),
            vec![1],
        ),
        (
            "d_duplicated",
            json!([{"name": "mug", "model": mug}, in_place,
                {"name": "mug.001", "model": mug, "pivot": pivot, "translation": [0.5, 0.25, 0.0],
                 "rotation": q90}]),
            vec![3],
        ),
        (
            "e_torus_blue",
            json!([{"name": "mug", "model": mug},
                {"name": "torus", "model": torus, "recolour": {"target": "#2050ff", "strength": 1.0}}]),
            vec![2],
        ),
    ];
    let mut failed = Vec::new();
    for (name, objects, edited) in cases {
        let work = f.scene.parent().unwrap().join("runs").join(name);
        let (full, masked, worst) = score(&work, &f.background, ORBIT_FRAMES, objects, &edited);
        eprintln!(
            "{name}: full frame {full:.2} dB (worst frame {worst:.2}), inside the edited object's true mask {masked:.2} dB"
        );
        common::figure(
            &format!("render_edit.{name}.full_frame_psnr_db"),
            full,
            26.0,
            true,
        );
        common::figure(
            &format!("render_edit.{name}.inside_psnr_db"),
            masked,
            24.0,
            true,
        );
        if full < 26.0 || masked < 24.0 {
            failed.push(name);
        }
    }
    assert!(failed.is_empty(), "below 26 / 24 dB: {failed:?}");
}

/// The box (min, max) of the cells of `f` whose densest corner makes one finest voxel at least
/// half opaque: the object's visible extent.
fn opaque_extent(f: &objnerf::field::Field) -> (DVec3, DVec3) {
    let shift = f.shift();
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for c in f.occupied_cell_list() {
        let dense = (0..8).any(|i| {
            let v = f
                .grid
                .vertex_slot(c[0] + (i & 1), c[1] + ((i >> 1) & 1), c[2] + (i >> 2));
            v != u32::MAX
                && 1.0
                    - (-objnerf::field::activation::softplus(f.grid.density(v as usize) + shift))
                        .exp()
                    >= 0.5
        });
        if dense {
            let p = f.cell_center(c).as_dvec3();
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    (lo, hi)
}

fn depth_exr(dir: &Path, k: usize) -> Vec<f32> {
    objnerf::scene::io::read_depth(&dir.join(format!("depth_{k:05}.exr")), 1.0)
        .unwrap()
        .metres
}

/// lego (its field from the images' alpha) inserted into the demo scene, standing 0.3 m tall on
/// the floor among the mug and the torus: in every frame of the orbit the object-index pass of
/// lego matches its truth silhouette with IoU >= 0.9. The truth silhouette: lego's field rendered
/// alone under the same transform (opacity >= 1/2), where it is nearer than the demo scene's exact
/// depth (the ray tracer's surface, with the mug and the torus where the edit keeps them), i.e.
/// lego as the composite should show it in front of and behind the scene's true geometry.
#[test]
#[ignore = "slow (trains the demo fields): cargo test --release --test render_edit_quality -- --ignored"]
fn lego_inserted_into_the_demo_scene() {
    let Some(lego) = common::shared_data("lego") else {
        return;
    };
    let f = fields();
    let dir = f.scene.parent().unwrap().to_path_buf();
    let model = dir.join("lego.objf");
    if !model.is_file() {
        let steps = LEGO_STEPS.to_string();
        run(&[
            "train",
            s(&lego.join("transforms_train.json")),
            "--masks",
            "alpha",
            "--downscale",
            "4",
            "--steps",
            &steps,
            "--out",
            s(&model),
        ]);
    }
    let field = objnerf::field::io::load_field(&model).unwrap().field;
    let (lo, hi) = opaque_extent(&field);
    let height = hi.z - lo.z;
    // 0.3 m tall, its base centre on the floor at (0.45, -0.55): free floor beside the box.
    let k = 0.3 / height;
    let pivot = [0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), lo.z];
    let spot = [0.45, -0.55, 0.0];
    let lego_obj = json!({"name": "lego", "model": s(&model), "metres_per_unit": k, "pivot": pivot,
        "translation": [spot[0] - k * pivot[0], spot[1] - k * pivot[1], spot[2] - k * pivot[2]]});
    eprintln!("lego: opaque extent {lo:.3} .. {hi:.3}, {k:.4} m per unit, pivot {pivot:.3?}");
    let work = dir.join("runs/lego");
    std::fs::create_dir_all(&work).unwrap();
    let path = work.join("camera_path.json");
    demo_orbit(ORBIT_FRAMES, 320, 240)
        .unwrap()
        .write(&path, &PathFrame::Data)
        .unwrap();
    let write = |name: &str, doc: serde_json::Value| {
        let p = work.join(name);
        std::fs::write(&p, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
        p
    };
    let (mug, torus) = (s(&f.mug), s(&f.torus));
    let scene_objects = json!([{"name": "mug", "model": mug}, {"name": "torus", "model": torus}]);
    let mut with_lego = scene_objects.clone();
    with_lego.as_array_mut().unwrap().push(lego_obj.clone());
    let bg = json!({"model": s(&f.background)});
    let composite = write(
        "edit.json",
        json!({"version": 1, "background": bg, "objects": with_lego}),
    );
    let alone = write(
        "alone.json",
        json!({"version": 1, "background": {"color": "#ffffff"},
        "objects": [lego_obj]}),
    );
    let truth_edit = write(
        "truth.json",
        json!({"version": 1, "background": bg,
        "objects": scene_objects}),
    );
    let (ours, solo, truth) = (work.join("render"), work.join("alone"), work.join("truth"));
    for (e, out) in [(&composite, &ours), (&alone, &solo)] {
        run(&[
            "render-edit",
            s(e),
            "--path",
            s(&path),
            "--out",
            s(out),
            "--passes",
            "rgb,depth,index",
        ]);
    }
    let _ = std::fs::remove_dir_all(&truth);
    run(&[
        "demo-scene",
        "--edit",
        s(&truth_edit),
        "--path",
        s(&path),
        "--out",
        s(&truth),
    ]);
    let mut ious = Vec::new();
    for k in 0..ORBIT_FRAMES {
        let (idx, solo_idx) = (gray(&ours, "index", k), gray(&solo, "index", k));
        let (solo_d, true_d) = (depth_exr(&solo, k), depth_exr(&truth, k));
        let (mut i, mut u) = (0, 0);
        for (j, (p, b)) in idx.pixels().zip(solo_idx.pixels()).enumerate() {
            let want = b[0] == 1 && solo_d[j] < true_d[j];
            let got = p[0] == 3;
            i += (want && got) as usize;
            u += (want || got) as usize;
        }
        ious.push(if u == 0 { 1.0 } else { i as f64 / u as f64 });
    }
    let worst = ious.iter().cloned().fold(1.0, f64::min);
    eprintln!(
        "lego's object-index pass vs its truth silhouette: min IoU {worst:.3}, mean {:.3}; frames in {}",
        ious.iter().sum::<f64>() / ORBIT_FRAMES as f64,
        ours.display()
    );
    common::figure(
        "render_edit.lego_inserted.worst_index_iou",
        worst,
        0.9,
        true,
    );
    assert!(worst >= 0.9, "IoU per frame: {ious:.3?}");
}

/// What a user does on the demo, every stage at its defaults: one click extracts the mug
/// (`extract`, 60 s), `remove` takes it out, and `render-edit` draws it moved 0.15 m over the
/// background along an 8-frame orbit at 320x240, scored against `demo-scene --edit`'s exact
/// truth: >= 28 dB full frame (issue 53; 25.87 dB when it was filed). Needs the SAM models.
#[test]
#[ignore = "slow (~10 min; its figure needs an idle machine): cargo test --release --test render_edit_quality the_users_path -- --ignored"]
fn the_users_path_on_the_demo() {
    if !common::sam_installed() {
        common::skip("the SAM models are not installed (objnerf models install)");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let dir = match std::env::var_os("OBJNERF_USER_PATH") {
        Some(d) => PathBuf::from(d),
        None => tmp.path().to_path_buf(),
    };
    let (scene, run_dir, removed) = (dir.join("scene"), dir.join("run"), dir.join("removed"));
    if !scene.join("truth").is_dir() {
        run(&["demo-scene", "--out", s(&scene)]);
    }
    let truth = objnerf::demo::read_truth(&scene).unwrap();
    let mug = truth.iter().find(|t| t.name == "mug").unwrap();
    let point = format!("{},{}", mug.click[0], mug.click[1]);
    if !run_dir.join("mug/model.objf").is_file() {
        run(&[
            "extract",
            s(&scene),
            "--view",
            &mug.view,
            "--object",
            "mug",
            "--point",
            &point,
            "--out",
            s(&run_dir),
            "--time-budget",
            "60",
        ]);
    }
    if !removed.join("background.objf").is_file() {
        run(&[
            "remove",
            s(&scene),
            "--segment",
            s(&run_dir.join("segment")),
            "--object",
            "mug",
            "--out",
            s(&removed),
        ]);
    }
    let objects = json!([{"name": "mug", "model": s(&run_dir.join("mug/model.objf")),
        "translation": [0.15, 0.0, 0.0]}]);
    let work = dir.join("edit");
    let (full, masked, worst) = score(&work, &removed.join("background.objf"), 8, objects, &[1]);
    eprintln!(
        "the user's path: full frame {full:.2} dB (worst frame {worst:.2}), inside the moved mug's true mask {masked:.2} dB; frames in {}",
        work.display()
    );
    common::figure("users_path.full_frame_psnr_db", full, 28.0, true);
    assert!(full >= 28.0, "full frame {full:.2} dB < 28");
}
