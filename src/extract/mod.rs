//! `objnerf extract`: click to mesh in one command. Segment (SAM + propagation) → train one field
//! per object on its ok views → marching cubes → turntable renders, with one progress bar per
//! stage and a report of what each stage did, how long it took and the memory it peaked at.
//!
//! Layout of the run folder (written under a temporary name, renamed into place at the end):
//! ```text
//! RUN/report.json                 everything below, summarised
//! RUN/mesh.glb                    every object, one node each (+Y up)
//! RUN/segment/                    `objnerf segment`'s output: masks/<object>/, <object>_points.ply,
//!                                 contact_sheet_<object>.png, report.json
//! RUN/<object>/model.objf         the object's field
//! RUN/<object>/mesh.glb, mesh.ply the object alone (.ply in the capture's frame)
//! RUN/<object>/turntable/         frame_NNN.png, and turntable.gif beside it
//! ```

pub mod cli;
pub mod turntable;

use crate::error::{Error, Result};
use crate::field::commands::{self as fc, DepthMode, TrainArgs, TrainReport};
use crate::field::{MaskSource, SetupConfig};
use crate::mesh::frame::GltfFrame;
use crate::mesh::from_field::{mesh_field, FieldMeshOptions, FieldMeshReport};
use crate::mesh::{cli::write_mesh, gltf::write_glbs, Mesh};
use crate::scene::Scene;
use crate::segment::propagate::{ObjectPrompt, PropagationOptions, ViewStatus};
use crate::segment::run::segment_scene;
use crate::util::{mem::peak_rss_mib, progress, AtomicDir};
use glam::DVec3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;
pub use turntable::TurntableOptions;

/// Everything `extract` can be told.
#[derive(Clone, Debug)]
pub struct ExtractOptions {
    pub propagation: PropagationOptions,
    /// Train on images downscaled by this factor.
    pub downscale: u32,
    /// Training stops after this many seconds per object (None: steps or a plateau).
    pub time_budget: Option<f64>,
    pub steps: usize,
    pub depth: DepthMode,
    pub seed: u64,
    pub setup: SetupConfig,
    pub mesh: FieldMeshOptions,
    pub turntable: TurntableOptions,
    pub overwrite: bool,
    /// Hold out every n-th view (index % n == n / 2) from training, for evaluation (0: none).
    pub hold_out_every: usize,
    /// Show progress bars.
    pub progress: bool,
}

