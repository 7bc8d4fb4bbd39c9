//! Textured, decimated meshes against the full vertex-coloured one: PSNR inside the true mask at
//! the held-out views (drawn by objnerf's own rasteriser, `mesh::raster`), triangles, .glb size,
//! Chamfer distance to the full mesh and export time, over triangle budgets and texture sizes.
//! Then `objnerf mesh` at the defaults in its own process, for the time and peak memory of an
//! export as a user runs it.
//!
//!     objnerf demo --out runs/demo            # the demo mug, its held-out views and truth masks
//!     cargo run --release --example textured_mesh_bench -- --run runs/demo [--object mug]
//!     objnerf train ../shared/data/lego/transforms_train.json --masks alpha --downscale 2 \
//!         --time-budget 240 --out runs/lego.objf
//!     target/release/examples/textured_mesh_bench --model runs/lego.objf --name textured_mesh_lego \
//!         --scene ../shared/data/lego/transforms_test.json --every 20 --downscale 2
//!
//! `--run` is an `objnerf demo` folder (scene/ with truth/masks, run/<object>/model.objf, and
//! run/report.json naming the held-out views); `--model` with `--scene` scores on every
//! `--every`-th view of a scene the model was not trained on, its mask the images' alpha (or, with
//! `--held-out RUN/report.json --masks RUN/segment/masks/OBJECT`, the views an extract run held
//! out, inside their segmented masks).
//! Writes `NAME.json` and `NAME.svg` (`--name`, default textured_mesh) into `--out` (default
//! examples/results); `--renders DIR` also writes each mesh drawn at the first three views under
//! the photos (inside the mask), to look at; `--budgets-only` measures the full mesh and
//! `--budgets` alone (printed, no JSON), each at the first of `--textures` where it is given.

#[path = "support/bench.rs"]
mod bench;

use bench::{git_commit, machine, run_objnerf};
use objnerf::field::{load_views, MaskSource};
use objnerf::mesh::chamfer::chamfer_distance;
use objnerf::mesh::colour::view_centres;
use objnerf::mesh::decimate::DEFAULT_TOLERANCE_VOXELS;
use objnerf::mesh::frame::GltfFrame;
use objnerf::mesh::from_field::{mesh_field, FieldMeshOptions};
use objnerf::mesh::raster::masked_psnr;
use objnerf::mesh::textured::{export_mesh, ExportOptions, TextureSize};
use objnerf::mesh::{io::write_mesh, Mesh};
use objnerf::util::chart::{palette, svg, Layer, Panel};
use objnerf::Scene;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// One exported variant, measured.
#[derive(serde::Serialize)]
struct Variant {
    budget: Option<usize>,
    texture: Option<u32>,
    triangles: usize,
    psnr_in_mask: f64,
    glb_bytes: u64,
    chamfer_to_full: f64,
    chamfer_to_full_fraction_of_diagonal: f64,
    /// To the true mesh, where there is one (the demo), as a fraction of its box diagonal.
    chamfer_to_truth_fraction_of_diagonal: Option<f64>,
    export_seconds: f64,
    atlas_utilization: Option<f32>,
}

struct Setup {
    truth: Option<(Mesh, f64)>,
    field: objnerf::field::Field,
    mesh_opts: FieldMeshOptions,
    full: Mesh,
    frame: GltfFrame,
    views: Vec<objnerf::field::View>,
    diag: f64,
    /// `--renders DIR`: where each variant's first views are written beside the photos.
    renders: Option<PathBuf>,
}

