//! Multi-view segmentation benchmark (issue 4): mIoU against wall time for ours (Algorithm 1),
//! the projection baseline and an oracle (one click per view at the truth mask's most interior
//! point), on the demo scene (four objects, occlusions) and on lego (alpha as truth, tracks from
//! `objnerf sfm`); and the time of three objects in one pass against one. Writes
//! `segment_bench.json` and `segment_bench.svg` to the output folder.
//!
//! cargo run --release --example segment_bench -- [--lego-model runs/lego_sfm] [--out examples/results]
//!
//! Every method gets a fresh segmenter with a memory-only embedding cache, so each pays for its
//! own encoder runs (the disk cache would make whichever runs second look free).

#[path = "support/bench.rs"]
mod bench;

use bench::cpu_seconds;
use image::GrayImage;
use objnerf::demo::{read_truth, truth_masks, write_demo_scene, DemoOptions};
use objnerf::models::ModelsDir;
use objnerf::sam::{Segmenter, SegmenterOptions};
use objnerf::segment::distance::most_interior_point;
use objnerf::segment::evaluate::{alpha_truth, view_ious};
use objnerf::segment::propagate::{projection_baseline, propagate_objects};
use objnerf::segment::types::{ViewResult, ViewSegmenter};
use objnerf::segment::{
    ObjectPrompt, ObjectSegmentation, PointPrompt, PropagationOptions, SamViews, ViewStatus,
};
use objnerf::util::chart::{palette, svg, ChartResult, Layer, Mark, Panel};
use objnerf::util::mask::is_object;
use objnerf::util::mem::peak_rss_mib;
use objnerf::util::stats::mean;
use objnerf::{Result, Scene};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

fn load_avg() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

#[derive(Serialize)]
struct MethodResult {
    scene: String,
    method: String,
    /// Mean IoU over every (object, view) with a non-empty truth mask (no mask = IoU 0).
    miou: f64,
    /// Ours only: over the views it marks ok.
    miou_ok: Option<f64>,
    /// Demo only: over the views where the object is partly visible (0.05 < visible < 0.5).
    miou_occluded: Option<f64>,
    views_scored: usize,
    wall_s: f64,
    cpu_s: f64,
    encoder_runs: usize,
    encoder_s: f64,
    decoder_s: f64,
}

#[derive(Serialize)]
struct Scaling {
    objects: Vec<String>,
    wall_s: f64,
    cpu_s: f64,
    encoder_runs: usize,
}

fn fresh_segmenter(models: &ModelsDir) -> Result<Segmenter> {
    let lib = models.require_library()?;
    let (enc, dec) = models.require_sam()?;
    Segmenter::from_files(&lib, &enc, &dec, &SegmenterOptions::default())
}

/// Run `f` on a fresh segmenter; wall and CPU time, encoder runs and seconds.
fn timed<T>(
    models: &ModelsDir,
    f: impl FnOnce(&mut SamViews) -> Result<T>,
) -> Result<(T, f64, f64, usize, f64, f64)> {
    let seg = fresh_segmenter(models)?;
    let mut views = SamViews::new(&seg);
    let (c0, t0) = (cpu_seconds(), Instant::now());
    let out = f(&mut views)?;
    Ok((
        out,
        t0.elapsed().as_secs_f64(),
        cpu_seconds() - c0,
        seg.encoder_runs(),
        views.encoder_seconds,
        views.decoder_seconds,
    ))
}

/// Per-object truth masks and per-view visible fractions (None: every view counts as visible).
struct Truth {
    masks: Vec<Vec<image::GrayImage>>,
    visible: Vec<Option<Vec<f64>>>,
}

fn score(
    scene_name: &str,
    method: &str,
    objects: &[ObjectSegmentation],
    truth: &Truth,
    t: (f64, f64, usize, f64, f64),
) -> MethodResult {
    let (mut all, mut ok, mut occ) = (vec![], vec![], vec![]);
    for (k, o) in objects.iter().enumerate() {
        let ious = view_ious(o, &truth.masks[k]);
        for (v, iou) in ious.iter().enumerate() {
            if truth.masks[k][v].pixels().all(|p| !is_object(p[0])) {
                continue;
            }
            all.push(*iou);
            if o.views[v].status == ViewStatus::Ok {
                ok.push(*iou);
            }
            if let Some(vis) = &truth.visible[k] {
                if vis[v] > 0.05 && vis[v] < 0.5 {
                    occ.push(*iou);
                }
            }
        }
    }
    let r = MethodResult {
        scene: scene_name.into(),
        method: method.into(),
        miou: mean(&all),
        miou_ok: (method == "ours").then(|| mean(&ok)),
        miou_occluded: truth.visible[0].as_ref().map(|_| mean(&occ)),
        views_scored: all.len(),
        wall_s: t.0,
        cpu_s: t.1,
        encoder_runs: t.2,
        encoder_s: t.3,
        decoder_s: t.4,
    };
    eprintln!(
        "{scene_name} {method}: mIoU {:.4} over {} views, {:.1} s wall, {:.1} s CPU, {} encoder runs",
        r.miou, r.views_scored, r.wall_s, r.cpu_s, r.encoder_runs
    );
    r
}