impl Default for ExtractOptions {
    fn default() -> Self {
        ExtractOptions {
            propagation: PropagationOptions::default(),
            downscale: 1,
            time_budget: Some(120.0),
            steps: 20_000,
            depth: DepthMode::Sparse,
            seed: 0,
            setup: SetupConfig::default(),
            mesh: FieldMeshOptions::default(),
            turntable: TurntableOptions::default(),
            overwrite: false,
            hold_out_every: 0,
            progress: true,
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct SegmentationSummary {
    pub num_views: usize,
    pub num_ok: usize,
    pub num_obstructed: usize,
    pub num_absent: usize,
    pub num_points: usize,
    /// Views segmentation marked ok (held-out ones included).
    pub ok_views: Vec<String>,
    /// Views left out of training because segmentation did not mark them ok.
    pub excluded: Vec<String>,
    /// Ok views held out of training for evaluation.
    pub held_out: Vec<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct ObjectReport {
    pub name: String,
    pub segmentation: SegmentationSummary,
    pub train: TrainReport,
    pub train_seconds: f64,
    pub mesh: FieldMeshReport,
    pub mesh_seconds: f64,
    pub render_seconds: f64,
    pub model: PathBuf,
    pub mesh_glb: PathBuf,
    pub turntable_gif: PathBuf,
}

#[derive(Clone, Debug, Serialize)]
pub struct StageSeconds {
    pub segment: f64,
    pub train: f64,
    pub mesh: f64,
    pub render: f64,
    pub total: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct ExtractReport {
    pub scene: PathBuf,
    pub out: PathBuf,
    pub objects: Vec<ObjectReport>,
    pub seconds: StageSeconds,
    pub segment_encoder_runs: usize,
    pub peak_rss_mib: u64,
    pub frame: GltfFrame,
    /// Filled in by callers that know the truth (the demo).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<serde_json::Value>,
}

/// Run the whole pipeline for `prompts` on `scene_path`, writing `out`.
pub fn extract(
    scene_path: &Path,
    scene: &Scene,
    prompts: &[ObjectPrompt],
    opts: &ExtractOptions,
    out: &Path,
) -> Result<ExtractReport> {
    if opts.downscale == 0 {
        return Err(Error::invalid("--downscale must be at least 1"));
    }
    let t0 = Instant::now();
    let dest = AtomicDir::new(out, opts.overwrite)?;
    let root = dest.path().to_path_buf();
    // The folder the final run will be at: paths in the report point there.
    let final_path = |p: &Path| out.join(p.strip_prefix(&root).unwrap_or(p));

    let seg_dir = root.join("segment");
    let (seg_report, segs) = segment_scene(
        scene,
        prompts,
        &opts.propagation,
        &seg_dir,
        false,
        opts.progress,
    )?;
    let t_segment = t0.elapsed().as_secs_f64();
    let frame = GltfFrame::for_scene(scene);
    let up = DVec3::from_array(frame.up);

    let mut objects = Vec::new();
    let mut meshes: Vec<Mesh> = Vec::new();
    let (mut t_train, mut t_mesh, mut t_render) = (0.0, 0.0, 0.0);
    for (obj, seg) in seg_report.objects.iter().zip(&segs) {
        let dir = root.join(&obj.name);
        let excluded: Vec<String> = obj
            .views
            .iter()
            .filter(|v| v.status != ViewStatus::Ok)
            .map(|v| v.view.clone())
            .collect();
        let held_out: Vec<String> = obj
            .views
            .iter()
            .enumerate()
            .filter(|(i, v)| {
                let n = opts.hold_out_every;
                n > 0 && i % n == n / 2 && v.status == ViewStatus::Ok
            })
            .map(|(_, v)| v.view.clone())
            .collect();
        let summary = SegmentationSummary {
            num_views: obj.views.len(),
            num_ok: obj.num_ok,
            num_obstructed: obj.num_obstructed,
            num_absent: obj.num_absent,
            num_points: seg.points.len(),
            ok_views: obj
                .views
                .iter()
                .filter(|v| v.status == ViewStatus::Ok)
                .map(|v| v.view.clone())
                .collect(),
            excluded: excluded.clone(),
            held_out: held_out.clone(),
        };
        if obj.num_ok == 0 {
            return Err(Error::invalid(format!(
                "'{}': segmentation found no unobstructed view to train on (see {})",
                obj.name,
                final_path(&seg_dir.join(format!("contact_sheet_{}.png", obj.name))).display()
            )));
        }

        let t = Instant::now();
        let model = dir.join("model.objf");
        let args = TrainArgs {
            scene: scene_path.to_path_buf(),
            masks: MaskSource::Dir(seg_dir.join("masks").join(&obj.name)),
            out: model.clone(),
            downscale: opts.downscale,
            time_budget: opts.time_budget,
            depth: opts.depth,
            seed: opts.seed,
            steps: opts.steps,
            setup: opts.setup.clone(),
            resume: None,
            exclude_views: [excluded, held_out].concat(),
        };
        let mut bar = progress::TrainProgress::new(opts.steps, &format!("train {}", obj.name));
        let train = fc::train(&args, |s, secs| {
            if opts.progress {
                bar.update(s, secs)
            }
        })?;
        bar.finish();
        let train_seconds = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let field = crate::field::io::load_field(&model)?.field;
        let (mesh, mesh_report) = mesh_field(&field, &obj.name, &opts.mesh)
            .map_err(|e| Error::invalid(format!("'{}': {e}", obj.name)))?;
        write_mesh(&mesh, &frame, &dir.join("mesh.glb"))?;
        write_mesh(&mesh, &frame, &dir.join("mesh.ply"))?;
        let mesh_seconds = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let n = opts.turntable.frames as u64;
        let rbar = progress::bar(n, &format!("render {}", obj.name));
        if !opts.progress {
            rbar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
        }
        let gif = dir.join("turntable.gif");
        let (lo, hi) = mesh.bounds();
        turntable::write_turntable(
            &field,
            (
                glam::Vec3::from(lo).as_dvec3(),
                glam::Vec3::from(hi).as_dvec3(),
            ),
            up,
            &opts.turntable,
            [1.0; 3],
            &dir.join("turntable"),
            &gif,
            |i| rbar.set_position(i as u64),
        )?;
        rbar.finish_and_clear();
        let render_seconds = t.elapsed().as_secs_f64();

        t_train += train_seconds;
        t_mesh += mesh_seconds;
        t_render += render_seconds;
        meshes.push(mesh);
        objects.push(ObjectReport {
            name: obj.name.clone(),
            segmentation: summary,
            train,
            train_seconds,
            mesh: mesh_report,
            mesh_seconds,
            render_seconds,
            model: final_path(&model),
            mesh_glb: final_path(&dir.join("mesh.glb")),
            turntable_gif: final_path(&gif),
        });
    }
    let turned: Vec<Mesh> = meshes
        .iter()
        .map(|m| {
            let mut t = m.clone();
            t.transform(frame.matrix());
            t
        })
        .collect();
    write_glbs(&turned, &root.join("mesh.glb"), Some(frame.extras()))?;

    let report = ExtractReport {
        scene: scene_path.to_path_buf(),
        out: out.to_path_buf(),
        objects,
        seconds: StageSeconds {
            segment: t_segment,
            train: t_train,
            mesh: t_mesh,
            render: t_render,
            total: t0.elapsed().as_secs_f64(),
        },
        segment_encoder_runs: seg_report.encoder_runs,
        peak_rss_mib: peak_rss_mib(),
        frame,
        truth: None,
    };
    write_report(&root.join("report.json"), &report)?;
    dest.commit()?;
    Ok(report)
}

pub fn write_report(path: &Path, report: &ExtractReport) -> Result<()> {
    let json = serde_json::to_string_pretty(report).map_err(|e| Error::json(path, e))?;
    crate::util::atomic::write_bytes_atomic(path, json.as_bytes())
}
