//! Camera poses and every conversion between frame conventions. Nothing else in objnerf flips axes.
//!
//! Internally a pose is world-to-camera in the OpenCV frame (x right, y down, z forward), as COLMAP
//! stores it. nerfstudio, Blender and NeRF-synthetic store camera-to-world in the OpenGL frame
//! (x right, y up, looking down -z): the two differ by negating the camera's y and z axes.
//!
//! A `Pose` keeps both the COLMAP form (quaternion + translation) and the camera-to-world matrix,
//! each computed once from whichever the source gave, so reading and writing the same format
//! reproduces its numbers bit for bit.

use crate::util::spread::Spread;
use glam::{DMat3, DMat4, DQuat, DVec3, DVec4};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// World-to-camera rotation as COLMAP's unit quaternion (w, x, y, z).
    qvec: [f64; 4],
    /// World-to-camera translation.
    tvec: [f64; 3],
    /// Camera-to-world, OpenCV camera axes, row-major 3x4.
    c2w: [[f64; 4]; 3],
}

/// Tolerance for "rigid": R^T R = I and det R = 1 within this.
const RIGID_TOL: f64 = 1e-3;

impl Pose {
    /// From COLMAP's world-to-camera quaternion (w, x, y, z) and translation. The quaternion is
    /// normalised for the matrix; the stored numbers stay as given.
    pub fn from_colmap(qvec: [f64; 4], tvec: [f64; 3]) -> Result<Self, String> {
        if qvec.iter().chain(tvec.iter()).any(|v| !v.is_finite()) {
            return Err(format!("pose is not finite: q={qvec:?} t={tvec:?}"));
        }
        let q = DQuat::from_xyzw(qvec[1], qvec[2], qvec[3], qvec[0]);
        let n = q.length();
        if (n - 1.0).abs() > 1e-2 {
            return Err(format!(
                "rotation quaternion is not unit length (|q| = {n})"
            ));
        }
        let r = DMat3::from_quat(q / n);
        let t = DVec3::from_array(tvec);
        let center = -(r.transpose() * t);
        Ok(Pose {
            qvec,
            tvec,
            c2w: rows_3x4(r.transpose(), center),
        })
    }

    /// From a camera-to-world matrix whose camera axes follow OpenCV.
    pub fn from_c2w_opencv(m: [[f64; 4]; 3]) -> Result<Self, String> {
        if m.iter().flatten().any(|v| !v.is_finite()) {
            return Err("transform matrix has a non-finite entry".into());
        }
        let rc = DMat3::from_cols(
            DVec3::new(m[0][0], m[1][0], m[2][0]),
            DVec3::new(m[0][1], m[1][1], m[2][1]),
            DVec3::new(m[0][2], m[1][2], m[2][2]),
        );
        check_rigid(rc)?;
        let center = DVec3::new(m[0][3], m[1][3], m[2][3]);
        let r = rc.transpose();
        let q = DQuat::from_mat3(&r).normalize();
        // COLMAP keeps qw >= 0 by convention.
        let q = if q.w < 0.0 { -q } else { q };
        let t = -(r * center);
        Ok(Pose {
            qvec: [q.w, q.x, q.y, q.z],
            tvec: t.to_array(),
            c2w: m,
        })
    }

    /// From a camera-to-world matrix in the OpenGL/Blender/nerfstudio convention.
    pub fn from_c2w_opengl(m: [[f64; 4]; 3]) -> Result<Self, String> {
        Self::from_c2w_opencv(flip_yz_columns(m))
    }

    /// A camera at `eye` looking at `target`, with `up` the world's up direction.
    pub fn look_at(eye: DVec3, target: DVec3, up: DVec3) -> Self {
        let z = (target - eye).normalize();
        let x = z.cross(up).normalize();
        let y = z.cross(x);
        Self::from_c2w_opencv(rows_3x4(DMat3::from_cols(x, y, z), eye))
            .expect("look_at makes a rigid pose")
    }

    pub fn qvec(&self) -> [f64; 4] {
        self.qvec
    }
    pub fn tvec(&self) -> [f64; 3] {
        self.tvec
    }

