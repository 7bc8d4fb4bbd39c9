//! The GPU renderer (wgpu, `src/render/gpu/`) against the CPU renderer: the same frames from
//! both, on the demo's fields (an SH object, a colour-network object with the reflected
//! direction and a second layer) and on lego when `../shared/data/lego` is there, for one field
//! (`render`/`eval`'s views, one and 2x2 rays a pixel) and several (`render-edit`'s composite:
//! a background field, objects moved, turned, scaled, duplicated and recoloured), every pass.
//! Per frame: RGB mean absolute difference <= 1e-3 and max <= 1/255 (on a software device, where
//! only rounding may differ, 1e-5, or 1e-4 with a recoloured layer: `tolerance`), alpha the same, depth
//! within 1e-4 of the scene's size, the object index identical except where two layers' weights
//! tie. And `objnerf render-edit --device gpu|auto` through the binary, and that a march the
//! device ends early (llvmpipe's loop budget) is an error rather than a wrong frame.
//!
//! Without a GPU, on Mesa's lavapipe (software Vulkan; `scripts/setup` installs Debian's
//! `mesa-vulkan-drivers`). No Vulkan adapter at all is a failure, with the reason.

mod common;

use common::{objnerf_bin, shared_data};
use glam::{DQuat, DVec3};
use objnerf::demo::edit_truth::demo_orbit;
use objnerf::demo::fields::{write_object_field, DemoFieldOptions};
use objnerf::demo::{write_demo_scene, DemoOptions};
use objnerf::edit::recolour::Recolour;
use objnerf::edit::Similarity;
use objnerf::field::eval::{render_view, Rendered};
use objnerf::field::io::load;
use objnerf::field::{self, Field, FieldConfig, MaskSource, RayCamera, RenderOptions, SetupConfig};
use objnerf::pipeline::render_edit::RenderEditOptions;
use objnerf::render::composite::{render_frame, render_ray, Composite, Frame, Layer, Scratch};
use objnerf::render::gpu::{single, Gpu};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The adapter the parity is checked on: `gpu`'s choice (hardware first, else lavapipe).
fn gpu() -> &'static Gpu {
    static G: OnceLock<Gpu> = OnceLock::new();
    G.get_or_init(|| match Gpu::open(true) {
        Ok(g) => {
            eprintln!("GPU parity on {}", g.name());
            g
        }
        Err(e) => panic!(
            "FAIL: no Vulkan adapter to check the GPU renderer on: {e}. \
             `bash scripts/setup` installs Mesa's lavapipe (mesa-vulkan-drivers)."
        ),
    })
}

/// The demo scene, its mug as an SH field and its torus as a network-coloured field (with the
/// reflected direction and a second hidden layer), trained briefly: what matters is that both
/// renderers draw the same fields.
fn demo_fields() -> &'static (tempfile::TempDir, Field, Field) {
    static F: OnceLock<(tempfile::TempDir, Field, Field)> = OnceLock::new();
    F.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let scene = tmp.path().join("demo");
        write_demo_scene(&DemoOptions::default(), &scene).unwrap();
        let mug = tmp.path().join("mug.objf");
        write_object_field(&scene, "mug", &DemoFieldOptions::steps(300), &mug).unwrap();
        let mut net = DemoFieldOptions::steps(300);
        net.fit.setup = SetupConfig {
            net_features: 8,
            net_hidden: 32,
            net_min_views: 0,
            net_reflect: true,
            net_hidden2: 8,
            net_hidden2_min_view_pixels: 0,
            ..net.fit.setup.clone()
        };
        let torus = tmp.path().join("torus.objf");
        write_object_field(&scene, "torus", &net, &torus).unwrap();
        let (mug, torus) = (load(&mug).unwrap().field, load(&torus).unwrap().field);
        assert!(mug.net.is_none(), "the mug is SH-coloured");
        let n = torus.net.as_ref().expect("the torus is network-coloured");
        assert!(n.refl_terms > 0 && n.hidden2 > 0, "{n:?}");
        (tmp, mug, torus)
    })
}

