//! `objnerf camera-path`: read a nerfstudio camera_path.json as objnerf reads it (data frame, or
//! the viewer's frame with the run's dataparser_transforms.json), print its cameras, and
//! optionally write it again in the data frame.

use super::print_json;
use clap::Args;
use objnerf::scene::camera_path::{CameraPath, DataparserTransform, PathFrame};
use objnerf::{Result, Scene};
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(Args)]
pub struct CameraPathCmd {
    /// A camera_path.json (nerfstudio's viewer, ns-render, the Blender add-on, objnerf).
    path: PathBuf,
    /// The path is in nerfstudio's viewer frame: the training run's dataparser_transforms.json.
    #[arg(long)]
    dataparser_transforms: Option<PathBuf>,
    /// The dataset the nerfstudio run trained on (its applied_transform is undone as well).
    #[arg(long, requires = "dataparser_transforms")]
    scene: Option<PathBuf>,
    /// Write the path again in the data frame (the dataset's own world) to this file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print every camera as JSON (camera_to_world: 16 row-major numbers, OpenGL axes, data
    /// frame; fx, fy, cx, cy in pixels) instead of a summary.
    #[arg(long)]
    json: bool,
}

impl CameraPathCmd {
    pub fn run(self) -> Result<()> {
        let frame = match &self.dataparser_transforms {
            None => PathFrame::Data,
            Some(dpt) => {
                let applied = match &self.scene {
                    Some(s) => Scene::load(s)?.applied_transform,
                    None => None,
                };
                PathFrame::Viewer(DataparserTransform::read(dpt, applied)?)
            }
        };
        let path = CameraPath::read(&self.path, &frame)?;
        if let Some(out) = &self.out {
            path.write(out, &PathFrame::Data)?;
        }
        if self.json {
            print_json(&describe(&path));
        } else {
            print!("{}", summary(&self, &path));
        }
        Ok(())
    }
}

/// The path's cameras, in the data frame, as JSON.
fn describe(path: &CameraPath) -> Value {
    let cameras: Vec<Value> = path
        .cameras
        .iter()
        .map(|c| {
            let m = c.pose.c2w_opengl();
            let mut flat: Vec<f64> = m.iter().flatten().copied().collect();
            flat.extend([0.0, 0.0, 0.0, 1.0]);
            let ((fx, fy), (cx, cy)) = (c.camera.focal(), c.camera.principal_point());
            json!({
                "camera_to_world": flat,
                "fx": fx, "fy": fy, "cx": cx, "cy": cy,
                "width": c.camera.width, "height": c.camera.height,
                "model": c.camera.model.name(),
            })
        })
        .collect();
    json!({
        "camera_type": path.lens.name(),
        "render_width": path.width,
        "render_height": path.height,
        "fps": path.fps,
        "seconds": path.seconds,
        "cameras": cameras,
    })
}

fn summary(cmd: &CameraPathCmd, path: &CameraPath) -> String {
    let first = &path.cameras[0];
    let fov = 2.0
        * (0.5 * path.height as f64 / first.camera.focal().1)
            .atan()
            .to_degrees();
    let centres: Vec<_> = path.cameras.iter().map(|c| c.pose.center()).collect();
    let length = centres
        .windows(2)
        .fold(0.0, |a, w| a + (w[1] - w[0]).length());
    let mut s = format!(
        "{}: {} {} camera(s) at {}x{}, {} fps, {} s\n",
        cmd.path.display(),
        path.cameras.len(),
        path.lens.name(),
        path.width,
        path.height,
        path.fps,
        path.seconds
    );
    s += &match &cmd.dataparser_transforms {
        Some(d) => format!(
            "read in nerfstudio's viewer frame, undone with {}{}\n",
            d.display(),
            if cmd.scene.is_some() {
                " and the dataset's applied_transform"
            } else {
                ""
            }
        ),
        None => "read in the data frame (the dataset's own world)\n".into(),
    };
    s += &format!(
        "first camera: centre {:.4?}, vertical fov {fov:.3} deg; path length {length:.4} (scene units)\n",
        first.pose.center().to_array()
    );
    if let Some(out) = &cmd.out {
        s += &format!("wrote {} (data frame)\n", out.display());
    }
    s
}
