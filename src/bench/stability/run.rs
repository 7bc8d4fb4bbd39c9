//! Running one case: prepare its subject (the demo scene or a variant, rendered once per
//! suite; lego triangulated once), perturb it, run the job (`extract`, or segmentation alone
//! for a click), score against the truth, and classify.

use super::cases::{CaseSpec, ClickKind, Job, Subject};
use super::outcome::{classify, CaseResult, StabilityOptions, Verdict};
use super::perturb::{perturb, Perturbation};
use super::score::{score_field, score_masks, score_mesh, ObjectScores, ScoredView, Truth};
use crate::demo::{read_truth, write_demo_scene, DemoOptions, Variant};
use crate::error::{Error, Result};
use crate::pipeline::{extract, ExtractOptions};
use crate::sam::Segmenter;
use crate::scene::io::{mask_file, read_mask};
use crate::scene::sfm::{triangulate, SfmOptions};
use crate::scene::Scene;
use crate::segment::propagate::propagate_objects;
use crate::segment::run::segmentation_warnings;
use crate::segment::{ObjectPrompt, PropagationOptions, SamViews, ViewStatus};
use crate::util::machine::cpu_seconds;
use crate::util::mem::{peak_rss_mib, reset_peak_rss};
use crate::util::{Rng, Silent, Warning};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A subject ready to run cases on: its scene, truth, and each object's suggested click.
pub struct Prepared {
    pub scene: Scene,
    pub truth: Truth,
    pub clicks: BTreeMap<String, (String, [f64; 2])>,
    /// Training resolution (lego trains downscaled).
    pub downscale: u32,
}

/// Render the demo variant into `dir` (reused when already there) and read its truth.
pub fn prepare_demo(variant: Variant, dir: &Path) -> Result<Prepared> {
    if !dir.join("truth/objects.json").is_file() {
        write_demo_scene(
            &DemoOptions {
                variant,
                overwrite: true,
                ..Default::default()
            },
            dir,
        )?;
    }
    let scene = Scene::load(dir)?;
    let truth = Truth::demo(dir, &scene)?;
    let clicks = read_truth(dir)?
        .into_iter()
        .map(|o| (o.name, (o.view, o.click)))
        .collect();
    Ok(Prepared {
        scene,
        truth,
        clicks,
        downscale: 1,
    })
}

/// lego triangulated (a COLMAP model from `objnerf sfm`), its alpha as the truth; the click
/// the README uses.
pub fn prepare_lego(model: &Path) -> Result<Prepared> {
    let scene = Scene::load(model)?;
    let truth = Truth::alpha("lego", &scene)?;
    let view = scene
        .images
        .iter()
        .find(|im| im.name.starts_with("r_0."))
        .map(|im| im.name.clone())
        .ok_or_else(|| Error::invalid(format!("{}: no view r_0", model.display())))?;
    Ok(Prepared {
        scene,
        truth,
        clicks: BTreeMap::from([("lego".to_string(), (view, [397.5, 492.5]))]),
        downscale: 4,
    })
}

/// Where the subjects' scenes live in the suite's folder.
pub fn subject_dir(out: &Path, s: &Subject) -> PathBuf {
    match s {
        Subject::Demo(v) => out.join("scenes").join(v.name()),
        Subject::Lego => out.join("scenes").join("lego"),
    }
}

