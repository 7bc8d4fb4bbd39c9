//! `objnerf camera-path`: read a nerfstudio camera_path.json as objnerf reads it (in the world it
//! states, else the data frame, or the viewer's frame with the run's dataparser_transforms.json),
//! print its cameras, and optionally write it again in either frame.

use super::print_json;
use clap::{Args, ValueEnum};
use objnerf::scene::camera_path::{CameraPath, DataparserTransform, FrameName, PathFrame};
use objnerf::{Error, Result, Scene};
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(Args)]
pub struct CameraPathCmd {
    /// A camera_path.json (nerfstudio's viewer, ns-render, the Blender add-on, objnerf).
    path: PathBuf,
    /// The training run's dataparser_transforms.json: reads a path in nerfstudio's viewer frame
    /// (one whose objnerf_frame says "viewer", or one that says nothing, as the viewer writes
    /// them) and writes one with --frame viewer.
    #[arg(long)]
    dataparser_transforms: Option<PathBuf>,
    /// The dataset the nerfstudio run trained on (its applied_transform is undone as well).
    #[arg(long, requires = "dataparser_transforms")]
    scene: Option<PathBuf>,
    /// Write the path again to this file, in the frame --frame names (stated in its
    /// objnerf_frame).
    #[arg(long)]
    out: Option<PathBuf>,
    /// The frame --out writes: data (the dataset's own world) or viewer (nerfstudio's, what
    /// `ns-render camera-path` reads; needs --dataparser-transforms). Default: data.
    #[arg(long, value_enum, requires = "out")]
    frame: Option<OutFrame>,
    /// Print every camera as JSON (camera_to_world: 16 row-major numbers, OpenGL axes, data
    /// frame; fx, fy, cx, cy in pixels) instead of a summary.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum OutFrame {
    Data,
    Viewer,
}

impl CameraPathCmd {
    pub fn run(self) -> Result<()> {
        let out_frame = self.frame.unwrap_or(OutFrame::Data);
        if out_frame == OutFrame::Viewer && self.dataparser_transforms.is_none() {
            return Err(Error::invalid(
                "--frame viewer needs the training run's --dataparser-transforms (and --scene, the dataset it trained on)",
            ));
        }
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
        let (path, stated) = CameraPath::read_stated(&self.path, &frame)?;
        if let Some(out) = &self.out {
            let write_in = match out_frame {
                OutFrame::Data => &PathFrame::Data,
                OutFrame::Viewer => &frame,
            };
            path.write(out, write_in)?;
        }
        if self.json {
            print_json(&describe(&path));
        } else {
            let read_in = stated.unwrap_or(frame.name());
            print!("{}", summary(&self, &path, read_in, stated.is_some()));
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

fn summary(cmd: &CameraPathCmd, path: &CameraPath, read_in: FrameName, stated: bool) -> String {
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
    let how = if stated {
        "as the file states"
    } else {
        "the file states no frame"
    };
    let undone = |d: &PathBuf| {
        let applied = match cmd.scene {
            Some(_) => " and the dataset's applied_transform",
            None => "",
        };
        format!("{}{applied}", d.display())
    };
    s += &match (read_in, &cmd.dataparser_transforms) {
        (FrameName::Viewer, Some(d)) => format!(
            "read in nerfstudio's viewer frame ({how}), undone with {}\n",
            undone(d)
        ),
        _ => format!("read in the data frame, the dataset's own world ({how})\n"),
    };
    s += &format!(
        "first camera: centre {:.4?}, vertical fov {fov:.3} deg; path length {length:.4} (scene units)\n",
        first.pose.center().to_array()
    );
    if let Some(out) = &cmd.out {
        let world = match cmd.frame {
            Some(OutFrame::Viewer) => "nerfstudio's viewer frame",
            _ => "the data frame",
        };
        s += &format!("wrote {} in {world}\n", out.display());
    }
    s
}
