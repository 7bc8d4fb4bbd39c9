//! The demo scene's fields for edits, as the edit tests and the render-edit benchmark use them:
//! the mug and the torus trained from their true masks, and the background without them made by
//! [`remove`](super::remove) with the true masks as its segmentation (a segment run written from
//! the truth) and the true depth maps, everything on step budgets so that results do not depend
//! on the machine's load.

use super::remove::{remove, RemoveOptions};
use crate::demo::fields::{write_object_field, DemoFieldOptions};
use crate::demo::{write_demo_scene, DemoOptions};
use crate::error::{Error, Result};
use crate::scene::io::find_mask;
use crate::scene::Scene;
use crate::util::{write_atomic, Silent};
use std::path::{Path, PathBuf};

/// Steps of the background (the removal's scene field) and of each object.
pub const BACKGROUND_STEPS: usize = 3000;
pub const OBJECT_STEPS: usize = 2000;

/// What [`ensure_edit_fields`] keeps in its folder.
#[derive(Clone, Debug)]
pub struct EditFields {
    pub scene: PathBuf,
    /// The scene without the mug and the torus (`objnerf remove`'s `background.objf`).
    pub background: PathBuf,
    pub mug: PathBuf,
    pub torus: PathBuf,
}

/// A segment run of the demo scene in `scene_dir` (read as its transforms.json, which names the
/// depth maps) whose masks of `objects` are their true masks (what `objnerf segment` writes:
/// report.json with every view ok, `masks/<object>/`).
pub fn truth_segment_run(scene_dir: &Path, objects: &[&str], out: &Path) -> Result<()> {
    let scene_file = scene_dir.join("transforms.json");
    let scene = Scene::load(&scene_file)?;
    let views: Vec<serde_json::Value> = scene
        .images
        .iter()
        .map(|im| serde_json::json!({"view": im.name, "status": "ok"}))
        .collect();
    for o in objects {
        let dir = out.join("masks").join(o);
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        for im in &scene.images {
            let from = find_mask(&scene_dir.join("truth/masks").join(o), &im.name)?;
            let to = crate::scene::io::mask_file(&dir, &im.name);
            if let Some(parent) = to.parent() {
                std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
            }
            std::fs::copy(&from, &to).map_err(|e| Error::io(&to, e))?;
        }
    }
    let report = serde_json::json!({
        "scene": scene_file,
        "objects": objects.iter().map(|o| serde_json::json!({"name": o, "views": views})).collect::<Vec<_>>(),
    });
    let path = out.join("report.json");
    write_atomic(&path, |w| w.write_all(report.to_string().as_bytes()))
}

/// The demo scene and its edit fields in `dir`: made when missing (the default demo scene; the
/// mug and the torus from their true masks; the background by `remove` with their true masks),
/// reused when present. `log` hears what was trained.
pub fn ensure_edit_fields(dir: &Path, log: &mut dyn FnMut(String)) -> Result<EditFields> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let f = EditFields {
        scene: dir.join("demo"),
        background: dir.join("removed/background.objf"),
        mug: dir.join("mug.objf"),
        torus: dir.join("torus.objf"),
    };
    if !f.scene.join("truth/objects.json").is_file() {
        write_demo_scene(&DemoOptions::default(), &f.scene)?;
    }
    for (name, out) in [("mug", &f.mug), ("torus", &f.torus)] {
        if !out.is_file() {
            let opts = DemoFieldOptions::steps(OBJECT_STEPS);
            let r = write_object_field(&f.scene, name, &opts, out)?;
            log(format!(
                "{name}: {} steps in {:.0} s, grid {:?}",
                r.run.steps, r.run.seconds, r.dims
            ));
        }
    }
    if !f.background.is_file() {
        let objects = ["mug", "torus"];
        let seg = dir.join("truth_segment");
        truth_segment_run(&f.scene, &objects, &seg)?;
        let mut opts = RemoveOptions {
            objects: objects.iter().map(|s| s.to_string()).collect(),
            overwrite: true,
            ..Default::default()
        };
        opts.field.fit.time_budget = None;
        opts.field.fit.steps = BACKGROUND_STEPS;
        // The demo's exact depth maps (the removed objects' pixels carry none). The memory
        // budget is `objnerf remove`'s default (1 GiB): at 512 MiB the finest grid is 1.3x
        // coarser and every edit loses ~0.4 dB full-frame.
        opts.field.fit.depth = crate::supervision::DepthMode::Dense;
        let scene = Scene::load(&f.scene.join("transforms.json"))?;
        let r = remove(&scene, &seg, &opts, &dir.join("removed"), &Silent)?;
        log(format!(
            "background without the mug and the torus: {} steps in {:.0} s, grid {:?}, {} hole pixels filled; peak RSS {} MiB",
            r.train.run.steps, r.seconds.train, r.train.dims, r.filled_px, r.peak_rss_mib
        ));
    }
    Ok(f)
}