/// Run one case and classify it.
pub fn run_case(
    spec: &CaseSpec,
    prep: &Prepared,
    opts: &StabilityOptions,
    seg: &Segmenter,
) -> Result<CaseResult> {
    let dir = opts.out.join("cases").join(&spec.id);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    }
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    reset_peak_rss();
    let (t0, c0) = (Instant::now(), cpu_seconds());
    let anchor = match &spec.job {
        Job::Extract { objects } => objects.first(),
        Job::Click { .. } => None,
    }
    .and_then(|o| prep.clicks.get(o))
    .and_then(|(view, _)| prep.scene.find_image(view).ok())
    .unwrap_or(0);
    let mut scene = perturb(&prep.scene, spec.perturbation, opts.seed, anchor, &dir)?;
    if let Perturbation::PoseNoise { .. } = spec.perturbation {
        scene = retriangulate(&scene, &spec.subject, &dir)?;
    }
    let outcome = match &spec.job {
        Job::Extract { objects } => run_extract(&scene, prep, objects, opts, seg, &dir),
        Job::Click { kind, index } => run_click(&scene, prep, *kind, *index, opts, seg),
    };
    let (scores, warnings, error) = match outcome {
        Ok((s, w)) => (s, w, None),
        Err(e) => (vec![], vec![], Some(e.to_string())),
    };
    let click = match &spec.job {
        Job::Click { kind, index } => click_point(prep, *kind, *index, opts.seed),
        Job::Extract { .. } => None,
    };
    let verdict = match &spec.job {
        Job::Click {
            kind: ClickKind::Outside,
            ..
        } => Verdict::NotScored,
        _ => classify(&scores, &warnings, error.is_some()),
    };
    Ok(CaseResult {
        spec: spec.clone(),
        verdict,
        click,
        objects: scores,
        warnings,
        error,
        seconds: t0.elapsed().as_secs_f64(),
        cpu_seconds: cpu_seconds() - c0,
        peak_rss_mib: peak_rss_mib(),
    })
}

/// Noisy poses as a user would meet them: `objnerf sfm` triangulates the capture with the poses
/// it was given (COLMAP matches the images and triangulates, dropping what the poses cannot
/// explain), so the points, tracks and their reprojection errors are COLMAP's, not the clean
/// ones with moved cameras (whose error would flag the noise by construction). Lego at the
/// README's settings (half size, 4096 features); the demo at full size.
fn retriangulate(scene: &Scene, subject: &Subject, dir: &Path) -> Result<Scene> {
    let opts = match subject {
        Subject::Demo(_) => SfmOptions {
            max_features: 4096,
            ..SfmOptions::default()
        },
        Subject::Lego => SfmOptions {
            downscale: 2,
            max_features: 4096,
            ..SfmOptions::default()
        },
    };
    let out = dir.join("sfm");
    triangulate(scene, &out, &opts, &Silent)?;
    Scene::load(&out)
}

type Outcome = (Vec<ObjectScores>, Vec<Warning>);

fn run_extract(
    scene: &Scene,
    prep: &Prepared,
    objects: &[String],
    opts: &StabilityOptions,
    seg: &Segmenter,
    dir: &Path,
) -> Result<Outcome> {
    let prompts = objects
        .iter()
        .map(|o| {
            let (view, xy) = prep
                .clicks
                .get(o)
                .ok_or_else(|| Error::invalid(format!("no object '{o}' in the subject")))?;
            ObjectPrompt::click(scene, o, view, *xy)
        })
        .collect::<Result<Vec<_>>>()?;
    let mut eo = ExtractOptions {
        overwrite: true,
        ..Default::default()
    };
    eo.fit.steps = opts.steps;
    eo.fit.time_budget = None;
    eo.fit.seed = opts.seed;
    eo.fit.downscale = prep.downscale;
    eo.turntable.frames = 1;
    let run = dir.join("run");
    let report = extract(scene, &prompts, &eo, seg, &run, &Silent)?;
    let scores = objects
        .iter()
        .zip(&report.objects)
        .map(|(name, o)| score_object(scene, prep, name, o, &run))
        .collect::<Result<Vec<_>>>()?;
    // Keep the reports; the models, meshes and renders are large and the scores are in hand.
    for (from, to) in [
        ("report.json", "report.json"),
        ("segment/report.json", "segment_report.json"),
    ] {
        let json = std::fs::read(run.join(from)).map_err(|e| Error::io(run.join(from), e))?;
        crate::util::atomic::write_bytes_atomic(&dir.join(to), &json)?;
    }
    std::fs::remove_dir_all(&run).map_err(|e| Error::io(&run, e))?;
    Ok((scores, report.warnings))
}

