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
    /// Column-major 4x4 (glTF's order), capture world -> glTF: the turn to +Y up, then the
    /// origin moved to `origin`, then scaled by `scale`.
    pub capture_to_gltf: [f64; 16],
    /// The capture's up direction.
    pub up: [f64; 3],
    pub why: String,
    /// glTF units per capture unit (1: the capture's own units).
    pub scale: f64,
    /// What the glTF origin is.
    pub origin: Origin,
    /// What one glTF unit is.
    pub units: String,
}

/// Where the glTF's origin is put.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Origin {
    /// The capture's own origin (objects keep their places relative to each other).
    #[default]
    Capture,
    /// The middle of the object's footprint at its lowest point: it stands on the ground at 0.
    Base,
    /// The centre of the object's bounding box.
    Centre,
}

impl Origin {
    pub fn parse(s: &str) -> Result<Origin> {
        match s.to_ascii_lowercase().as_str() {
            "capture" => Ok(Origin::Capture),
            "base" => Ok(Origin::Base),
            "centre" | "center" => Ok(Origin::Centre),
            _ => Err(Error::invalid(format!(
                "--origin {s}: expected base, centre or capture"
            ))),
        }
    }
}

/// Where a mesh goes in its glTF file and at what size.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Placement {
    pub origin: Origin,
    /// Metres per capture unit (None: glTF units are the capture's).
    pub metres_per_unit: Option<f64>,
    /// The object's height along up in metres: the scale that makes it so (instead of
    /// `metres_per_unit`).
    pub height_metres: Option<f64>,
}

impl Placement {
    /// `base` placed for the mesh `positions` (capture frame).
    pub fn frame(&self, base: &GltfFrame, positions: &[[f32; 3]]) -> Result<GltfFrame> {
        let scale = match (self.metres_per_unit, self.height_metres) {
            (Some(_), Some(_)) => {
                return Err(Error::invalid(
                    "give the scale or the object's height, not both",
                ))
            }
            (Some(s), None) => s,
            (None, Some(h)) if !(h > 0.0 && h.is_finite()) => {
                return Err(Error::invalid(format!(
                    "the object's height must be a positive length in metres, not {h}"
                )))
            }
            (None, Some(h)) => {
                let turn = base.matrix();
                let ys = positions.iter().map(|p| {
                    turn.transform_point3(DVec3::from_array(p.map(|x| x as f64)))
                        .y
                });
                let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, u), y| {
                    (l.min(y), u.max(y))
                });
                if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
                    return Err(Error::invalid(
                        "the mesh has no height to scale to a given height",
                    ));
                }
                h / (hi - lo)
            }
            (None, None) => 1.0,
        };
        let metres = self.metres_per_unit.is_some() || self.height_metres.is_some();
        base.placed(positions, self.origin, scale, metres)
    }
}

/// The units a scale stands for: metres when one was given, else the capture's.
const CAPTURE_UNITS: &str = "the capture's world units";

impl GltfFrame {
    /// glTF node extras recording the transform, so a mesh can be put back into the capture.
    pub fn extras(&self) -> serde_json::Value {
        serde_json::json!({
            "objnerf": {
                "capture_to_gltf": self.capture_to_gltf,
                "capture_up": self.up,
                "units": self.units,
                "scale": self.scale,
                "origin": self.origin,
            }
        })
    }

    /// This frame with the origin at `origin` of the mesh `positions` (capture frame) and
    /// scaled by `scale` glTF units per capture unit (`metres`: whether that makes metres).
    pub fn placed(
        &self,
        positions: &[[f32; 3]],
        origin: Origin,
        scale: f64,
        metres: bool,
    ) -> Result<GltfFrame> {
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(Error::invalid(format!(
                "the scale must be a positive number, not {scale}"
            )));
        }
        let turn = self.matrix();
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in positions {
            let q = turn.transform_point3(DVec3::from_array(p.map(|x| x as f64)));
            lo = lo.min(q);
            hi = hi.max(q);
        }
        let centre = 0.5 * (lo + hi);
        let o = match origin {
            _ if positions.is_empty() => DVec3::ZERO,
            Origin::Capture => DVec3::ZERO,
            Origin::Base => DVec3::new(centre.x, lo.y, centre.z),
            Origin::Centre => centre,
        };
        let m = DMat4::from_scale(DVec3::splat(scale)) * DMat4::from_translation(-o) * turn;
        Ok(GltfFrame {
            capture_to_gltf: m.to_cols_array(),
            up: self.up,
            why: self.why.clone(),
            scale,
            origin,
            units: if metres {
                "metres".into()
            } else if scale == 1.0 {
                CAPTURE_UNITS.into()
            } else {
                format!("{scale} x the capture's world units")
            },
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
            scale: 1.0,
            origin: Origin::Capture,
            units: CAPTURE_UNITS.into(),
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

    #[test]
    fn placed_at_the_base_and_scaled() {
        let f = GltfFrame::from_up(DVec3::Z, String::new());
        // A box from (1, 2, 3) to (3, 4, 7) in a Z-up capture.
        let pts = [[1.0, 2.0, 3.0], [3.0, 4.0, 7.0]];
        let p = f.placed(&pts, Origin::Base, 0.5, true).unwrap();
        let m = p.matrix();
        let a = m.transform_point3(DVec3::new(1.0, 2.0, 3.0));
        let b = m.transform_point3(DVec3::new(3.0, 4.0, 7.0));
        // Lowest point at y = 0, footprint centred on x = z = 0, height 4 * 0.5.
        assert!((a.y).abs() < 1e-12 && (b.y - 2.0).abs() < 1e-12, "{a} {b}");
        assert!((a.x + b.x).abs() < 1e-12 && (a.z + b.z).abs() < 1e-12);
        assert_eq!(p.units, "metres");
        let c = f.placed(&pts, Origin::Centre, 1.0, false).unwrap();
        let mid = c.matrix().transform_point3(DVec3::new(2.0, 3.0, 5.0));
        assert!(mid.length() < 1e-12);
        assert!(f.placed(&pts, Origin::Base, 0.0, false).is_err());
    }
}
