//! `objnerf segment`: one or more objects from clicks in one view, propagated to every view;
//! writes masks, the segmented sparse clouds, contact sheets and report.json.

use super::output::{write_contact_sheet, write_object};
use super::propagate::{
    propagate_objects, ObjectPrompt, ObjectSegmentation, PointPrompt, PropagationOptions,
    ViewResult,
};
use super::scene_views::SamViews;
use super::{ModelsDir, Segmenter};
use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::util::AtomicDir;
use clap::Args;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The scene and the clicks, shared by `segment` and `extract`. The options' order on the
/// command line matters (see [`group_prompts`]); clap only declares them.
#[derive(Args, Debug)]
pub struct ClickArgs {
    /// A scene with 2D-3D tracks (a COLMAP model, or any scene after `objnerf sfm`).
    pub scene: PathBuf,
    /// The view the clicks are in (name, file name, stem or index); applies to the objects after it.
    #[arg(long)]
    pub view: Vec<String>,
    /// Start a new object with this name; the --point options after it belong to it.
    #[arg(long)]
    pub object: Vec<String>,
    /// A click x,y[,fg|bg] in pixels (corner origin) on the current object.
    #[arg(long, allow_hyphen_values = true)]
    pub point: Vec<String>,
}

#[derive(Args, Debug)]
pub struct SegmentCmd {
    #[command(flatten)]
    pub clicks: ClickArgs,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Positive prompts per view.
    #[arg(long, default_value_t = 8)]
    pub prompts: usize,
    /// Coverage of the expected (alpha-shape) mask below which a view is obstructed.
    #[arg(long, default_value_t = 0.52)]
    pub obstruction_coverage: f64,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub overwrite: bool,
    /// Print report.json to stdout too.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
pub struct ObjectReport {
    pub name: String,
    pub num_points: usize,
    pub num_ok: usize,
    pub num_obstructed: usize,
    pub num_absent: usize,
    pub views: Vec<ViewResult>,
}

#[derive(Serialize, Default)]
pub struct Timings {
    pub total: f64,
    pub encoder: f64,
    pub decoder: f64,
    pub propagation: f64,
    pub writing: f64,
}

#[derive(Serialize)]
pub struct SegmentReport {
    pub scene: String,
    pub objects: Vec<ObjectReport>,
    pub encoder_runs: usize,
    pub timings: Timings,
}

/// Group `--view/--object/--point` by their order on the command line: points belong to the
/// object named before them, an object to the view named before it (or the first view given).
pub fn group_prompts(args: &[String], scene: &Scene) -> Result<Vec<ObjectPrompt>> {
    let mut objects: Vec<ObjectPrompt> = Vec::new();
    let mut view: Option<usize> = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let (flag, inline) = match a.split_once('=') {
            Some((f, v)) if f.starts_with("--") => (f, Some(v.to_string())),
            _ => (a.as_str(), None),
        };
        if !matches!(flag, "--view" | "--object" | "--point") {
            continue;
        }
        let value = match inline {
            Some(v) => v,
            None => it
                .next()
                .cloned()
                .ok_or_else(|| Error::invalid(format!("{flag} needs a value")))?,
        };
        match flag {
            "--view" => {
                let v = scene.find_image(&value)?;
                view = Some(v);
                if let Some(o) = objects.last_mut() {
                    if o.points.is_empty() {
                        o.view = v;
                    }
                }
            }
            "--object" => objects.push(ObjectPrompt {
                name: sanitize(&value)?,
                view: view.unwrap_or(usize::MAX),
                points: vec![],
                bbox: None,
            }),
            _ => {
                if objects.is_empty() {
                    objects.push(ObjectPrompt {
                        name: "object".into(),
                        view: view.unwrap_or(usize::MAX),
                        points: vec![],
                        bbox: None,
                    });
                }
                let p = super::prompt::parse_point(&value)?;
                objects.last_mut().unwrap().points.push(PointPrompt {
                    xy: [p.x as f64, p.y as f64],
                    positive: p.positive,
                });
            }
        }
    }
    let first_view = view;
    for o in &mut objects {
        if o.view == usize::MAX {
            o.view = first_view
                .ok_or_else(|| Error::invalid("give the clicked view with --view NAME"))?;
        }
        if o.points.is_empty() {
            return Err(Error::invalid(format!(
                "object '{}' has no --point",
                o.name
            )));
        }
        let im = &scene.images[o.view];
        let cam = scene.camera_of(im);
        for p in &o.points {
            if !(p.xy[0] >= 0.0
                && p.xy[1] >= 0.0
                && p.xy[0] < cam.width as f64
                && p.xy[1] < cam.height as f64)
            {
                return Err(Error::invalid(format!(
                    "click ({}, {}) for '{}' is outside view '{}' ({}x{})",
                    p.xy[0], p.xy[1], o.name, im.name, cam.width, cam.height
                )));
            }
        }
    }
    if objects.is_empty() {
        return Err(Error::invalid(
            "give at least one --point (and --object NAME for several objects)",
        ));
    }
    let mut names: Vec<&str> = objects.iter().map(|o| o.name.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    if names.len() != objects.len() {
        return Err(Error::invalid("object names must differ"));
    }
    Ok(objects)
}

fn sanitize(name: &str) -> Result<String> {
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(Error::invalid(format!(
            "object name '{name}': use letters, digits, '_' and '-'"
        )));
    }
    Ok(name.to_string())
}