fn score_object(
    scene: &Scene,
    prep: &Prepared,
    name: &str,
    o: &crate::pipeline::extract::ObjectReport,
    run: &Path,
) -> Result<ObjectScores> {
    let masks = crate::pipeline::extract::object_masks_dir(run, name);
    let seg_report: serde_json::Value = {
        let p = run.join("segment/report.json");
        let text = std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?;
        serde_json::from_str(&text).map_err(|e| Error::json(&p, e))?
    };
    let statuses: BTreeMap<String, (String, bool)> = seg_report["objects"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|ob| ob["name"] == name)
        .flat_map(|ob| ob["views"].as_array().cloned().unwrap_or_default())
        .map(|v| {
            let cut = v["flags"]
                .as_array()
                .is_some_and(|f| f.iter().any(|x| x == "cut"));
            (
                v["view"].as_str().unwrap_or_default().to_string(),
                (v["status"].as_str().unwrap_or_default().to_string(), cut),
            )
        })
        .collect();
    let views = scene
        .images
        .iter()
        .map(|im| {
            let (status, cut) = statuses.get(&im.name).cloned().unwrap_or_default();
            let status = match status.as_str() {
                "ok" => ViewStatus::Ok,
                "obstructed" => ViewStatus::Obstructed,
                _ => ViewStatus::Absent,
            };
            let file = mask_file(&masks, &im.name);
            let mask = if file.is_file() {
                Some(read_mask(&file)?)
            } else {
                None
            };
            Ok(ScoredView {
                view: im.name.clone(),
                status,
                cut,
                mask,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let mut s = score_masks(&prep.truth, name, &views);
    let trained: Vec<String> = scene
        .images
        .iter()
        .map(|im| im.name.clone())
        .filter(|n| !o.segmentation.held_out.contains(n))
        .collect();
    let model = crate::field::io::load_field(&run.join(name).join("model.objf"))?;
    score_field(
        &prep.truth,
        name,
        &model.field,
        &trained,
        prep.downscale,
        &mut s,
    )?;
    let mesh = crate::mesh::io::read_ply(&run.join(name).join("mesh.ply"))?;
    s.chamfer = score_mesh(&prep.truth, name, &mesh)?;
    Ok(s)
}

/// The `index`-th seeded click of `kind` on the mug's true mask in its click view.
pub fn click_point(prep: &Prepared, kind: ClickKind, index: usize, seed: u64) -> Option<[f64; 2]> {
    let (view, _) = prep.clicks.get("mug")?;
    let mask = prep.truth.masks.get("mug")?.get(view)?;
    let sd = crate::segment::distance::signed_distance(mask);
    let w = mask.width() as usize;
    let pool: Vec<usize> = (0..sd.len())
        .filter(|&i| match kind {
            ClickKind::Inside => sd[i] > 0.0,
            ClickKind::Edge => sd[i] > 0.0 && sd[i] <= 1.5,
            ClickKind::Outside => (-4.0..=-2.0).contains(&sd[i]),
        })
        .collect();
    if pool.is_empty() {
        return None;
    }
    let stream = match kind {
        ClickKind::Inside => 1,
        ClickKind::Edge => 2,
        ClickKind::Outside => 3,
    };
    let mut rng = Rng::fork(seed, 0xC11C_0000 + stream * 1000 + index as u64);
    let i = pool[rng.below(pool.len())];
    Some([(i % w) as f64 + 0.5, (i / w) as f64 + 0.5])
}

fn run_click(
    scene: &Scene,
    prep: &Prepared,
    kind: ClickKind,
    index: usize,
    opts: &StabilityOptions,
    seg: &Segmenter,
) -> Result<Outcome> {
    let (view, _) = prep
        .clicks
        .get("mug")
        .ok_or_else(|| Error::invalid("the subject has no mug"))?;
    let xy = click_point(prep, kind, index, opts.seed)
        .ok_or_else(|| Error::invalid("no pixel to click"))?;
    let p = ObjectPrompt::click(scene, "mug", view, xy)?;
    let mut views = SamViews::new(seg);
    let objs = propagate_objects(scene, &[p], &mut views, &PropagationOptions::default())?;
    let warnings = segmentation_warnings(scene, &objs);
    let o = &objs[0];
    let scored: Vec<ScoredView> = o
        .views
        .iter()
        .map(|v| ScoredView {
            view: v.view.clone(),
            status: v.status,
            cut: v.flags.contains(&"cut"),
            mask: v.mask.clone(),
        })
        .collect();
    let mut s = score_masks(&prep.truth, "mug", &scored);
    s.click_agreement = o.click_agreement;
    Ok((vec![s], warnings))
}
