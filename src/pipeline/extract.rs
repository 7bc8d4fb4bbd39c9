//! `objnerf extract`: click to mesh in one command. Segment (SAM + propagation) → train one field
//! per object on its ok views → marching cubes → turntable renders, with progress reported per
//! stage and a report of what each stage did, how long it took and the memory it peaked at. The
//! scene, the masks and each field stay in memory from stage to stage; files are written for the
//! user, never read back.
//!
//! Layout of the run folder (written under a temporary name, renamed into place at the end):
//! ```text
//! RUN/report.json                 everything below, summarised
//! RUN/report.html                 the same for a person, offline: scores, warnings, each object's
//!                                 mesh in a glTF viewer (RUN/viewer/), turntable, contact sheet
//! RUN/mesh.glb                    every object, one node each (+Y up, the capture's origin)
//! RUN/segment/                    `objnerf segment`'s output: masks/<object>/, <object>_points.ply,
//!                                 contact_sheet_<object>.png, report.json
//! RUN/<object>/model.objf         the object's field
//! RUN/<object>/mesh.glb          the object alone: decimated, textured, unlit, origin at its base
//! RUN/<object>/mesh.ply          the full marching-cubes mesh, vertex colours, capture's frame
//! RUN/<object>/turntable/         frame_NNN.png, and turntable.gif beside it
//! ```

use crate::error::{Error, Result};
use crate::field::holdout::HoldOut;
use crate::field::MaskSource;
use crate::fit::{fit_object, model_notes, FieldKind, FitOptions};
use crate::mesh::colour::view_centres;
use crate::mesh::frame::{GltfFrame, Origin, Placement};
use crate::mesh::from_field::{mesh_field, FieldMeshOptions};
use crate::mesh::textured::export_mesh;
use crate::mesh::{gltf::write_glbs, io::write_mesh, Mesh};
use crate::pipeline::extract_checks::{check_views, field_warnings, mesh_warnings};
pub use crate::pipeline::extract_report::{
    ExtractReport, ObjectReport, SegmentationSummary, StageSeconds,
};
use crate::pipeline::report_html::write_report_html;
use crate::render::{write_turntable, Orbit, TurntableOptions};
use crate::sam::Segmenter;
use crate::scene::Scene;
use crate::segment::output::masks_dir;
use crate::segment::{
    segment_scene, ObjectPrompt, ObjectSegmentation, PropagationOptions, ViewStatus,
};
use crate::util::{mem::peak_rss_mib, AtomicDir, Progress, Warning};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Everything `extract` can be told.
#[derive(Clone, Debug)]
pub struct ExtractOptions {
    pub propagation: PropagationOptions,
    /// Training, per object (its `exclude_views` are filled in from the segmentation).
    pub fit: FitOptions,
    pub mesh: FieldMeshOptions,
    pub turntable: TurntableOptions,
    pub overwrite: bool,
    /// Views held out of training, for evaluation (none: `check_views` kept back instead).
    pub hold_out: HoldOut,
    /// Without `hold_out`: at most this many ok views kept out of training to check the
    /// field on ([`crate::pipeline::extract_checks::check_views`]).
    pub check_views: usize,
}

impl Default for ExtractOptions {
    fn default() -> Self {
        ExtractOptions {
            propagation: PropagationOptions::default(),
            fit: FitOptions {
                time_budget: Some(120.0),
                depth: crate::supervision::DepthMode::Sparse,
                ..Default::default()
            },
            mesh: FieldMeshOptions::default(),
            turntable: TurntableOptions::default(),
            overwrite: false,
            hold_out: HoldOut::None,
            check_views: 3,
        }
    }
}