/// Lego at 50x50 (every 10th training view), SH and network colour, 80 steps each.
fn lego_fields() -> Option<&'static (Vec<RayCamera>, Field, Field)> {
    static F: OnceLock<Option<(Vec<RayCamera>, Field, Field)>> = OnceLock::new();
    F.get_or_init(|| {
        let dir = shared_data("lego")?;
        let mut scene = objnerf::Scene::load(&dir.join("transforms_train.json")).unwrap();
        scene.images = scene.images.into_iter().step_by(10).collect();
        let views = field::load_views(&scene, &MaskSource::Alpha, 16).unwrap();
        let train = |setup: SetupConfig| {
            let cfg = field::TrainConfig {
                seed: 7,
                batch: 2048,
                steps: 80,
                ..Default::default()
            };
            let (mut t, rays, _) = field::prepare(&views, &[], &setup, cfg, None).unwrap();
            for _ in 0..80 {
                t.train_step(&views, &rays);
            }
            t.field
        };
        let sh = train(SetupConfig::default());
        let net = train(SetupConfig {
            net_features: 8,
            net_hidden: 32,
            net_min_views: 0,
            ..Default::default()
        });
        let test = objnerf::Scene::load(&dir.join("transforms_test.json")).unwrap();
        let cams = RayCamera::for_scene(&test, 16)
            .into_iter()
            .step_by(50)
            .collect();
        Some((cams, sh, net))
    })
    .as_ref()
}

/// Demo cameras: an orbit around the demo's objects.
fn demo_cams(n: usize, w: u32, h: u32) -> Vec<RayCamera> {
    demo_orbit(n, w, h)
        .unwrap()
        .cameras
        .iter()
        .enumerate()
        .map(|(k, c)| RayCamera::new(format!("{k}"), c.camera.clone(), c.pose))
        .collect()
}