/// The first three views: the photos inside their masks over white (top), the mesh as the
/// rasteriser scores it (bottom), side by side, as `dir/name.png`.
fn save_renders(mesh: &Mesh, views: &[objnerf::field::View], dir: &Path, name: &str) {
    let shown = &views[..views.len().min(3)];
    let Some(first) = shown.first() else { return };
    let (w, h) = (first.cam.width, first.cam.height);
    let mut sheet =
        image::RgbImage::from_pixel(w * shown.len() as u32, 2 * h, image::Rgb([255; 3]));
    for (k, v) in shown.iter().enumerate() {
        let drawn = objnerf::mesh::raster::render_mesh(mesh, &v.cam);
        for (i, (px, target)) in drawn.iter().zip(&v.rgba).enumerate() {
            let (x, y) = (k as u32 * w + i as u32 % w, i as u32 / w);
            if target[3] == 255 {
                sheet.put_pixel(x, y, image::Rgb([target[0], target[1], target[2]]));
                let c = px
                    .unwrap_or([1.0; 3])
                    .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
                sheet.put_pixel(x, y + h, image::Rgb(c));
            }
        }
    }
    std::fs::create_dir_all(dir).expect("renders folder");
    sheet
        .save(dir.join(format!("{name}.png")))
        .expect("write renders");
}