/// Run the whole pipeline for `prompts` on `scene`, writing `out`. `seg` is SAM; `progress`
/// hears one stage per step of the work (segment, then train, render per object).
pub fn extract(
    scene: &Scene,
    prompts: &[ObjectPrompt],
    opts: &ExtractOptions,
    seg: &Segmenter,
    out: &Path,
    progress: &dyn Progress,
) -> Result<ExtractReport> {
    if opts.fit.downscale == 0 {
        return Err(Error::invalid("--downscale must be at least 1"));
    }
    let t0 = Instant::now();
    let dest = AtomicDir::new(out, opts.overwrite)?;
    let root = dest.path().to_path_buf();
    let run = RunFolder {
        root: root.clone(),
        out: out.to_path_buf(),
    };
    let seg_dir = root.join("segment");
    let (seg_report, segs) = segment_scene(
        scene,
        prompts,
        &opts.propagation,
        seg,
        &seg_dir,
        false,
        progress,
    )?;
    let t_segment = t0.elapsed().as_secs_f64();
    // The run's frame: the capture's origin (objects keep their places), at the scale asked for.
    let placement = Placement {
        origin: Origin::Capture,
        height_metres: None,
        ..opts.mesh.placement
    };
    let capture_frame = GltfFrame::for_scene(scene);
    let frame = placement.frame(&capture_frame, &[])?;

    let mut objects = Vec::new();
    let mut meshes: Vec<Mesh> = Vec::new();
    let mut warnings = seg_report.warnings.clone();
    for obj in &segs {
        let (report, mesh, w) = extract_object(scene, obj, opts, &capture_frame, &run, progress)?;
        objects.push(report);
        meshes.push(mesh);
        warnings.extend(w);
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

    let sum = |f: fn(&ObjectReport) -> f64| objects.iter().map(f).sum();
    let report = ExtractReport {
        scene: scene.source.clone(),
        out: out.to_path_buf(),
        seconds: StageSeconds {
            segment: t_segment,
            train: sum(|o| o.train_seconds),
            mesh: sum(|o| o.mesh_seconds),
            render: sum(|o| o.render_seconds),
            total: t0.elapsed().as_secs_f64(),
        },
        objects,
        segment_encoder_runs: seg_report.encoder_runs,
        peak_rss_mib: peak_rss_mib(),
        frame,
        warnings,
        truth: None,
    };
    write_report(&root, &report)?;
    dest.commit()?;
    Ok(report)
}

/// The run folder being written (`root`, a temporary name) and where it will end up (`out`):
/// paths in the report point at the final place.
struct RunFolder {
    root: PathBuf,
    out: PathBuf,
}

impl RunFolder {
    fn final_path(&self, p: &Path) -> PathBuf {
        self.out.join(p.strip_prefix(&self.root).unwrap_or(p))
    }
}

/// Train, mesh and render one segmented object into `RUN/<object>/`; its field's and mesh's
/// self-checks.
fn extract_object(
    scene: &Scene,
    obj: &ObjectSegmentation,
    opts: &ExtractOptions,
    frame: &GltfFrame,
    run: &RunFolder,
    progress: &dyn Progress,
) -> Result<(ObjectReport, Mesh, Vec<Warning>)> {
    let dir = run.root.join(&obj.name);
    let summary = summarise(obj, opts.hold_out, opts.check_views);
    if summary.num_ok == 0 {
        let sheet = run
            .root
            .join("segment")
            .join(format!("contact_sheet_{}.png", obj.name));
        return Err(Error::invalid(format!(
            "'{}': segmentation found no unobstructed view to train on (see {})",
            obj.name,
            run.final_path(&sheet).display()
        )));
    }

    let t = Instant::now();
    let fit = FitOptions {
        exclude_views: [summary.excluded.clone(), summary.held_out.clone()].concat(),
        ..opts.fit.clone()
    };
    let masks = MaskSource::Images(Arc::new(obj.views.iter().map(|v| v.mask.clone()).collect()));
    progress.begin(&format!("train {}", obj.name), fit.steps as u64);
    let fitted = fit_object(scene, &masks, &fit, None, &mut |s| {
        progress.advance(s.step as u64, s.detail())
    })?;
    progress.end();
    let model = dir.join("model.objf");
    let notes = model_notes(FieldKind::Object, scene, &fit, &fitted.report);
    let mesh_opts = FieldMeshOptions {
        seen_from: view_centres(&notes),
        ..opts.mesh.clone()
    };
    crate::field::io::save(
        &model,
        &fitted.trainer.parts(crate::field::io::IDENTITY, notes),
    )?;
    let train_seconds = t.elapsed().as_secs_f64();
    let field = &fitted.trainer.field;
    let (held_out_check, mut warnings) = field_warnings(
        scene,
        obj,
        &summary.held_out,
        fit.downscale,
        field,
        &fitted.report,
        fit.steps,
    )?;

    let t = Instant::now();
    let up = DVec3::from_array(frame.up);
    let (full, mesh_report) = mesh_field(field, &obj.name, &mesh_opts, Some(up))
        .map_err(|e| Error::invalid(format!("'{}': {e}", obj.name)))?;
    let (mesh, export) = export_mesh(
        field,
        &full,
        &mesh_opts.export,
        &mesh_opts.seen_from,
        mesh_opts.recolour,
    )
    .map_err(|e| Error::invalid(format!("'{}': {e}", obj.name)))?;
    let object_frame = opts.mesh.placement.frame(frame, &mesh.positions)?;
    write_mesh(&mesh, Some(&object_frame), &dir.join("mesh.glb"))?;
    write_mesh(&full, Some(frame), &dir.join("mesh.ply"))?;
    warnings.extend(mesh_warnings(&obj.name, &full, field));
    let mesh_seconds = t.elapsed().as_secs_f64();

    let t = Instant::now();
    progress.begin(
        &format!("render {}", obj.name),
        opts.turntable.frames as u64,
    );
    let gif = dir.join("turntable.gif");
    let (lo, hi) = mesh.bounds();
    let box_ = (
        glam::Vec3::from(lo).as_dvec3(),
        glam::Vec3::from(hi).as_dvec3(),
    );
    let seen_from: Vec<DVec3> = mesh_opts.seen_from.iter().map(|c| c.as_dvec3()).collect();
    let orbit = Orbit::following(
        0.5 * (box_.0 + box_.1),
        up,
        &seen_from,
        opts.turntable.elevation_deg,
    );
    write_turntable(
        field,
        box_,
        up,
        &orbit,
        &opts.turntable,
        [1.0; 3],
        &dir.join("turntable"),
        &gif,
        progress,
    )?;
    progress.end();
    let report = ObjectReport {
        name: obj.name.clone(),
        segmentation: summary,
        train: fitted.report,
        train_seconds,
        held_out_check,
        mesh: mesh_report,
        export,
        frame: object_frame,
        mesh_seconds,
        turntable: orbit,
        render_seconds: t.elapsed().as_secs_f64(),
        model: run.final_path(&model),
        mesh_glb: run.final_path(&dir.join("mesh.glb")),
        turntable_gif: run.final_path(&gif),
    };
    Ok((report, mesh, warnings))
}

/// Which views an object trains on: ok views, less those `hold_out` holds out for
/// evaluation, or without it up to `check_views` kept back for the field's
/// self-check ([`check_views`]).
fn summarise(
    obj: &ObjectSegmentation,
    hold_out: HoldOut,
    most_check_views: usize,
) -> SegmentationSummary {
    let names = |keep: &dyn Fn(usize, ViewStatus) -> bool| -> Vec<String> {
        obj.views
            .iter()
            .enumerate()
            .filter(|(i, v)| keep(*i, v.status))
            .map(|(_, v)| v.view.clone())
            .collect()
    };
    let count = |s| obj.views.iter().filter(|v| v.status == s).count();
    SegmentationSummary {
        num_views: obj.views.len(),
        num_ok: count(ViewStatus::Ok),
        num_obstructed: count(ViewStatus::Obstructed),
        num_absent: count(ViewStatus::Absent),
        num_points: obj.points.len(),
        ok_views: names(&|_, s| s == ViewStatus::Ok),
        excluded: names(&|_, s| s != ViewStatus::Ok),
        held_out: if !hold_out.is_none() {
            names(&|i, s| hold_out.holds_out(i) && s == ViewStatus::Ok)
        } else {
            check_views(obj, most_check_views)
        },
    }
}

/// Write `run/report.json` and `run/report.html` (which reads the objects' meshes from `run`).
pub fn write_report(run: &Path, report: &ExtractReport) -> Result<()> {
    let path = run.join("report.json");
    let json = serde_json::to_string_pretty(report).map_err(|e| Error::json(&path, e))?;
    crate::util::atomic::write_bytes_atomic(&path, json.as_bytes())?;
    write_report_html(run, report)
}

/// Where `extract` put an object's masks, given the run folder.
pub fn object_masks_dir(run: &Path, object: &str) -> PathBuf {
    masks_dir(&run.join("segment"), object)
}