    /// Camera-to-world, OpenCV axes, row-major 3x4.
    pub fn c2w_opencv(&self) -> [[f64; 4]; 3] {
        self.c2w
    }

    /// Camera-to-world, OpenGL axes (as nerfstudio/Blender store it), row-major 3x4.
    pub fn c2w_opengl(&self) -> [[f64; 4]; 3] {
        flip_yz_columns(self.c2w)
    }

    /// Camera-to-world rotation (columns: the camera's x, y, z axes in the world, OpenCV).
    pub fn c2w_rotation(&self) -> DMat3 {
        let m = &self.c2w;
        DMat3::from_cols(
            DVec3::new(m[0][0], m[1][0], m[2][0]),
            DVec3::new(m[0][1], m[1][1], m[2][1]),
            DVec3::new(m[0][2], m[1][2], m[2][2]),
        )
    }

    /// The camera centre in world coordinates.
    pub fn center(&self) -> DVec3 {
        DVec3::new(self.c2w[0][3], self.c2w[1][3], self.c2w[2][3])
    }

    /// World-to-camera as a 4x4 matrix.
    pub fn w2c_matrix(&self) -> DMat4 {
        let r = self.c2w_rotation().transpose();
        let t = -(r * self.center());
        DMat4::from_cols(
            r.x_axis.extend(0.0),
            r.y_axis.extend(0.0),
            r.z_axis.extend(0.0),
            t.extend(1.0),
        )
    }

    /// Camera-to-world as a 4x4 matrix (OpenCV axes).
    pub fn c2w_matrix(&self) -> DMat4 {
        let r = self.c2w_rotation();
        DMat4::from_cols(
            r.x_axis.extend(0.0),
            r.y_axis.extend(0.0),
            r.z_axis.extend(0.0),
            self.center().extend(1.0),
        )
    }

    /// A world point in this camera's frame.
    pub fn world_to_camera(&self, p: DVec3) -> DVec3 {
        self.c2w_rotation().transpose() * (p - self.center())
    }

    /// A camera-frame direction in world coordinates.
    pub fn camera_to_world_dir(&self, d: DVec3) -> DVec3 {
        self.c2w_rotation() * d
    }

    /// This pose after a world transform `p -> s R p + t` (a similarity; `m` must be one).
    pub fn transformed(&self, m: DMat4) -> Result<Self, String> {
        let lin = DMat3::from_mat4(m);
        let s = lin.determinant().cbrt();
        if !(s.is_finite() && s > 0.0) {
            return Err("world transform is not a similarity".into());
        }
        let rot = lin * (1.0 / s);
        let r = rot * self.c2w_rotation();
        let c = m.transform_point3(self.center());
        Self::from_c2w_opencv(rows_3x4(r, c))
    }
}

/// Row-major 3x4 from a rotation and a translation column.
pub fn rows_3x4(r: DMat3, t: DVec3) -> [[f64; 4]; 3] {
    let row = |i: usize| -> [f64; 4] {
        let v: DVec4 = DVec4::new(r.col(0)[i], r.col(1)[i], r.col(2)[i], t[i]);
        v.to_array()
    };
    [row(0), row(1), row(2)]
}

/// Negate the second and third columns: OpenCV camera axes <-> OpenGL camera axes.
pub fn flip_yz_columns(m: [[f64; 4]; 3]) -> [[f64; 4]; 3] {
    let mut o = m;
    for row in o.iter_mut() {
        row[1] = -row[1];
        row[2] = -row[2];
    }
    o
}

fn check_rigid(r: DMat3) -> Result<(), String> {
    let rtr = r.transpose() * r;
    let err = (rtr - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |a, v| a.max(v.abs()));
    let det = r.determinant();
    if err > RIGID_TOL || (det - 1.0).abs() > RIGID_TOL {
        return Err(format!(
            "rotation is not rigid (|R^T R - I| = {err:.3e}, det R = {det:.6}): scaled or sheared poses are not supported"
        ));
    }
    Ok(())
}