fn measure(s: &Setup, opts: &ExportOptions, dir: &Path) -> Variant {
    let t = Instant::now();
    let mesh_opts = FieldMeshOptions {
        export: opts.clone(),
        ..s.mesh_opts.clone()
    };
    let (mesh, report) = export_mesh(
        &s.field,
        &s.full,
        &mesh_opts.export,
        &mesh_opts.seen_from,
        None,
    )
    .expect("export");
    let export_seconds = t.elapsed().as_secs_f64();
    let glb = dir.join("m.glb");
    write_mesh(&mesh, Some(&s.frame), &glb).expect("write glb");
    let cd = chamfer_distance(&mesh, &s.full, 50_000, 7);
    if let Some(r) = &s.renders {
        let name = format!(
            "{}_{}",
            opts.max_triangles.map_or("full".into(), |b| b.to_string()),
            opts.texture.map_or("vertex_colours".into(), |t| match t {
                TextureSize::Auto => "texture_auto".into(),
                TextureSize::Side(n) => format!("texture_{n}"),
            })
        );
        save_renders(&mesh, &s.views, r, &name);
    }
    let v = Variant {
        budget: opts.max_triangles,
        texture: report.atlas.as_ref().map(|a| a.size),
        triangles: mesh.triangles.len(),
        psnr_in_mask: masked_psnr(&mesh, &s.views),
        glb_bytes: std::fs::metadata(&glb).map(|m| m.len()).unwrap_or(0),
        chamfer_to_full: cd,
        chamfer_to_full_fraction_of_diagonal: cd / s.diag,
        chamfer_to_truth_fraction_of_diagonal: s
            .truth
            .as_ref()
            .map(|(t, d)| chamfer_distance(&mesh, t, 50_000, 7) / d),
        export_seconds,
        atlas_utilization: report.atlas.as_ref().map(|a| a.utilization),
    };
    eprintln!(
        "budget {:?} texture {:?}: {} triangles, {:.2} dB, {} kB, Chamfer {:.3}% diag (truth {:?}), {:.1} s",
        v.budget,
        v.texture,
        v.triangles,
        v.psnr_in_mask,
        v.glb_bytes / 1000,
        100.0 * v.chamfer_to_full_fraction_of_diagonal,
        v.chamfer_to_truth_fraction_of_diagonal.map(|c| 100.0 * c),
        v.export_seconds
    );
    v
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let run = arg(&args, "--run").map(PathBuf::from);
    let object = arg(&args, "--object").unwrap_or_else(|| {
        arg(&args, "--model")
            .and_then(|m| Some(Path::new(&m).file_stem()?.to_string_lossy().to_string()))
            .unwrap_or_else(|| "mug".into())
    });
    let out = PathBuf::from(arg(&args, "--out").unwrap_or_else(|| "examples/results".into()));
    let budgets: Vec<usize> = arg(&args, "--budgets")
        .unwrap_or_else(|| "1000,2000,3000,5000,10000,50000".into())
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let textures: Vec<u32> = arg(&args, "--textures")
        .unwrap_or_else(|| "256,512,1024,2048,4096".into())
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;

    let (model_path, views) = match &run {
        Some(run) => demo_views(run, &object)?,
        None => capture_views(&args)?,
    };
    let model = objnerf::field::io::load_field(&model_path)?;
    let frame = GltfFrame::for_model(&model, None)?;
    let up = glam::DVec3::from_array(frame.up);
    let t = Instant::now();
    let mut mesh_opts = FieldMeshOptions {
        seen_from: view_centres(&model.notes),
        ..Default::default()
    };
    if let Some(m) = arg(&args, "--min-component") {
        mesh_opts.min_component = m.parse()?;
    }
    if let Some(m) = arg(&args, "--iso") {
        mesh_opts.iso_alpha = m.parse()?;
    }
    if mesh_opts.seen_from.is_empty() {
        return Err(
            "the model records no training cameras (trained before they were): train it again"
                .into(),
        );
    }
    let (full, _) = mesh_field(&model.field, &object, &mesh_opts, Some(up))?;
    let full_seconds = t.elapsed().as_secs_f64();
    let (lo, hi) = full.bounds();
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) as f64;
    let truth = run.as_ref().and_then(|r| {
        let t = objnerf::mesh::io::read_ply(&r.join(format!("scene/truth/meshes/{object}.ply")))
            .ok()?;
        let (lo, hi) = t.bounds();
        let d = glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) as f64;
        Some((t, d))
    });
    let s = Setup {
        truth,
        field: model.field,
        mesh_opts,
        full,
        frame,
        views,
        diag,
        renders: arg(&args, "--renders").map(PathBuf::from),
    };
    let full_psnr = masked_psnr(&s.full, &s.views);
    eprintln!(
        "full mesh: {} triangles, {full_psnr:.2} dB on {} held-out views",
        s.full.triangles.len(),
        s.views.len()
    );
    if args.iter().any(|a| a == "--full-only") {
        if let Some((t, d)) = &s.truth {
            let cd = chamfer_distance(&s.full, t, 50_000, 7) / d;
            eprintln!(
                "full mesh Chamfer to the truth {:.3}% of its diagonal",
                100.0 * cd
            );
        }
        if let Some(r) = &s.renders {
            save_renders(&s.full, &s.views, r, "full_vertex_colours");
        }
        return Ok(());
    }
    let dir = tempfile::tempdir()?;
    let full_vc = measure(
        &s,
        &ExportOptions {
            max_triangles: None,
            texture: None,
            ..Default::default()
        },
        dir.path(),
    );
    let budgets_only = args.iter().any(|a| a == "--budgets-only");
    let default = (!budgets_only).then(|| measure(&s, &ExportOptions::default(), dir.path()));
    let default_side = default.as_ref().and_then(|d| d.texture);
    let mut by_budget = Vec::new();
    let mut by_budget_vc = Vec::new();
    // Budgets alone are measured at the texture asked for, if any (else the automatic size).
    let budget_texture = match arg(&args, "--textures") {
        Some(_) if budgets_only => Some(TextureSize::Side(textures[0])),
        _ => ExportOptions::default().texture,
    };
    for &b in &budgets {
        let o = ExportOptions {
            max_triangles: Some(b),
            fraction_of_full: None,
            texture: budget_texture,
            ..Default::default()
        };
        by_budget.push(measure(&s, &o, dir.path()));
        by_budget_vc.push(measure(
            &s,
            &ExportOptions { texture: None, ..o },
            dir.path(),
        ));
    }
    if budgets_only {
        return Ok(());
    }
    let by_texture: Vec<Variant> = textures
        .iter()
        .map(|&t| {
            let o = ExportOptions {
                texture: Some(TextureSize::Side(t)),
                ..Default::default()
            };
            measure(&s, &o, dir.path())
        })
        .collect();

    // `objnerf mesh` at its defaults, in its own process: time and peak memory of an export.
    let glb = dir.path().join("cli.glb");
    let cli = run_objnerf(&[
        "mesh".into(),
        model_path.display().to_string(),
        "--out".into(),
        glb.display().to_string(),
        "--json".into(),
    ]);
    let stdout = String::from_utf8_lossy(&cli.stdout);
    let json_end = stdout.rfind("\n}").map_or(stdout.len(), |i| i + 2);
    let cli_report: serde_json::Value = serde_json::from_str(&stdout[..json_end])?;

    let (source, mask) = match (&run, arg(&args, "--masks")) {
        (Some(_), _) => ("an objnerf demo run", "the true mask"),
        (None, Some(m)) if m != "alpha" => ("a model", "the segmented mask"),
        (None, _) => ("a model", "the images' alpha"),
    };
    let result = serde_json::json!({
        "what": format!("the {object} of {source}: its full marching-cubes mesh (vertex colours) and exported meshes (decimated to a budget within a {DEFAULT_TOLERANCE_VOXELS}-voxel tolerance, UV atlas, base colour baked from the field), drawn by objnerf's rasteriser (no lighting: the unlit material) at {} views it was not trained on, PSNR over the pixels inside {mask} (uncovered pixels count as white); Chamfer to the full mesh with 50k samples a side", s.views.len()),
        "command": format!("cargo run --release --example textured_mesh_bench -- {}", args[1..].join(" ")),
        "machine": machine(),
        "git_commit": git_commit(),
        "full_mesh": { "triangles": s.full.triangles.len(), "psnr_in_mask": full_psnr, "marching_cubes_seconds": full_seconds, "box_diagonal": diag },
        "full_vertex_coloured": full_vc,
        "default": default,
        "default_texture_size": default_side,
        "by_budget_textured": by_budget,
        "by_budget_vertex_coloured": by_budget_vc,
        "by_texture_size": by_texture,
        "objnerf_mesh_defaults": {
            "seconds": cli_report["seconds"],
            "peak_rss_mib": cli_report["peak_rss_mib"],
            "export": cli_report["export"],
        },
    });
    std::fs::create_dir_all(&out)?;
    let stem = arg(&args, "--name").unwrap_or_else(|| "textured_mesh".into());
    std::fs::write(
        out.join(format!("{stem}.json")),
        serde_json::to_string_pretty(&result)? + "\n",
    )?;
    write_chart(&out.join(format!("{stem}.svg")), &result)?;
    println!("{}", serde_json::to_string_pretty(&result["default"])?);
    Ok(())
}

