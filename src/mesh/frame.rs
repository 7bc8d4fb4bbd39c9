//! From a capture's world frame to glTF's (+Y up, right-handed, metres-or-whatever-the-capture-used).
//!
//! Capture worlds disagree on "up": NeRF-synthetic, nerfstudio, Blender and the demo scene are
//! +Z up, a COLMAP reconstruction is whatever its first camera made it. The cameras say which way
//! is up (people hold cameras upright), so the up direction is the mean of the cameras' up vectors,
//! snapped to a world axis when it is within 15 degrees of one (so a Z-up capture gets exactly the
//! axis swap Blender's importer undoes).

use crate::scene::Scene;
use glam::{DMat4, DQuat, DVec3};
use serde::Serialize;

/// The capture-to-glTF transform and how it was chosen.
#[derive(Clone, Debug, Serialize)]
pub struct GltfFrame {
    /// Column-major 4x4 (glTF's order), capture world -> glTF.
    pub capture_to_gltf: [f64; 16],
    /// The capture's up direction.
    pub up: [f64; 3],
    pub why: String,
}

impl GltfFrame {
    /// glTF node extras recording the transform, so a mesh can be put back into the capture.
    pub fn extras(&self) -> serde_json::Value {
        serde_json::json!({
            "objnerf": {
                "capture_to_gltf": self.capture_to_gltf,
                "capture_up": self.up,
                "units": "the capture's world units",
            }
        })
    }

    pub fn matrix(&self) -> DMat4 {
        DMat4::from_cols_array(&self.capture_to_gltf)
    }

    /// The rotation taking `up` to +Y (a Z-up world gets (x, y, z) -> (x, z, -y)).
    pub fn from_up(up: DVec3, why: String) -> GltfFrame {
        let up = up.normalize();
        let m = if (up - DVec3::Z).length() < 1e-9 {
            super::z_up_to_gltf()
        } else {
            DMat4::from_quat(DQuat::from_rotation_arc(up, DVec3::Y))
        };
        GltfFrame {
            capture_to_gltf: m.to_cols_array(),
            up: up.to_array(),
            why,
        }
    }

    /// Up from the scene's cameras (see the module notes).
    pub fn for_scene(scene: &Scene) -> GltfFrame {
        let mut sum = DVec3::ZERO;
        for im in &scene.images {
            // OpenCV camera: y points down in the image, so up is -y.
            sum -= im.pose.c2w_rotation().col(1);
        }
        if sum.length() < 1e-9 {
            return GltfFrame::from_up(DVec3::Z, "no camera agrees on up: assumed +Z".into());
        }
        let mean = sum.normalize();
        let axes = [
            DVec3::X,
            DVec3::NEG_X,
            DVec3::Y,
            DVec3::NEG_Y,
            DVec3::Z,
            DVec3::NEG_Z,
        ];
        let best = axes
            .into_iter()
            .max_by(|a, b| a.dot(mean).total_cmp(&b.dot(mean)))
            .expect("six axes");
        let angle = best.dot(mean).clamp(-1.0, 1.0).acos().to_degrees();
        if angle <= 15.0 {
            GltfFrame::from_up(
                best,
                format!(
                    "the cameras' mean up is {angle:.1} deg from world {}: snapped to it",
                    axis_name(best)
                ),
            )
        } else {
            GltfFrame::from_up(
                mean,
                format!(
                    "the cameras' mean up ({:.3}, {:.3}, {:.3}) is {angle:.1} deg from the nearest axis: used as is",
                    mean.x, mean.y, mean.z
                ),
            )
        }
    }
}

fn axis_name(a: DVec3) -> &'static str {
    match (a.x, a.y, a.z) {
        (x, _, _) if x > 0.5 => "+X",
        (x, _, _) if x < -0.5 => "-X",
        (_, y, _) if y > 0.5 => "+Y",
        (_, y, _) if y < -0.5 => "-Y",
        (_, _, z) if z > 0.5 => "+Z",
        _ => "-Z",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_up_maps_to_y_up_and_keeps_handedness() {
        let f = GltfFrame::from_up(DVec3::Z, String::new());
        let m = f.matrix();
        assert!((m.transform_vector3(DVec3::Z) - DVec3::Y).length() < 1e-12);
        assert!((m.determinant() - 1.0).abs() < 1e-12);
        let g = GltfFrame::from_up(DVec3::new(0.0, -1.0, 0.2), String::new());
        let up = DVec3::from_array(g.up);
        assert!((g.matrix().transform_vector3(up) - DVec3::Y).length() < 1e-9);
        assert!((g.matrix().determinant() - 1.0).abs() < 1e-9);
    }
}
