//! A saved run of `objnerf segment` (or the `segment/` folder of an `objnerf extract` run), read
//! back by later commands (export, removal): its scene, its objects, each view's status per object, the masks and segmented points.

use crate::error::{Error, Result};
use crate::scene::formats::{nerfstudio::read_json_file, ply};
use crate::scene::io::mask_file;
use crate::scene::Scene;
use crate::segment::output::masks_dir;
use glam::DVec3;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The parts of the segmentation's report.json an export reads.
#[derive(Deserialize)]
struct Report {
    scene: PathBuf,
    objects: Vec<ReportObject>,
}

#[derive(Deserialize)]
struct ReportObject {
    name: String,
    views: Vec<ReportView>,
}

#[derive(Deserialize)]
struct ReportView {
    view: String,
    status: String,
}

/// One segmented object: its name and each view's status ("ok", "obstructed", "absent").
pub struct RunObject {
    pub name: String,
    pub status: HashMap<String, String>,
}

/// A segmentation run, opened.
pub struct SegmentRun {
    /// The folder holding report.json and masks/.
    pub dir: PathBuf,
    pub scene: Scene,
    pub objects: Vec<RunObject>,
}

impl SegmentRun {
    /// The segmentation folder of a run: `RUN/segment/` (extract) or `RUN/` (segment); `None`
    /// when `input` is neither (a scene).
    pub fn find(input: &Path) -> Option<PathBuf> {
        if input.join("segment/report.json").is_file() {
            Some(input.join("segment"))
        } else if input.join("report.json").is_file() && input.join("masks").is_dir() {
            Some(input.to_path_buf())
        } else {
            None
        }
    }

    /// Read the report and load the scene it names.
    pub fn open(dir: &Path) -> Result<SegmentRun> {
        let report_path = dir.join("report.json");
        let report: Report = read_json_file(&report_path)?;
        let scene = Scene::load(&resolve_scene(&report_path, dir, &report.scene)?)?;
        let objects = report
            .objects
            .into_iter()
            .map(|o| RunObject {
                name: o.name,
                status: o.views.into_iter().map(|v| (v.view, v.status)).collect(),
            })
            .collect();
        Ok(SegmentRun {
            dir: dir.to_path_buf(),
            scene,
            objects,
        })
    }

    /// The object called `name`, or an error listing the run's objects.
    pub fn object(&self, name: &str) -> Result<&RunObject> {
        self.objects.iter().find(|o| o.name == name).ok_or_else(|| {
            Error::invalid(format!(
                "{}: no object '{name}' in this run (objects: {})",
                self.dir.join("report.json").display(),
                self.object_names().join(", ")
            ))
        })
    }

    pub fn object_names(&self) -> Vec<&str> {
        self.objects.iter().map(|o| o.name.as_str()).collect()
    }

    /// The mask `objnerf segment` wrote for view `image_name` of `object` (the one mask-name
    /// rule, [`mask_file`]).
    pub fn mask_path(&self, object: &str, image_name: &str) -> PathBuf {
        mask_file(&masks_dir(&self.dir, object), image_name)
    }

    /// The object's segmented sparse points (`<object>_points.ply`).
    pub fn object_points(&self, object: &str) -> Result<Vec<(DVec3, [u8; 3])>> {
        ply::read_points(&self.dir.join(format!("{object}_points.ply")))
    }
}

/// The report's scene path: as written, or (when it was relative to the folder the run was made
/// from) relative to one of the run's parent folders.
fn resolve_scene(report_path: &Path, dir: &Path, scene: &Path) -> Result<PathBuf> {
    if scene.exists() || scene.is_absolute() {
        return Ok(scene.to_path_buf());
    }
    crate::util::paths::absolute(dir)
        .ancestors()
        .map(|a| a.join(scene))
        .find(|p| p.exists())
        .ok_or_else(|| {
            Error::format(
                report_path,
                format!(
                    "its scene {} is not found (a relative path is read from the folder the run was made in: export from there)",
                    scene.display()
                ),
            )
        })
}