type Views = (PathBuf, Vec<objnerf::field::View>);

/// A demo run's model and its held-out views with their true masks.
fn demo_views(run: &Path, object: &str) -> Result<Views, Box<dyn std::error::Error>> {
    let scene = Scene::load(&run.join("scene"))?;
    let held = held_out_of(&run.join("run/report.json"))?;
    let masks = MaskSource::Dir(run.join("scene/truth/masks").join(object));
    let views = load_views(&scene, &masks, 1)?
        .into_iter()
        .filter(|v| held.contains(&v.cam.name))
        .collect();
    Ok((run.join("run").join(object).join("model.objf"), views))
}

/// The views an extract or demo run's `report.json` held out of training.
fn held_out_of(report: &Path) -> Result<Vec<String>, Box<dyn std::error::Error>> {
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(report)?)?;
    let held: Vec<String> = report["objects"][0]["segmentation"]["held_out"]
        .as_array()
        .ok_or("report.json names no held-out views")?
        .iter()
        .filter_map(|v| v.as_str().map(str::to_string))
        .collect();
    Ok(held)
}

/// `--model M --scene S [--masks alpha|DIR] [--every N | --held-out REPORT] [--downscale F]`: a
/// model and every N-th view of a scene it was not trained on (lego's test views), masks from
/// the images' alpha; or, with an extract run's `report.json`, the views that run held out of
/// training, masks its segmentation's (`RUN/segment/masks/OBJECT`).
fn capture_views(args: &[String]) -> Result<Views, Box<dyn std::error::Error>> {
    let model = PathBuf::from(arg(args, "--model").ok_or("give --run or --model and --scene")?);
    let scene_path = PathBuf::from(arg(args, "--scene").ok_or("--scene is required")?);
    let every: usize = arg(args, "--every").map_or(Ok(20), |s| s.parse())?;
    let factor: u32 = arg(args, "--downscale").map_or(Ok(1), |s| s.parse())?;
    let scene = Scene::load(&scene_path)?;
    let masks = MaskSource::parse(
        &arg(args, "--masks").unwrap_or_else(|| "alpha".into()),
        &scene_path,
    )?;
    let views = load_views(&scene, &masks, factor)?;
    let views = match arg(args, "--held-out") {
        Some(report) => {
            let held = held_out_of(Path::new(&report))?;
            views
                .into_iter()
                .filter(|v| held.contains(&v.cam.name))
                .collect()
        }
        None => views.into_iter().step_by(every.max(1)).collect(),
    };
    Ok((model, views))
}

