//! Which training cameras see a point of a mesh's surface.
//!
//! A mesh's colour at a point is read along the rays of the training cameras that face it
//! ([`super::colour`]); a camera that faces the point but whose view of it is blocked (the inside
//! of a bucket seen from behind its wall) never trained the field's colour in that direction, and
//! its guess there mottles the mesh. Each camera gets a depth map of the full mesh (shadow
//! mapping): a perspective view from the camera's centre towards the mesh, wide enough to hold
//! its bounding sphere. A point is seen where it lies no deeper than the map's surface there,
//! within a tolerance for the map's resolution and for a decimated mesh lying off the full one.

use super::raster::depth_map;
use super::Mesh;
use crate::field::model::Field;
use crate::field::RayCamera;
use crate::scene::{Camera, Pose};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// How much deeper than a camera's depth map of a field's mesh a point of that mesh may lie and
/// still count as seen: two finest voxels (the marching-cubes surface and the map's sampling of
/// it differ by about a voxel; a wall thinner than this does not hide what is behind it).
pub fn occlusion_tolerance(field: &Field) -> f32 {
    2.0 * field.voxel
}

/// Pixels across a camera's depth map of the mesh's bounding sphere (the training views hold
/// an object at a few hundred pixels across; the map matches that), at most.
const MAP_SIZE: u32 = 512;

/// All the maps together stay within this many bytes: a capture of many views (a video's
/// hundreds of frames) gets coarser maps rather than hundreds of MiB of them, down to
/// [`MIN_MAP_SIZE`].
const MAPS_BUDGET_BYTES: usize = 128 << 20;
const MIN_MAP_SIZE: u32 = 128;

/// The side of each of `cameras` depth maps.
fn map_size(cameras: usize) -> u32 {
    let per = MAPS_BUDGET_BYTES / (cameras.max(1) * std::mem::size_of::<f32>());
    ((per as f64).sqrt() as u32).clamp(MIN_MAP_SIZE, MAP_SIZE)
}

/// The training cameras' centres and, where built, each camera's depth map of the mesh.
pub struct SeenFrom {
    pub centres: Vec<Vec3>,
    maps: Vec<Option<DepthMap>>,
    /// How much deeper than the map a point may lie and still be seen (world units).
    tolerance: f32,
}

/// One camera's view of the mesh: the camera (looking at the mesh's centre, its centre and axis
/// kept for the per-point test) and its depth along that axis per pixel (infinity: no surface).
struct DepthMap {
    cam: RayCamera,
    centre: Vec3,
    forward: Vec3,
    depth: Vec<f32>,
}

impl SeenFrom {
    /// Cameras at `centres` with no occlusion test: every camera facing a point sees it.
    pub fn centres_only(centres: &[Vec3]) -> SeenFrom {
        SeenFrom {
            centres: centres.to_vec(),
            maps: Vec::new(),
            tolerance: 0.0,
        }
    }

    /// Cameras at `centres`, each with a depth map of `mesh`: a point is seen from a camera
    /// where no part of `mesh` lies more than `tolerance` (world units) in front of it. A camera
    /// within the mesh's bounding sphere gets no map (it sees every point it faces).
    pub fn with_occlusion(centres: &[Vec3], mesh: &Mesh, tolerance: f32) -> SeenFrom {
        let (lo, hi) = mesh.bounds();
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        if mesh.triangles.is_empty() || !lo.is_finite() || !hi.is_finite() {
            return SeenFrom::centres_only(centres);
        }
        let (centre, radius) = ((lo + hi) * 0.5, ((hi - lo) * 0.5).length().max(1e-6));
        let size = map_size(centres.len());
        let maps = centres
            .par_iter()
            .map(|c| {
                let cam = map_camera(*c, centre, radius, size)?;
                let depth = depth_map(mesh, &cam);
                let forward = cam.pose.camera_to_world_dir(DVec3::Z).as_vec3();
                Some(DepthMap {
                    centre: cam.center(),
                    forward,
                    cam,
                    depth,
                })
            })
            .collect();
        SeenFrom {
            centres: centres.to_vec(),
            maps,
            tolerance,
        }
    }

    /// Whether camera `i` sees `p` (`slack`: how far the point may lie off the mapped mesh, as
    /// a decimated mesh's does, on top of the tolerance). True where the camera has no map.
    pub fn sees(&self, i: usize, p: Vec3, slack: f32) -> bool {
        let Some(Some(map)) = self.maps.get(i) else {
            return true;
        };
        let Some((x, y)) = map.cam.project(p) else {
            return true;
        };
        let z = (p - map.centre).dot(map.forward);
        // The deepest surface among the pixel and its neighbours: a point on a silhouette or on
        // a surface seen at a grazing angle is not hidden by its own pixel's neighbour.
        let (w, h) = (map.cam.width as i64, map.cam.height as i64);
        let (px, py) = (x.floor() as i64, y.floor() as i64);
        let mut deepest = f32::NEG_INFINITY;
        for yy in (py - 1).max(0)..=(py + 1).min(h - 1) {
            for xx in (px - 1).max(0)..=(px + 1).min(w - 1) {
                deepest = deepest.max(map.depth[(xx + w * yy) as usize]);
            }
        }
        deepest == f32::NEG_INFINITY || z <= deepest + self.tolerance + slack
    }
}

