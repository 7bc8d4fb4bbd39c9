//! Harder versions of the demo scene, one difficulty at a time, for the stability suite
//! (`objnerf bench stability`) and for anyone who wants to see where the pipeline breaks. Each
//! is about the mug (the object the demo extracts):
//!
//! - `out-of-frame`: every third view (never view 0) turns so that the mug sits on the image's
//!   right edge, about half of it outside the frame;
//! - `occluded`: two tall panels stand beside the mug, hiding it from the views on the -x and +y
//!   sides;
//! - `textureless`: the mug is one plain colour, and the sparse model has a twentieth of its
//!   points there (SIFT finds little on a plain surface);
//! - `distractor`: an identical mug (`mug_twin`, same shape and texture, turned) stands beside it.
//!
//! Extra objects get truth like the others (masks, meshes, visibility; their click is in the
//! first view that sees them).

use super::geometry::{Object, Placement, Shape, World};
use super::render::pixel_ray;
use crate::scene::{Camera, Pose};
use glam::{DVec2, DVec3};

/// Which variant of the demo scene to render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Variant {
    #[default]
    Standard,
    OutOfFrame,
    Occluded,
    Textureless,
    Distractor,
}

impl Variant {
    pub const ALL: [Variant; 5] = [
        Variant::Standard,
        Variant::OutOfFrame,
        Variant::Occluded,
        Variant::Textureless,
        Variant::Distractor,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Variant::Standard => "standard",
            Variant::OutOfFrame => "out-of-frame",
            Variant::Occluded => "occluded",
            Variant::Textureless => "textureless",
            Variant::Distractor => "distractor",
        }
    }

    /// The demo world for this variant.
    pub fn world(self) -> World {
        let mut w = World::demo();
        let mug = w.object("mug").cloned().expect("the demo has a mug");
        match self {
            Variant::Occluded => {
                // Panels 0.3 m tall (the sight line from the ring to the mug's rim crosses
                // their line at about 0.3 m), 0.18 m from the mug's axis.
                let c = mug.place.to_world(DVec3::ZERO);
                w.objects.push(Object::new(
                    "panel_west",
                    Shape::Cuboid {
                        half: DVec3::new(0.015, 0.26, 0.15),
                    },
                    Placement::new(c + DVec3::new(-0.2, 0.02, 0.0), 0.0),
                ));
                w.objects.push(Object::new(
                    "panel_north",
                    Shape::Cuboid {
                        half: DVec3::new(0.26, 0.015, 0.15),
                    },
                    Placement::new(c + DVec3::new(0.02, 0.2, 0.0), 0.0),
                ));
            }
            Variant::Textureless => {
                for o in &mut w.objects {
                    o.plain = o.name == "mug";
                }
            }
            Variant::Distractor => {
                let c = mug.place.to_world(DVec3::ZERO);
                w.objects.push(Object::new(
                    "mug_twin",
                    mug.shape,
                    Placement::new(c + DVec3::new(0.25, 0.1, 0.0), 120.0),
                ));
            }
            Variant::Standard | Variant::OutOfFrame => {}
        }
        w
    }

    /// Adjust the camera ring for this variant (out-of-frame turns every third view).
    pub fn adjust_poses(self, world: &World, cam: &Camera, poses: &mut [Pose]) {
        if self != Variant::OutOfFrame {
            return;
        }
        let mug = world.object("mug").expect("the demo has a mug");
        let (lo, hi) = mug.world_bbox();
        let centre = 0.5 * (lo + hi);
        for (i, pose) in poses.iter_mut().enumerate() {
            if i % 3 == 1 {
                *pose = turn_to_edge(cam, pose, centre);
            }
        }
    }
}

impl std::str::FromStr for Variant {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Variant::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Variant::ALL.iter().map(|v| v.name()).collect();
                format!("variant '{s}': use one of {}", names.join(", "))
            })
    }
}

impl std::fmt::Display for Variant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The same camera position, turned (aim moved sideways along the horizontal) until `point`
/// projects onto the image's right edge. Bisection on the aim's sideways offset.
fn turn_to_edge(cam: &Camera, pose: &Pose, point: DVec3) -> Pose {
    let eye = pose.center();
    let forward = pixel_ray(
        cam,
        pose,
        DVec2::new(cam.width as f64 * 0.5, cam.height as f64 * 0.5),
    )
    .d;
    let aim = eye + forward * (point - eye).length();
    let right = forward.cross(DVec3::Z).normalize();
    let u_of = |s: f64| {
        let p = Pose::look_at(eye, aim + right * s, DVec3::Z);
        cam.project(p.world_to_camera(point))
            .map_or(f64::NEG_INFINITY, |px| px.x)
    };
    // Aiming left (negative s) moves the point right in the image.
    let target = cam.width as f64;
    let (mut a, mut b) = (-2.0f64, 0.0f64);
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if u_of(m) > target {
            a = m;
        } else {
            b = m;
        }
    }
    Pose::look_at(eye, aim + right * (0.5 * (a + b)), DVec3::Z)
}
