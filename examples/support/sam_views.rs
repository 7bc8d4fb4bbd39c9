//! The views on which a SAM encoder's masks are compared with fp32's: the demo scene (every third
//! of its 36 views, one click per object at the most interior point of its true mask), lego (three
//! training views, a click inside the alpha) and fox (three photos, a click at the centre). Absent
//! shared data is skipped with a note. Used through `#[path = "support/sam_views.rs"] mod sam_views;`.
#![allow(dead_code)]

use image::{GrayImage, RgbImage};
use objnerf::demo::{read_truth, view_name, write_demo_scene, DemoOptions};
use objnerf::sam::{Prompts, Segmenter};
use objnerf::scene::io::read_rgb;
use objnerf::segment::distance::most_interior_point;
use objnerf::util::mask::iou_bits;
use objnerf::{Error, Result};
use std::path::{Path, PathBuf};

/// One image and the clicks made on it.
pub struct IouCase {
    pub name: String,
    pub image: RgbImage,
    pub clicks: Vec<(f32, f32)>,
    /// Each click's true mask where the case has one (the demo's objects), row-major.
    pub truths: Vec<Option<Vec<bool>>>,
}

fn shared_data(name: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(name);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skip: {} is absent", p.display());
        None
    }
}

fn interior(mask: &GrayImage) -> Option<(f32, f32)> {
    most_interior_point(mask).map(|(x, y)| (x as f32, y as f32))
}

/// The cases (the demo scene is rendered into `tmp`).
pub fn iou_cases(tmp: &Path) -> Result<Vec<IouCase>> {
    let mut out = Vec::new();
    let demo = tmp.join("demo");
    write_demo_scene(&DemoOptions::default(), &demo)?;
    let objects = read_truth(&demo)?;
    for v in (0..36).step_by(3) {
        let name = view_name(v);
        let image = read_rgb(&demo.join("images").join(&name))?;
        let (mut clicks, mut truths) = (Vec::new(), Vec::new());
        for o in &objects {
            let p = demo.join("truth/masks").join(&o.name).join(&name);
            let t = image::open(&p)
                .map_err(|e| Error::format(&p, e.to_string()))?
                .to_luma8();
            if t.pixels().filter(|p| p[0] > 127).count() > 200 {
                if let Some(c) = interior(&t) {
                    clicks.push(c);
                    truths.push(Some(t.pixels().map(|p| p[0] > 127).collect()));
                }
            }
        }
        out.push(IouCase {
            name: format!("demo {name}"),
            image,
            clicks,
            truths,
        });
    }
    if let Some(lego) = shared_data("lego") {
        for r in [0, 10, 50] {
            let p = lego.join(format!("train/r_{r}.png"));
            let rgba = image::open(&p)
                .map_err(|e| Error::format(&p, e.to_string()))?
                .to_rgba8();
            let alpha = GrayImage::from_fn(rgba.width(), rgba.height(), |x, y| {
                image::Luma([if rgba.get_pixel(x, y)[3] > 127 {
                    255
                } else {
                    0
                }])
            });
            let clicks: Vec<(f32, f32)> = interior(&alpha).into_iter().collect();
            out.push(IouCase {
                name: format!("lego r_{r}"),
                image: read_rgb(&p)?,
                truths: vec![None; clicks.len()],
                clicks,
            });
        }
    }
    if let Some(fox) = shared_data("fox") {
        let dir = fox.join("images");
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .map_err(|e| Error::io(&dir, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
            .collect();
        files.sort();
        for p in files.iter().step_by(20).take(3) {
            let image = read_rgb(p)?;
            let c = (image.width() as f32 / 2.0, image.height() as f32 / 2.0);
            out.push(IouCase {
                name: format!(
                    "fox {}",
                    p.file_name().unwrap_or_default().to_string_lossy()
                ),
                image,
                clicks: vec![c],
                truths: vec![None],
            });
        }
    }
    Ok(out)
}

/// The same cases with every pixel channel moved by -1, 0 or +1 grey level (seeded): a change no
/// one could see, whose effect on fp32's masks says how stable each click's mask is, the floor
/// against which an encoder's differences from fp32 are read.
pub fn perturbed(cases: &[IouCase], seed: u64) -> Vec<IouCase> {
    let mut rng = objnerf::util::Rng::new(seed);
    cases
        .iter()
        .map(|c| {
            let mut image = c.image.clone();
            for v in image.iter_mut() {
                *v = (*v as i32 + rng.below(3) as i32 - 1).clamp(0, 255) as u8;
            }
            IouCase {
                name: c.name.clone(),
                image,
                clicks: c.clicks.clone(),
                truths: c.truths.clone(),
            }
        })
        .collect()
}

/// Every click's mask (one click each), in case order.
pub fn masks(seg: &Segmenter, cases: &[IouCase]) -> Result<Vec<Vec<bool>>> {
    let mut out = Vec::new();
    for c in cases {
        let emb = seg.embed(&c.image)?;
        for &(x, y) in &c.clicks {
            out.push(seg.predict_allow_empty(&emb, &Prompts::click(x, y))?.bitmap);
        }
    }
    Ok(out)
}

/// Mean IoU of the masks against the true ones, over the clicks that have one (the demo's).
pub fn mean_iou_vs_truth(cases: &[IouCase], got: &[Vec<bool>]) -> f64 {
    let truths = cases.iter().flat_map(|c| c.truths.iter());
    let ious: Vec<f64> = truths
        .zip(got)
        .filter_map(|(t, m)| {
            t.as_ref()
                .map(|t| iou_bits(t.iter().copied(), m.iter().copied()))
        })
        .collect();
    ious.iter().sum::<f64>() / ious.len().max(1) as f64
}

/// Mask IoU against the reference masks: mean, worst, and the worst one's case name.
#[derive(Clone, Debug, serde::Serialize)]
pub struct IouSummary {
    pub masks: usize,
    pub mean: f64,
    pub worst: f64,
    pub worst_case: String,
    /// Mean IoU per source (demo, lego, fox).
    pub by_source: Vec<(String, f64)>,
}

pub fn compare(cases: &[IouCase], reference: &[Vec<bool>], got: &[Vec<bool>]) -> IouSummary {
    let names: Vec<&str> = cases
        .iter()
        .flat_map(|c| c.clicks.iter().map(|_| c.name.as_str()))
        .collect();
    let ious: Vec<f64> = reference
        .iter()
        .zip(got)
        .map(|(a, b)| iou_bits(a.iter().copied(), b.iter().copied()))
        .collect();
    let (wi, worst) = ious
        .iter()
        .copied()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, f64::NAN));
    let by_source = ["demo", "lego", "fox"]
        .iter()
        .filter_map(|src| {
            let v: Vec<f64> = ious
                .iter()
                .zip(&names)
                .filter(|(_, n)| n.starts_with(src))
                .map(|(i, _)| *i)
                .collect();
            (!v.is_empty()).then(|| (src.to_string(), v.iter().sum::<f64>() / v.len() as f64))
        })
        .collect();
    IouSummary {
        masks: ious.len(),
        mean: ious.iter().sum::<f64>() / ious.len().max(1) as f64,
        worst,
        worst_case: names.get(wi).map(|s| s.to_string()).unwrap_or_default(),
        by_source,
    }
}