/// A square pinhole camera of `size` pixels at `eye` looking at `centre`, its field of view just
/// holding the sphere of `radius` there; None when the eye is within the sphere.
fn map_camera(eye: Vec3, centre: Vec3, radius: f32, size: u32) -> Option<RayCamera> {
    let dist = (centre - eye).length();
    if !dist.is_finite() || dist <= radius * 1.02 {
        return None;
    }
    let half_angle = (radius / dist).asin() * 1.02;
    let f = 0.5 * size as f64 / (half_angle as f64).tan();
    let c = 0.5 * size as f64;
    let camera = Camera::pinhole(size, size, f, f, c, c);
    let dir = (centre - eye).as_dvec3() / dist as f64;
    let up = if dir.z.abs() < 0.9 {
        DVec3::Z
    } else {
        DVec3::X
    };
    let pose = Pose::look_at(eye.as_dvec3(), centre.as_dvec3(), up);
    Some(RayCamera::new(String::new(), camera, pose))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis-aligned cube from `lo` to `hi` (12 triangles, outward winding not needed here).
    fn cube(lo: Vec3, hi: Vec3) -> Mesh {
        let v = |i: u32| {
            let b = |k: u32| (i >> k) & 1 == 1;
            let pick = |k: u32, a: f32, b2: f32| if b(k) { b2 } else { a };
            [
                pick(0, lo.x, hi.x),
                pick(1, lo.y, hi.y),
                pick(2, lo.z, hi.z),
            ]
        };
        let positions: Vec<[f32; 3]> = (0..8).map(v).collect();
        let quads = [
            [0, 1, 3, 2],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 3, 7, 5],
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        let mut m = Mesh {
            name: "cube".into(),
            positions,
            triangles,
            ..Default::default()
        };
        m.compute_normals();
        m
    }

    #[test]
    fn a_point_behind_a_wall_is_hidden_and_one_in_front_is_seen() {
        // A wall (a thin box) at x in [0, 0.1]; cameras on either side, 3 units away.
        let wall = cube(Vec3::new(0.0, -1.0, -1.0), Vec3::new(0.1, 1.0, 1.0));
        let cams = [Vec3::new(-3.0, 0.0, 0.2), Vec3::new(3.0, 0.0, 0.2)];
        let seen = SeenFrom::with_occlusion(&cams, &wall, 0.01);
        let near_face = Vec3::new(0.0, 0.3, -0.2); // on the face towards camera 0
        let far_face = Vec3::new(0.1, 0.3, -0.2); // on the face towards camera 1
        assert!(seen.sees(0, near_face, 0.0));
        assert!(!seen.sees(1, near_face, 0.0));
        assert!(seen.sees(1, far_face, 0.0));
        assert!(!seen.sees(0, far_face, 0.0));
        // The slack lets a point a little behind the surface (a decimated mesh's) be seen.
        assert!(!seen.sees(0, Vec3::new(0.05, 0.3, -0.2), 0.0));
        assert!(seen.sees(0, Vec3::new(0.05, 0.3, -0.2), 0.06));
        // Without maps every camera sees everything.
        let all = SeenFrom::centres_only(&cams);
        assert!(all.sees(1, near_face, 0.0) && all.sees(0, far_face, 0.0));
    }

    #[test]
    fn many_cameras_share_a_memory_budget() {
        assert_eq!(map_size(100), MAP_SIZE); // lego's 100 views: full size
        assert!(map_size(300) < MAP_SIZE && map_size(300) > MIN_MAP_SIZE);
        assert!(300 * (map_size(300) as usize).pow(2) * 4 <= MAPS_BUDGET_BYTES);
        assert_eq!(map_size(100_000), MIN_MAP_SIZE);
    }

    #[test]
    fn a_camera_inside_the_mesh_bounds_tests_nothing() {
        let wall = cube(Vec3::new(0.0, -1.0, -1.0), Vec3::new(0.1, 1.0, 1.0));
        let cams = [Vec3::new(0.5, 0.0, 0.0)];
        let seen = SeenFrom::with_occlusion(&cams, &wall, 0.01);
        assert!(seen.sees(0, Vec3::new(0.0, 0.3, 0.0), 0.0));
    }
}
