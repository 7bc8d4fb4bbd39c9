//! What `extract` did, as `RUN/report.json` holds it (and `RUN/report.html` shows it).

use crate::fit::object_checks::HeldOutCheck;
use crate::fit::TrainReport;
use crate::mesh::frame::GltfFrame;
use crate::mesh::from_field::FieldMeshReport;
use crate::mesh::textured::ExportReport;
use crate::render::Orbit;
use crate::util::Warning;
use serde::Serialize;
use std::path::PathBuf;

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
    /// Ok views held out of training for evaluation and the field's self-check.
    pub held_out: Vec<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct ObjectReport {
    pub name: String,
    pub segmentation: SegmentationSummary,
    pub train: TrainReport,
    pub train_seconds: f64,
    /// The field measured on the held-out views (the self-check's figures).
    pub held_out_check: HeldOutCheck,
    /// The full marching-cubes mesh (`mesh.ply`).
    pub mesh: FieldMeshReport,
    /// The mesh in `mesh.glb`: decimation, atlas, bake, material.
    pub export: ExportReport,
    /// The object's own glTF frame (`mesh.glb`): origin and scale.
    pub frame: GltfFrame,
    pub mesh_seconds: f64,
    /// Where the turntable's cameras went (the training cameras' elevation and arc).
    pub turntable: Orbit,
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
    /// Every self-check that tripped, scene to mesh ([`crate::util::warnings`]).
    pub warnings: Vec<Warning>,
    /// Filled in by callers that know the truth (the demo).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<serde_json::Value>,
}