/// The world's up direction from the cameras, with a sentence saying how it was found.
///
/// People hold cameras upright, so the mean of the cameras' up vectors (-y of the OpenCV camera)
/// is near up; but it leans by however much the cameras tilted, and a walk-around looking down
/// at an object tilts it toward the object on every side unevenly. People also walk around
/// at about one height: where the centres lie near a plane ([`RING_FLATNESS`]) whose normal is
/// within [`RING_MAX_TILT_DEG`] of the mean up (not a forward capture's plane of positions,
/// which faces the scene), that plane's normal is up. Up is snapped to a world axis within
/// [`SNAP_DEG`] of one (synthetic and Blender captures are axis-aligned), a ring's normal only
/// within [`RING_SNAP_DEG`] (it measures up well, and a COLMAP world's axes are arbitrary).
pub fn up_from_cameras<'a>(poses: impl IntoIterator<Item = &'a Pose>) -> (DVec3, String) {
    let mut sum = DVec3::ZERO;
    let mut centres = Vec::new();
    for pose in poses {
        sum -= pose.c2w_rotation().col(1);
        centres.push(pose.center());
    }
    if sum.length() < 1e-9 {
        return (DVec3::Z, "no camera agrees on up: assumed +Z".into());
    }
    let mean = sum.normalize();
    if let Some((normal, flatness)) = ring_normal(&centres, mean) {
        let tilt = normal.dot(mean).clamp(-1.0, 1.0).acos().to_degrees();
        let how = format!(
            "the normal of the plane the cameras moved round in (spread across it {:.0}% of the \
             least within it; {tilt:.1} deg from their mean up)",
            100.0 * flatness
        );
        return snap_to_axis(normal, RING_SNAP_DEG, &how);
    }
    snap_to_axis(mean, SNAP_DEG, "the cameras' mean up")
}

/// Centres this flat (the spread across their plane over the least spread within it) may be
/// one walk round at about one height: a hand-held walk-around rises and dips, and the phone
/// capture of a can measured here is 0.42.
pub const RING_FLATNESS: f64 = 0.5;
/// The most a ring's normal may lean from the cameras' mean up. Cameras looking down lean
/// their up vectors toward the object; over a walk round that does not go evenly all the way
/// the lean does not cancel (22 degrees on that can, looking down at 30).
pub const RING_MAX_TILT_DEG: f64 = 35.0;
/// Snapping tolerances: the mean up's, and a ring normal's (it measures up well, and a
/// COLMAP world's axes say nothing about up).
pub const SNAP_DEG: f64 = 15.0;
pub const RING_SNAP_DEG: f64 = 5.0;

/// The normal of the plane the centres lie in, facing like `mean_up`, and the flatness, where
/// they make a ring: at least 8 cameras, flat, and the normal near the mean up.
fn ring_normal(centres: &[DVec3], mean_up: DVec3) -> Option<(DVec3, f64)> {
    if centres.len() < 8 {
        return None;
    }
    let spread = Spread::of(centres)?;
    let flatness = spread.flatness()?;
    let normal = spread.normal() * spread.normal().dot(mean_up).signum();
    let tilt = normal.dot(mean_up).clamp(-1.0, 1.0).acos().to_degrees();
    (flatness <= RING_FLATNESS && tilt <= RING_MAX_TILT_DEG).then_some((normal, flatness))
}