/// Segment and write everything under `out` (atomically); `progress`: a bar over the views
/// (each object's pass over them) on stderr.
pub fn segment_scene(
    scene: &Scene,
    prompts: &[ObjectPrompt],
    opts: &PropagationOptions,
    out: &Path,
    overwrite: bool,
    progress: bool,
) -> Result<(SegmentReport, Vec<ObjectSegmentation>)> {
    let t0 = Instant::now();
    super::propagate::require_tracks(scene)?;
    for p in prompts {
        super::propagate::require_view_tracks(scene, p.view)?;
    }
    let dest = AtomicDir::new(out, overwrite)?;
    let models = ModelsDir::from_env()?;
    let seg = Segmenter::open(&models, 0)?;
    let bar = crate::util::progress::bar((scene.images.len() * prompts.len()) as u64, "segment");
    if !progress {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let mut views = SamViews::new(&seg).with_progress(bar.clone());
    let objects = propagate_objects(scene, prompts, &mut views, opts)?;
    bar.finish_and_clear();
    let t_prop = t0.elapsed().as_secs_f64();
    for o in &objects {
        write_object(scene, o, dest.path())?;
        write_contact_sheet(
            scene,
            o,
            &dest.path().join(format!("contact_sheet_{}.png", o.name)),
        )?;
    }
    let report = SegmentReport {
        scene: scene.source.display().to_string(),
        objects: objects
            .iter()
            .map(|o| {
                let count = |s| o.views.iter().filter(|v| v.status == s).count();
                use super::propagate::ViewStatus::*;
                ObjectReport {
                    name: o.name.clone(),
                    num_points: o.points.len(),
                    num_ok: count(Ok),
                    num_obstructed: count(Obstructed),
                    num_absent: count(Absent),
                    views: o.views.clone(),
                }
            })
            .collect(),
        encoder_runs: seg.encoder_runs(),
        timings: Timings {
            total: t0.elapsed().as_secs_f64(),
            encoder: views.encoder_seconds,
            decoder: views.decoder_seconds,
            propagation: t_prop - views.encoder_seconds - views.decoder_seconds,
            writing: t0.elapsed().as_secs_f64() - t_prop,
        },
    };
    let json = serde_json::to_string_pretty(&report).expect("report serialises");
    crate::util::atomic::write_bytes_atomic(&dest.path().join("report.json"), json.as_bytes())?;
    dest.commit()?;
    Ok((report, objects))
}

impl SegmentCmd {
    /// `argv` is the raw command line, read for the order of --view/--object/--point.
    pub fn run(self, argv: &[String]) -> Result<()> {
        let scene = Scene::load(&self.clicks.scene)?;
        let prompts = group_prompts(argv, &scene)?;
        let opts = PropagationOptions {
            max_prompts: self.prompts,
            obstruction_coverage: self.obstruction_coverage,
            ..Default::default()
        };
        let (report, _) = segment_scene(&scene, &prompts, &opts, &self.out, self.overwrite, true)?;
        if self.json {
            println!(
                "{}",
                serde_json::to_string_pretty(&report).expect("report serialises")
            );
        }
        for o in &report.objects {
            println!(
                "{}: {} ok, {} obstructed, {} absent of {} views; {} points -> {}",
                o.name,
                o.num_ok,
                o.num_obstructed,
                o.num_absent,
                o.views.len(),
                o.num_points,
                self.out.join("masks").join(&o.name).display()
            );
        }
        println!(
            "{:.1} s (encoder {:.1} s over {} runs, decoder {:.1} s)",
            report.timings.total,
            report.timings.encoder,
            report.encoder_runs,
            report.timings.decoder
        );
        Ok(())
    }
}