/// Ours, the projection baseline and the oracle on one scene, each on a fresh segmenter.
fn compare(
    models: &ModelsDir,
    scene_name: &str,
    scene: &Scene,
    prompts: &[ObjectPrompt],
    truth: &Truth,
) -> Result<Vec<MethodResult>> {
    let opts = PropagationOptions::default();
    let mut out = vec![];
    let (objs, a, b, c, d, e) = timed(models, |v| propagate_objects(scene, prompts, v, &opts))?;
    out.push(score(scene_name, "ours", &objs, truth, (a, b, c, d, e)));
    let (objs, a, b, c, d, e) = timed(models, |v| {
        prompts
            .iter()
            .map(|p| projection_baseline(scene, p, v, &opts))
            .collect::<Result<Vec<_>>>()
    })?;
    out.push(score(
        scene_name,
        "projection",
        &objs,
        truth,
        (a, b, c, d, e),
    ));
    let (objs, a, b, c, d, e) = timed(models, |v| {
        prompts
            .iter()
            .zip(&truth.masks)
            .map(|(p, t)| oracle(scene, &p.name, t, v))
            .collect::<Result<Vec<_>>>()
    })?;
    out.push(score(scene_name, "oracle", &objs, truth, (a, b, c, d, e)));
    Ok(out)
}

/// The oracle: every view where the truth mask is not empty gets one click at its most interior
/// point (what a person clicking each view would do); views with an empty truth stay absent.
fn oracle(
    scene: &Scene,
    name: &str,
    truth: &[GrayImage],
    seg: &mut dyn ViewSegmenter,
) -> Result<ObjectSegmentation> {
    let mut views = Vec::with_capacity(scene.images.len());
    for (v, (im, t)) in scene.images.iter().zip(truth).enumerate() {
        let mut res = ViewResult::unsegmented(&im.name);
        if let Some((x, y)) = most_interior_point(t) {
            let prompts = vec![PointPrompt {
                xy: [x, y],
                positive: true,
            }];
            let m = seg.segment(scene, v, &prompts, None)?;
            res.status = ViewStatus::Ok;
            res.score = m.score;
            res.num_prompts = 1;
            res.prompts = prompts;
            res.order = Some(v);
            res.mask = Some(m.mask);
        }
        views.push(res);
    }
    Ok(ObjectSegmentation {
        name: name.to_string(),
        views,
        points: vec![],
        click_agreement: None,
    })
}

#[derive(Serialize)]
struct Report<'a> {
    command: String,
    machine: bench::Machine,
    note: String,
    load_average_start: String,
    load_average_end: String,
    git_commit: Option<String>,
    options: String,
    results: &'a [MethodResult],
    /// Demo scene: ours with one object, then three, each on a fresh segmenter.
    scaling: &'a [Scaling],
    three_over_one_wall: Option<f64>,
    three_over_one_cpu: Option<f64>,
    peak_rss_mib: u64,
    total_s: f64,
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .map(PathBuf::from)
    };
    let out_dir = arg("--out").unwrap_or_else(|| PathBuf::from("examples/results"));
    let lego_model = arg("--lego-model");
    let t0 = Instant::now();
    let load_start = load_avg();
    let models = ModelsDir::from_env()?;
    let work = tempfile::tempdir().map_err(|e| objnerf::Error::io(std::env::temp_dir(), e))?;

    // The demo scene: every object from its suggested click.
    let scene_dir = work.path().join("demo");
    write_demo_scene(&DemoOptions::default(), &scene_dir)?;
    let scene = Scene::load(&scene_dir)?;
    let truths = read_truth(&scene_dir)?;
    let prompts = truths
        .iter()
        .map(|t| ObjectPrompt::click(&scene, &t.name, &t.view, t.click))
        .collect::<Result<Vec<_>>>()?;
    let truth = Truth {
        masks: truths
            .iter()
            .map(|t| truth_masks(&scene_dir, &scene, &t.name))
            .collect::<Result<_>>()?,
        visible: truths
            .iter()
            .map(|t| Some(scene.images.iter().map(|im| t.visible[&im.name]).collect()))
            .collect(),
    };

    // One object against three in one pass.
    let opts = PropagationOptions::default();
    let mut scaling = vec![];
    for k in [1, 3] {
        let (_, wall, cpu, runs, _, _) = timed(&models, |v| {
            propagate_objects(&scene, &prompts[..k], v, &opts)
        })?;
        eprintln!("demo, {k} object(s) in one pass: {wall:.1} s wall, {cpu:.1} s CPU, {runs} encoder runs");
        scaling.push(Scaling {
            objects: prompts[..k].iter().map(|p| p.name.clone()).collect(),
            wall_s: wall,
            cpu_s: cpu,
            encoder_runs: runs,
        });
    }

    let mut results: Vec<MethodResult> = vec![];
    write_report(&out_dir, &args, &load_start, t0, &opts, &results, &scaling)?;
    results.extend(compare(&models, "demo", &scene, &prompts, &truth)?);
    write_report(&out_dir, &args, &load_start, t0, &opts, &results, &scaling)?;

    if let Some(model) = &lego_model {
        let lego = Scene::load(model)?;
        let truth = Truth {
            masks: vec![alpha_truth(&lego)?],
            visible: vec![None],
        };
        let prompts = [ObjectPrompt::click(&lego, "lego", "r_0", [397.5, 492.5])?];
        results.extend(compare(&models, "lego", &lego, &prompts, &truth)?);
    }

    write_report(&out_dir, &args, &load_start, t0, &opts, &results, &scaling)
}

