//! The `train`, `render` and `eval` commands as library functions (the CLI only parses arguments
//! and draws the progress bar).

use super::eval::{evaluate, render_view, EvalReport};
use super::io::{self, Model, IDENTITY};
use super::rays::{load_views, MaskSource, View};
use super::session::{prepare, run, RunSummary, SetupConfig, SetupReport, StopRule};
use super::train::{StepStats, TrainConfig, Trainer};
use crate::error::{Error, Result};
use crate::util::AtomicDir;
use std::path::{Path, PathBuf};

/// Depth supervision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DepthMode {
    None,
    Sparse,
    Dense,
}

impl std::str::FromStr for DepthMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "none" => Ok(DepthMode::None),
            "sparse" => Ok(DepthMode::Sparse),
            "dense" => Ok(DepthMode::Dense),
            _ => Err(format!("depth must be sparse, dense or none, not '{s}'")),
        }
    }
}

/// Parse `--masks`: `alpha`, `scene` (each view's mask_path), `truth:OBJECT` (the demo scene's
/// `truth/masks/OBJECT/` beside the scene) or a folder of masks.
pub fn parse_masks(s: &str, scene: &Path) -> Result<MaskSource> {
    if s == "alpha" {
        Ok(MaskSource::Alpha)
    } else if s == "scene" {
        Ok(MaskSource::Scene)
    } else if let Some(obj) = s.strip_prefix("truth:") {
        // The scene may be named by its folder or by a file inside it (transforms.json,
        // sparse/0): look upwards for truth/masks/OBJECT.
        let start = if scene.is_dir() {
            scene.to_path_buf()
        } else {
            scene.parent().unwrap_or(Path::new(".")).to_path_buf()
        };
        for dir in start.ancestors() {
            let d = dir.join("truth/masks").join(obj);
            if d.is_dir() {
                return Ok(MaskSource::Dir(d));
            }
        }
        Err(Error::invalid(format!(
            "--masks truth:{obj}: no truth/masks/{obj}/ folder at or above {} (true masks come with the demo scene: objnerf demo-scene)",
            start.display()
        )))
    } else {
        let p = PathBuf::from(s);
        if p.is_dir() {
            Ok(MaskSource::Dir(p))
        } else {
            Err(Error::invalid(format!(
                "--masks {s}: expected 'alpha', 'scene', 'truth:OBJECT' or an existing folder of masks"
            )))
        }
    }
}