fn points(v: &serde_json::Value, x: &str, y: &str, x_scale: f64) -> Vec<(f64, f64)> {
    v.as_array()
        .into_iter()
        .flatten()
        .filter_map(|e| Some((e[x].as_f64()? * x_scale, e[y].as_f64()?)))
        .collect()
}

/// PSNR against triangles and texture size; .glb size against both.
fn write_chart(path: &Path, r: &serde_json::Value) -> Result<(), Box<dyn std::error::Error>> {
    let full = r["full_mesh"]["psnr_in_mask"].as_f64().unwrap_or(0.0);
    let full_tris = r["full_mesh"]["triangles"].as_f64().unwrap_or(0.0) / 1000.0;
    let tex = format!("textured, auto ({} px)", r["default_texture_size"]);
    let budget_psnr = vec![
        Layer::new(
            tex.clone(),
            palette(0),
            points(&r["by_budget_textured"], "triangles", "psnr_in_mask", 1e-3),
        ),
        Layer::new(
            "vertex colours",
            palette(1),
            points(
                &r["by_budget_vertex_coloured"],
                "triangles",
                "psnr_in_mask",
                1e-3,
            ),
        ),
        Layer::new(
            "full mesh, vertex colours",
            palette(2),
            vec![(full_tris, full)],
        )
        .mark(objnerf::util::chart::Mark::Points(5)),
    ];
    let tex_psnr = vec![Layer::new(
        "textured, default budget",
        palette(0),
        points(&r["by_texture_size"], "texture", "psnr_in_mask", 1.0),
    )];
    let budget_size = vec![
        Layer::new(
            tex,
            palette(0),
            points(&r["by_budget_textured"], "triangles", "glb_bytes", 1e-3)
                .into_iter()
                .map(|(x, y)| (x, y / 1e6))
                .collect(),
        ),
        Layer::new(
            "vertex colours",
            palette(1),
            points(
                &r["by_budget_vertex_coloured"],
                "triangles",
                "glb_bytes",
                1e-3,
            )
            .into_iter()
            .map(|(x, y)| (x, y / 1e6))
            .collect(),
        ),
    ];
    let tex_size = vec![Layer::new(
        "textured, default budget",
        palette(0),
        points(&r["by_texture_size"], "texture", "glb_bytes", 1.0)
            .into_iter()
            .map(|(x, y)| (x, y / 1e6))
            .collect(),
    )];
    let panels = [
        Panel::fitted(
            "PSNR in mask vs triangles",
            "thousand triangles",
            "dB",
            budget_psnr,
        ),
        Panel::fitted(
            "PSNR in mask vs texture size",
            "texture side, px",
            "dB",
            tex_psnr,
        ),
        Panel::fitted(
            ".glb size vs triangles",
            "thousand triangles",
            "MB",
            budget_size,
        ),
        Panel::fitted(
            ".glb size vs texture size",
            "texture side, px",
            "MB",
            tex_size,
        ),
    ];
    std::fs::write(path, svg((1100, 800), 2, &panels)?)?;
    Ok(())
}