/// Write the JSON and the chart (after every phase, so a long run leaves its results so far).
fn write_report(
    out_dir: &std::path::Path,
    args: &[String],
    load_start: &str,
    t0: Instant,
    opts: &PropagationOptions,
    results: &[MethodResult],
    scaling: &[Scaling],
) -> Result<()> {
    let commit = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    let ratio =
        |f: fn(&Scaling) -> f64| (scaling.len() == 2).then(|| f(&scaling[1]) / f(&scaling[0]));
    let report = Report {
        command: args.join(" "),
        machine: bench::machine(),
        note: "shared machine: other jobs ran at the same time (see the load averages); CPU seconds are this process's".into(),
        load_average_start: load_start.to_string(),
        load_average_end: load_avg(),
        git_commit: commit,
        options: format!("{opts:?}"),
        three_over_one_wall: ratio(|s| s.wall_s),
        three_over_one_cpu: ratio(|s| s.cpu_s),
        results,
        scaling,
        peak_rss_mib: peak_rss_mib(),
        total_s: t0.elapsed().as_secs_f64(),
    };
    std::fs::create_dir_all(out_dir).map_err(|e| objnerf::Error::io(out_dir, e))?;
    let json = out_dir.join("segment_bench.json");
    objnerf::util::atomic::write_bytes_atomic(
        &json,
        serde_json::to_string_pretty(&report)
            .expect("report serialises")
            .as_bytes(),
    )?;
    if !results.is_empty() {
        let svg = out_dir.join("segment_bench.svg");
        let chart = chart(&report).map_err(|e| objnerf::Error::invalid(format!("chart: {e}")))?;
        objnerf::util::atomic::write_bytes_atomic(&svg, chart.as_bytes())?;
    }
    eprintln!(
        "3 objects / 1 object: {:?} wall, {:?} CPU; wrote {}",
        report.three_over_one_wall,
        report.three_over_one_cpu,
        json.display()
    );
    Ok(())
}

/// One panel per scene: mIoU against wall time, one marker per method.
fn chart(r: &Report) -> ChartResult<String> {
    let scenes: Vec<&str> = {
        let mut s: Vec<&str> = r.results.iter().map(|m| m.scene.as_str()).collect();
        s.dedup();
        s
    };
    let panels: Vec<Panel> = scenes
        .iter()
        .map(|scene| {
            let ms: Vec<&MethodResult> = r.results.iter().filter(|m| m.scene == *scene).collect();
            let layers = ms
                .iter()
                .enumerate()
                .map(|(i, m)| {
                    let name = format!("{} ({:.3})", m.method, m.miou);
                    Layer::new(name, palette(i), vec![(m.wall_s, m.miou)]).mark(Mark::Points(6))
                })
                .collect();
            let mut p = Panel::fitted(
                &format!("{scene}: mIoU vs wall time"),
                "wall time, s (shared 2-core machine)",
                "mIoU",
                layers,
            );
            p.y.end = p.y.end.min(1.0);
            p
        })
        .collect();
    svg((480 * scenes.len() as u32, 420), 1, &panels)
}