/// RGB: (mean abs difference, max abs difference) over every channel of every pixel.
fn rgb_diff(a: &[[f32; 3]], b: &[[f32; 3]]) -> (f64, f32) {
    let (mut sum, mut max) = (0f64, 0f32);
    for (p, q) in a.iter().zip(b) {
        for c in 0..3 {
            let d = (p[c] - q[c]).abs();
            sum += d as f64;
            max = max.max(d);
        }
    }
    (sum / (3 * a.len()).max(1) as f64, max)
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// Depths equal within `tol` (both infinite counts as equal); the number that are not.
fn depth_misses(a: &[f32], b: &[f32], tol: f32) -> usize {
    a.iter()
        .zip(b)
        .filter(|(x, y)| !((x.is_infinite() && y.is_infinite()) || (*x - *y).abs() <= tol))
        .count()
}

/// The largest RGB (and alpha) difference a pixel may show. On a hardware GPU, whose exp and log
/// are not correctly rounded, the 1/255. On a software device (lavapipe: LLVM's f32,
/// the CPU's operations in the CPU's order) only rounding differs: 1e-5, ten times the most
/// measured (1.5e-6, SH and network fields alike); 1e-4 where a layer is recoloured, since
/// the OKLab and sRGB curves there are WGSL's pow against the CPU's cbrt and powf and the sRGB
/// curve's slope near black (up to 12.92 / 2.4 x^-0.58) magnifies their last-bit differences
/// (measured 4.5e-5).
fn tolerance(recoloured: bool) -> f32 {
    match (gpu().is_software(), recoloured) {
        (false, _) => 1.0 / 255.0,
        (true, false) => 1e-5,
        (true, true) => 1e-4,
    }
}

fn check_rgb(what: &str, cpu: &[[f32; 3]], gpu: &[[f32; 3]], tol: f32) {
    let (mean, max) = rgb_diff(cpu, gpu);
    eprintln!("{what}: rgb mean |diff| {mean:.2e}, max {max:.2e}");
    let off = cpu.iter().zip(gpu).enumerate();
    let off = off.filter(|(_, (p, q))| (0..3).any(|c| (p[c] - q[c]).abs() > tol));
    for (i, (p, q)) in off.take(10) {
        eprintln!("  pixel {i}: cpu {p:?} gpu {q:?}");
    }
    assert!(mean <= 1e-3, "{what}: rgb mean |diff| {mean}");
    assert!(max <= tol, "{what}: rgb max |diff| {max} over {tol}");
}

fn check_view(what: &str, cpu: &Rendered, gpu: &Rendered, size: f32) {
    let tol = tolerance(false);
    check_rgb(what, &cpu.rgb, &gpu.rgb, tol);
    let a = max_diff(&cpu.alpha, &gpu.alpha);
    assert!(a <= tol, "{what}: alpha max |diff| {a} over {tol}");
    let bad = depth_misses(&cpu.depth, &gpu.depth, 1e-4 * size);
    eprintln!("{what}: alpha max |diff| {a:.2e}, depth off in {bad} pixels");
    assert_eq!(bad, 0, "{what}: depth differs by more than 1e-4 of {size}");
}

/// Whether the CPU's object index at pixel `i` is a tie: the two largest layer weights (the
/// background's with what shows through) within 1e-4.
fn is_tie(c: &Composite, cam: &RayCamera, i: u32) -> bool {
    let (o, d) = cam.ray(i);
    let mut s = Scratch::default();
    let p = render_ray(c, o, d, &mut s);
    let mut bg = 1.0 - p.alpha;
    let mut objects = Vec::new();
    for (l, w) in c.layers.iter().zip(s.weights()) {
        if l.index == 0 {
            bg += w;
        } else {
            objects.push(*w);
        }
    }
    objects.push(bg);
    objects.sort_by(|a, b| b.total_cmp(a));
    objects.len() > 1 && objects[0] - objects[1] <= 1e-4
}

/// `recoloured`: whether a layer of `c` is recoloured (see [`tolerance`]).
fn check_frame(what: &str, c: &Composite, cam: &RayCamera, size: f32, recoloured: bool) {
    let cpu: Frame = render_frame(c, cam);
    let up = gpu().upload(c).unwrap();
    let gpu_frame = up.render_frame(cam).unwrap();
    let tol = tolerance(recoloured);
    check_rgb(what, &cpu.rgb, &gpu_frame.rgb, tol);
    let a = max_diff(&cpu.alpha, &gpu_frame.alpha);
    assert!(a <= tol, "{what}: alpha max |diff| {a} over {tol}");
    let bad = depth_misses(&cpu.depth, &gpu_frame.depth, 1e-4 * size);
    let mut index_off = 0;
    for (i, (p, q)) in cpu.index.iter().zip(&gpu_frame.index).enumerate() {
        if p != q {
            assert!(
                is_tie(c, cam, i as u32),
                "{what}: index {p} vs {q} at pixel {i}"
            );
            index_off += 1;
        }
    }
    let drawn = cpu.alpha.iter().filter(|a| **a > 0.5).count();
    eprintln!(
        "{what}: alpha max |diff| {a:.2e}, depth off in {bad} pixels, index differs in \
         {index_off} (ties), {drawn} opaque pixels"
    );
    assert!(drawn > 0, "{what}: nothing drawn; the check would be empty");
    assert_eq!(bad, 0, "{what}: depth differs by more than 1e-4 of {size}");
}

/// The diagonal of a field's box (its scene's size).
fn size_of(f: &Field) -> f32 {
    (f.box_max - f.box_min).length()
}

fn views_match(what: &str, f: &Field, opt: &RenderOptions, cams: &[RayCamera], bg: [f32; 3]) {
    let c = single(f, opt, bg);
    let up = gpu().upload(&c).unwrap();
    for (k, cam) in cams.iter().enumerate() {
        let cpu = render_view(f, opt, cam, bg);
        let g = up.render_view(cam).unwrap();
        check_view(&format!("{what}, view {k}"), &cpu, &g, size_of(f));
    }
}

#[test]
fn one_sh_field_renders_the_same_on_both() {
    let (_, mug, _) = demo_fields();
    let cams = demo_cams(3, 160, 120);
    views_match("mug (SH)", mug, &RenderOptions::default(), &cams, [1.0; 3]);
    // 2x2 rays a pixel, a coloured background, the render-edit sampling.
    let opt = RenderOptions {
        pixel_samples: 2,
        ..RenderEditOptions::default().render
    };
    views_match("mug (SH) 2x2", mug, &opt, &cams[..1], [0.2, 0.4, 0.9]);
}

#[test]
fn one_network_field_renders_the_same_on_both() {
    let (_, _, torus) = demo_fields();
    let cams = demo_cams(3, 160, 120);
    views_match(
        "torus (net)",
        torus,
        &RenderOptions::default(),
        &cams,
        [1.0; 3],
    );
}

/// The composite of render-edit: a background field (the torus, index 0), the mug moved and
/// turned (1), scaled up and recoloured towards a target (2), scaled down with its hue turned
/// (3), and the torus again moved (4), over a plain colour.
#[test]
fn several_fields_composite_the_same_on_both() {
    let (_, mug, torus) = demo_fields();
    let sim = |t: [f64; 3], angle: f64, scale: f64| Similarity {
        scale,
        rotation: DQuat::from_rotation_z(angle),
        translation: DVec3::from(t),
    };
    let target = Recolour::Target {
        rgb: [0.1, 0.6, 0.9],
        strength: 0.8,
    };
    let hue = Recolour::Hue {
        degrees: 120.0,
        strength: 1.0,
    };
    let render = RenderEditOptions::default().render;
    let c = Composite {
        layers: vec![
            Layer::new(torus, &Similarity::IDENTITY, 0),
            Layer::new(mug, &sim([0.15, 0.0, 0.0], 0.7, 1.0), 1),
            Layer::new(mug, &sim([0.0, 0.3, 0.0], -0.4, 1.3), 2)
                .with_recolour(Some(target.prepare())),
            Layer::new(mug, &sim([-0.2, -0.2, 0.05], 2.0, 0.6), 3)
                .with_recolour(Some(hue.prepare())),
            Layer::new(torus, &sim([0.3, -0.3, 0.0], 1.0, 1.0), 4),
        ],
        background: [0.9, 0.85, 0.8],
        render,
    };
    let size = size_of(torus).max(size_of(mug)) * 2.0;
    for (k, cam) in demo_cams(3, 160, 120).iter().enumerate() {
        check_frame(&format!("composite, frame {k}"), &c, cam, size, true);
    }
    // One object alone in place, at the half-voxel sampling and a small frame.
    let one = Composite {
        layers: vec![Layer::new(mug, &Similarity::IDENTITY, 1)],
        background: [1.0; 3],
        render: RenderOptions::default(),
    };
    for (k, cam) in demo_cams(2, 64, 48).iter().enumerate() {
        check_frame(
            &format!("mug alone, frame {k}"),
            &one,
            cam,
            size_of(mug),
            false,
        );
    }
}

#[test]
fn lego_renders_the_same_on_both() {
    let Some((cams, sh, net)) = lego_fields() else {
        return;
    };
    let opt = RenderOptions::default();
    views_match("lego (SH)", sh, &opt, cams, [1.0; 3]);
    views_match("lego (net)", net, &opt, cams, [1.0; 3]);
    let c = Composite {
        layers: vec![
            Layer::new(sh, &Similarity::IDENTITY, 0),
            Layer::new(
                net,
                &Similarity {
                    scale: 0.5,
                    rotation: DQuat::from_rotation_z(0.5),
                    translation: DVec3::new(0.5, 0.3, 0.6),
                },
                1,
            ),
        ],
        background: [1.0; 3],
        render: RenderEditOptions::default().render,
    };
    for (k, cam) in cams.iter().enumerate() {
        check_frame(
            &format!("lego composite, view {k}"),
            &c,
            cam,
            size_of(sh),
            false,
        );
    }
}

/// A march that a device ends early is an error naming it, never a wrong frame. Mesa's llvmpipe
/// gives a batch of rays 65535 loop iterations over all loops and then ends every loop: a wide
/// network (27 features, 128 + 128 hidden units, reflection) over the torus's box, every sample
/// faint (alpha_init 0.01), so that a ray colours some 200 samples, is far past that. On a
/// hardware GPU, which has no such limit, the frame matches the CPU's.
#[test]
fn a_march_the_device_ends_early_is_an_error() {
    let (_, _, torus) = demo_fields();
    let voxel = (torus.box_max - torus.box_min).max_element() / 64.0;
    let config = FieldConfig {
        sh_degree: 3,
        alpha_init: 0.01,
        base_voxel: voxel,
    };
    let dims = Field::dims_for(torus.box_min, torus.box_max, voxel);
    let f = Field::new(config, torus.box_min, torus.box_max, dims).with_colour_net(
        27,
        [128, 128],
        true,
        5,
    );
    let opt = RenderOptions::default();
    let cams = demo_cams(1, 16, 12);
    let c = single(&f, &opt, [1.0; 3]);
    match gpu().upload(&c).unwrap().render_view(&cams[0]) {
        Err(e) => {
            let msg = e.to_string();
            eprintln!("wide network on {}: {msg}", gpu().name());
            assert!(gpu().is_software(), "a hardware GPU cut the march: {msg}");
            assert!(msg.contains("ended the march's loops early"), "{msg}");
        }
        Ok(g) => {
            assert!(!gpu().is_software(), "{} drew it whole", gpu().name());
            let cpu = render_view(&f, &opt, &cams[0], [1.0; 3]);
            check_view("wide network", &cpu, &g, size_of(&f));
        }
    }
}

fn write_edit(dir: &Path, mug: &Path) -> PathBuf {
    let p = dir.join("edit.json");
    let doc = serde_json::json!({"version": 1, "background": {"color": "#ffffff"},
        "objects": [{"name": "mug", "model": mug}]});
    std::fs::write(&p, doc.to_string()).unwrap();
    p
}

fn render_edit(edit: &Path, out: &Path, device: &str, env: Option<&str>) -> std::process::Output {
    let mut cmd = Command::new(objnerf_bin());
    cmd.args([
        "render-edit",
        edit.to_str().unwrap(),
        "--orbit",
        "2",
        "--size",
        "64x48",
    ]);
    cmd.args(["--passes", "rgb,alpha,depth,index", "--no-video", "--json"]);
    cmd.args(["--device", device, "--out", out.to_str().unwrap()]);
    if let Some(name) = env {
        cmd.env(objnerf::render::gpu::device::ADAPTER_ENV, name);
    }
    cmd.output().unwrap()
}

/// Through the binary: `--device gpu` draws the frames `--device cpu` does (to 1/255 in 8
/// bits, the index pass identical) and says which adapter; `gpu` with no adapter to take is an
/// error naming what it looked for; `auto` without a hardware adapter falls back and says so.
#[test]
fn render_edit_takes_the_device_asked_for() {
    let (dir, _, _) = demo_fields();
    let edit = write_edit(dir.path(), &dir.path().join("mug.objf"));
    let tmp = tempfile::tempdir().unwrap();
    let (cpu_out, gpu_out) = (tmp.path().join("cpu"), tmp.path().join("gpu"));
    let report = |o: &std::process::Output| -> serde_json::Value {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let c = report(&render_edit(&edit, &cpu_out, "cpu", None));
    assert_eq!(c["device"]["device"], "cpu");
    let g = report(&render_edit(&edit, &gpu_out, "gpu", None));
    assert_eq!(g["device"]["device"], "gpu", "{g}");
    assert!(g["device"]["adapter"].is_string(), "{g}");
    for k in 0..2 {
        for kind in ["frame", "alpha", "index"] {
            let name = format!("{kind}_{k:05}.png");
            let a = image::open(cpu_out.join(&name)).unwrap().to_rgb8();
            let b = image::open(gpu_out.join(&name)).unwrap().to_rgb8();
            let worst = a
                .as_raw()
                .iter()
                .zip(b.as_raw())
                .map(|(x, y)| x.abs_diff(*y))
                .max()
                .unwrap();
            let most = if kind == "index" { 0 } else { 1 };
            assert!(worst <= most, "{name}: 8-bit values differ by {worst}");
        }
    }
    let none = render_edit(
        &edit,
        &tmp.path().join("none"),
        "gpu",
        Some("no-such-adapter"),
    );
    assert!(!none.status.success());
    let err = String::from_utf8_lossy(&none.stderr);
    assert!(
        err.contains("no-such-adapter") && err.contains("Vulkan"),
        "the error names what it looked for: {err}"
    );
    let auto = report(&render_edit(&edit, &tmp.path().join("auto"), "auto", None));
    if !gpu().is_software() {
        assert_eq!(auto["device"]["device"], "gpu", "{auto}");
    } else {
        assert_eq!(auto["device"]["device"], "cpu", "{auto}");
        let note = auto["device"]["note"].as_str().unwrap_or_default();
        assert!(note.contains("hardware"), "auto says why: {auto}");
    }
}