/// `dir`, or the world axis nearest it when within `tolerance_deg`; with the sentence.
fn snap_to_axis(dir: DVec3, tolerance_deg: f64, how: &str) -> (DVec3, String) {
    let axes = [
        (DVec3::X, "+X"),
        (DVec3::NEG_X, "-X"),
        (DVec3::Y, "+Y"),
        (DVec3::NEG_Y, "-Y"),
        (DVec3::Z, "+Z"),
        (DVec3::NEG_Z, "-Z"),
    ];
    let (best, name) = axes
        .into_iter()
        .max_by(|a, b| a.0.dot(dir).total_cmp(&b.0.dot(dir)))
        .expect("six axes");
    let angle = best.dot(dir).clamp(-1.0, 1.0).acos().to_degrees();
    if angle <= tolerance_deg {
        (
            best,
            format!("{how} is {angle:.1} deg from world {name}: snapped to it"),
        )
    } else {
        (
            dir,
            format!(
                "{how} ({:.3}, {:.3}, {:.3}) is {angle:.1} deg from the nearest axis: used as is",
                dir.x, dir.y, dir.z
            ),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colmap_and_matrix_forms_agree() {
        let p = Pose::look_at(DVec3::new(3.0, -2.0, 1.5), DVec3::ZERO, DVec3::Z);
        let q = Pose::from_colmap(p.qvec(), p.tvec()).unwrap();
        let a = p.c2w_opencv();
        let b = q.c2w_opencv();
        for i in 0..3 {
            for j in 0..4 {
                assert!((a[i][j] - b[i][j]).abs() < 1e-12);
            }
        }
        // The target is straight ahead on the optical axis.
        let cam = p.world_to_camera(DVec3::ZERO);
        assert!(cam.x.abs() < 1e-12 && cam.y.abs() < 1e-12 && cam.z > 0.0);
    }

    #[test]
    fn opengl_round_trip_is_exact() {
        let p = Pose::look_at(
            DVec3::new(0.3, 4.0, 2.0),
            DVec3::new(0.1, 0.0, 0.2),
            DVec3::Z,
        );
        let gl = p.c2w_opengl();
        let back = Pose::from_c2w_opengl(gl).unwrap();
        assert_eq!(back.c2w_opengl(), gl);
    }

    /// Cameras at `height` above the plane through the origin normal to `up`, `count` of them
    /// over `arc_deg` of azimuth, all looking at the origin.
    fn walk_around(up: DVec3, height: f64, count: usize, arc_deg: f64) -> Vec<Pose> {
        let side = up.any_orthonormal_vector();
        let fwd = up.cross(side);
        (0..count)
            .map(|i| {
                let a = (arc_deg * i as f64 / count as f64).to_radians();
                let c = (side * a.cos() + fwd * a.sin()) * 2.0 + up * height;
                Pose::look_at(c, DVec3::ZERO, up)
            })
            .collect()
    }

    #[test]
    fn a_walk_around_looking_down_finds_up_from_its_ring() {
        // A COLMAP-like world: up 10 degrees off -Y. Half a walk round, looking down at about
        // 40 degrees: each camera's up leans toward the object, so their mean leans too.
        let up = DQuat::from_rotation_x(10f64.to_radians()) * DVec3::NEG_Y;
        let poses = walk_around(up, 1.7, 30, 180.0);
        let mean: DVec3 = poses
            .iter()
            .map(|p| -p.c2w_rotation().col(1))
            .sum::<DVec3>()
            .normalize();
        assert!(mean.angle_between(up).to_degrees() > 5.0);
        let (found, why) = up_from_cameras(&poses);
        assert!(found.angle_between(up).to_degrees() < 0.01, "{found} {why}");
        assert!(why.contains("plane"), "{why}");
    }

    #[test]
    fn an_axis_aligned_ring_snaps_and_a_forward_capture_keeps_the_mean_up() {
        let (found, why) = up_from_cameras(&walk_around(DVec3::Z, 1.0, 24, 360.0));
        assert_eq!(found, DVec3::Z, "{why}");
        // A forward capture: positions in a plane facing the scene (its normal is the view
        // direction, not up), every camera upright.
        let poses: Vec<Pose> = (0..20)
            .map(|i| {
                let c = DVec3::new((i % 5) as f64 * 0.1, 0.0, (i / 5) as f64 * 0.05);
                Pose::look_at(c, c + DVec3::Y * 5.0, DVec3::Z)
            })
            .collect();
        let (found, why) = up_from_cameras(&poses);
        assert_eq!(found, DVec3::Z, "{why}");
        assert!(why.contains("mean up"), "{why}");
    }

    #[test]
    fn rejects_non_rigid_and_nan() {
        let mut m = Pose::look_at(DVec3::new(1.0, 2.0, 3.0), DVec3::ZERO, DVec3::Z).c2w_opencv();
        m[0][0] *= 2.0;
        assert!(Pose::from_c2w_opencv(m).is_err());
        m[0][0] = f64::NAN;
        assert!(Pose::from_c2w_opencv(m).is_err());
        assert!(Pose::from_colmap([2.0, 0.0, 0.0, 0.0], [0.0; 3]).is_err());
    }
}