#[derive(Clone, Debug)]
pub struct TrainArgs {
    pub scene: PathBuf,
    pub masks: MaskSource,
    pub out: PathBuf,
    pub downscale: u32,
    pub time_budget: Option<f64>,
    pub depth: DepthMode,
    pub seed: u64,
    pub steps: usize,
    pub setup: SetupConfig,
    /// Continue from this model (its grid, step and optimiser state).
    pub resume: Option<PathBuf>,
    /// Views left out of training (e.g. the ones segmentation found obstructed).
    pub exclude_views: Vec<String>,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct TrainReport {
    pub setup: Option<SetupReport>,
    pub run: RunSummary,
    pub vertices: usize,
    pub dims: [usize; 3],
    pub memory_bytes: usize,
    pub occupied_cells: usize,
    pub depth_targets: usize,
}

/// Train a field on a scene's views and save it; `progress(stats, seconds, rays_per_second)`.
pub fn train(args: &TrainArgs, mut progress: impl FnMut(&StepStats, f64)) -> Result<TrainReport> {
    if args.downscale == 0 {
        return Err(Error::invalid("--downscale must be at least 1"));
    }
    let scene = crate::Scene::load(&args.scene)?;
    let mut views = load_views(&scene, &args.masks, args.downscale)?;
    let depth_targets = match args.depth {
        DepthMode::None => 0,
        DepthMode::Sparse => super::depth::add_sparse_depth(&mut views, &scene, args.downscale)?,
        DepthMode::Dense => super::depth::add_dense_depth(&mut views, &scene, args.downscale)?,
    };
    views.retain(|v| !args.exclude_views.contains(&v.name));
    if views.is_empty() {
        return Err(Error::invalid("the scene has no views to train on"));
    }
    let cfg = TrainConfig {
        seed: args.seed,
        steps: args.steps,
        ..Default::default()
    };
    let (mut trainer, rays, setup) = match &args.resume {
        None => {
            let (t, r, s) = prepare(&views, &args.setup, cfg)?;
            (t, r, Some(s))
        }
        Some(p) => {
            let m = io::load(p)?;
            let t = Trainer::from_model(m, cfg);
            let rays = super::rays::RaySet::build(&views, t.field.box_min, t.field.box_max);
            (t, rays, None)
        }
    };
    let stop = StopRule {
        time_budget: args.time_budget,
        plateau_db: Some(0.01),
        window: 500,
    };
    let summary = run(&mut trainer, &views, &rays, &stop, &mut progress);
    let notes = serde_json::json!({
        "downscale": args.downscale,
        "setup": setup,
        "run": summary,
        "scene": args.scene,
        "depth": format!("{:?}", args.depth),
        "depth_targets": depth_targets,
    });
    io::save(&args.out, &trainer.parts(IDENTITY, notes))?;
    Ok(TrainReport {
        setup,
        run: summary,
        vertices: trainer.field.grid.num_vertices(),
        dims: trainer.field.grid.dims,
        memory_bytes: trainer.memory_bytes(),
        occupied_cells: trainer.field.occupied_cells(),
        depth_targets,
    })
}

/// The downscale a model was trained at (1 if it does not say).
pub fn model_downscale(m: &Model) -> u32 {
    m.notes
        .get("downscale")
        .and_then(|v| v.as_u64())
        .map(|v| v.max(1) as u32)
        .unwrap_or(1)
}

/// Views with cameras only (no pixels), for rendering.
pub fn camera_views(scene: &crate::Scene, downscale: u32) -> Vec<View> {
    scene
        .images
        .iter()
        .map(|im| {
            let cam = scene.camera_of(im);
            let cam = if downscale > 1 {
                cam.downscaled(downscale)
            } else {
                cam.clone()
            };
            let n = (cam.width * cam.height) as usize;
            View::new(im.name.clone(), cam, im.pose, vec![[0; 4]; n])
        })
        .collect()
}

/// Render every view of `scene`: `<name>.png` (RGB on white), `<name>_alpha.png` and
/// `<name>_depth.png` (z-depth, 16-bit millimetres, 0 = empty) into `out`. Returns the files written.
pub fn render(model: &Path, scene: &Path, out: &Path, downscale: Option<u32>) -> Result<usize> {
    let m = io::load_field(model)?;
    let ds = downscale.unwrap_or_else(|| model_downscale(&m));
    let scene = crate::Scene::load(scene)?;
    let views = camera_views(&scene, ds);
    let dir = AtomicDir::new(out, true)?;
    // The default sampling (half-voxel steps), however coarsely training sampled.
    let opt = super::RenderOptions::default();
    for v in &views {
        let r = render_view(&m.field, &opt, v, [1.0; 3]);
        let stem = Path::new(&v.name)
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| v.name.clone());
        let rgb = image::RgbImage::from_fn(r.width, r.height, |x, y| {
            let p = r.rgb[(y * r.width + x) as usize];
            image::Rgb(p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
        });
        let alpha = image::GrayImage::from_fn(r.width, r.height, |x, y| {
            image::Luma([
                (r.alpha[(y * r.width + x) as usize].clamp(0.0, 1.0) * 255.0).round() as u8,
            ])
        });
        let depth =
            image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(r.width, r.height, |x, y| {
                // z-depth, as depth images store it, from the distance along the ray.
                let i = y * r.width + x;
                let z = r.depth[i as usize] / v.ray_scale(i);
                image::Luma([(z * 1000.0).round().clamp(0.0, 65535.0) as u16])
            });
        let save = |name: String, img: image::DynamicImage| {
            crate::util::atomic::save_image_atomic(&dir.path().join(name), &img)
        };
        save(format!("{stem}.png"), rgb.into())?;
        save(format!("{stem}_alpha.png"), alpha.into())?;
        save(format!("{stem}_depth.png"), depth.into())?;
    }
    dir.commit()?;
    Ok(views.len() * 3)
}

/// Evaluate a model on a scene's views with their alpha (or `masks`) as truth, on white.
pub fn eval(
    model: &Path,
    scene: &Path,
    masks: &MaskSource,
    downscale: Option<u32>,
) -> Result<EvalReport> {
    let m = io::load_field(model)?;
    let ds = downscale.unwrap_or_else(|| model_downscale(&m));
    let scene = crate::Scene::load(scene)?;
    let views = load_views(&scene, masks, ds)?;
    // The default sampling (half-voxel steps), however coarsely training sampled.
    let opt = super::RenderOptions::default();
    Ok(evaluate(&m.field, &opt, &views))
}
