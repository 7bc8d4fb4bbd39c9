//! From a capture's world frame to glTF's (+Y up, right-handed, metres-or-whatever-the-capture-used).
//!
//! Capture worlds disagree on "up": NeRF-synthetic, nerfstudio, Blender and the demo scene are
//! +Z up, a COLMAP reconstruction is whatever its first camera made it. The cameras say which way
//! is up ([`Scene::up`]); a Z-up capture gets exactly the axis swap Blender's importer undoes.

use crate::error::{Error, Result};
use crate::field::io::Model;
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

    /// The frame of a model: `up` if given, else the up direction recorded at training, else the
    /// cameras of the scene it was trained on (older model files), else an error asking for it.
    pub fn for_model(model: &Model, up: Option<DVec3>) -> Result<GltfFrame> {
        if let Some(u) = up {
            return Ok(GltfFrame::from_up(u, "given with --up".into()));
        }
        if let Some(u) = model.up() {
            let why = model
                .notes
                .get("up_why")
                .and_then(|w| w.as_str())
                .unwrap_or("");
            return Ok(GltfFrame::from_up(
                u,
                format!("recorded at training: {why}"),
            ));
        }
        let scene = model.notes.get("scene").and_then(|s| s.as_str());
        match scene.map(|s| Scene::load(std::path::Path::new(s))) {
            Some(Ok(s)) => Ok(GltfFrame::for_scene(&s)),
            _ => Err(Error::invalid(format!(
                "the model records no up direction and its training scene ({}) cannot be read: give --up",
                scene.unwrap_or("unknown")
            ))),
        }
    }

    /// Up from the scene's cameras ([`Scene::up`]).
    pub fn for_scene(scene: &Scene) -> GltfFrame {
        let (up, why) = scene.up();
        GltfFrame::from_up(up, why)
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
