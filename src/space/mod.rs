//! Where a field's grid lives. The grid is a box of cubic voxels in *space coordinates*; a
//! [`Space`] maps world points there and turns a world ray into the path its samples follow:
//!
//! - [`Space::Box`]: space = world. An object, or a scene every camera looks into (a turntable,
//!   the demo scene).
//! - [`Space::Unbounded`]: Mip-NeRF 360's contraction, as DVGO v2 uses it: x = (p - center) /
//!   radius is kept where |x| <= 1 and becomes (2 - 1/|x|) x/|x| beyond, so all of space fits in
//!   the ball of radius 2 and the grid spends half its width on the inner region (cameras inside
//!   or around a large scene: a room, a Mip-NeRF 360 capture). Samples are spaced evenly in
//!   contracted space, so a far wall costs no more samples than the centre.
//! - [`Space::Ndc`]: normalised device coordinates of a reference camera (forward-facing
//!   captures, as NeRF and DVGO do for LLFF): x/z and y/z scaled to the image, and disparity
//!   1 - 2 near / z, so the depth axis is sampled evenly in disparity out to infinity. Rays stay
//!   straight in NDC. The depth axis is scaled by `z_scale` (< 1) so that cubic grid voxels give
//!   it fewer cells than the image axes.
//!
//! Densities are per unit of space length (in finest voxels), so a sample's alpha depends only on
//! the step in space coordinates; `t`, the distance along the world ray, is kept for depth.

pub mod layout;

pub use layout::SpaceChoice;

use glam::{Mat3, Vec3};
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Space {
    /// World coordinates.
    #[default]
    Box,
    /// Contraction about `center` with the inner ball's `radius` (world units).
    Unbounded { center: [f32; 3], radius: f32 },
    /// NDC of a reference camera.
    Ndc(NdcSpace),
}

/// A reference camera for NDC: world to its OpenCV frame (x right, y down, z forward), the scale
/// of x/z and y/z (2 f / size), the near plane and the depth axis' scale.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NdcSpace {
    /// World-to-camera rotation, rows.
    pub rotation: [[f32; 3]; 3],
    /// The reference camera's centre, world.
    pub center: [f32; 3],
    /// 2 fx / width and 2 fy / height of the reference camera.
    pub scale_xy: [f32; 2],
    /// Depth (camera z) of the near plane: NDC z = -1 there, +1 at infinity.
    pub near: f32,
    /// NDC z is multiplied by this in space coordinates.
    pub z_scale: f32,
}

/// Rays are marched out to this contracted radius (|x| = 1 / (2 - R)): past it, all is at
/// infinity.
const MAX_CONTRACTED: f32 = 1.99;
/// Most samples on one ray in contracted space (a ray grazing the inner ball's edge).
const MAX_CONTRACTED_SAMPLES: usize = 8192;

/// Intersect a ray with an axis-aligned box: (t_near, t_far) with t_near >= 0, if it hits.
#[inline]
pub fn ray_box(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
    let inv = d.recip();
    let t0 = (lo - o) * inv;
    let t1 = (hi - o) * inv;
    let tmin = t0.min(t1);
    let tmax = t0.max(t1);
    // NaN (0 * inf, a ray in a box face's plane) must not decide the interval: max/min of glam
    // ignore NaNs only partly, so fall back to "no constraint" for such axes.
    let pick = |a: f32, fallback: f32| if a.is_nan() { fallback } else { a };
    let tn = pick(tmin.x, f32::MIN)
        .max(pick(tmin.y, f32::MIN))
        .max(pick(tmin.z, f32::MIN))
        .max(0.0);
    let tf = pick(tmax.x, f32::MAX)
        .min(pick(tmax.y, f32::MAX))
        .min(pick(tmax.z, f32::MAX));
    (tf > tn).then_some((tn, tf))
}

/// How a ray's samples are placed in space coordinates.
#[derive(Clone, Copy, Debug)]
pub enum RayPath {
    /// A straight segment `o + d s`, s in [s0, s1) (d unit in space coordinates); `t` maps s to
    /// the distance along the world ray.
    Line {
        o: Vec3,
        d: Vec3,
        s0: f32,
        s1: f32,
        t: LineDepth,
    },
    /// The world ray `o + d t` from `t0`, through the contraction about `center` / `radius`.
    Contracted {
        o: Vec3,
        d: Vec3,
        t0: f32,
        center: Vec3,
        radius: f32,
    },
}

/// From the parameter of a straight path in space to the world distance along the ray.
#[derive(Clone, Copy, Debug)]
pub enum LineDepth {
    /// Space is the world: s is t.
    Same,
    /// NDC: the space z at s gives camera depth 2 near / (1 - z / z_scale), and depth is linear
    /// in t: t = (depth - depth0) / depth_rate.
    Ndc {
        z0: f32,
        dz: f32,
        near: f32,
        z_scale: f32,
        depth0: f32,
        depth_rate: f32,
    },
}

impl LineDepth {
    #[inline]
    pub fn world_t(&self, s: f32) -> f32 {
        match *self {
            LineDepth::Same => s,
            LineDepth::Ndc {
                z0,
                dz,
                near,
                z_scale,
                depth0,
                depth_rate,
            } => {
                let zn = (z0 + dz * s) / z_scale;
                let depth = 2.0 * near / (1.0 - zn).max(1e-6);
                (depth - depth0) / depth_rate
            }
        }
    }
}

/// Mip-NeRF 360's contraction of a point in units of the inner radius.
#[inline]
pub fn contract(x: Vec3) -> Vec3 {
    let r = x.length();
    if r <= 1.0 {
        x
    } else {
        x * ((2.0 - 1.0 / r) / r)
    }
}

impl NdcSpace {
    fn rot(&self) -> Mat3 {
        Mat3::from_cols_array_2d(&self.rotation).transpose()
    }

    /// A world point in the reference camera's frame.
    #[inline]
    fn camera(&self, p: Vec3) -> Vec3 {
        self.rot() * (p - Vec3::from_array(self.center))
    }

    /// NDC (space coordinates) of a point in the camera frame with z > 0.
    #[inline]
    fn ndc(&self, q: Vec3) -> Vec3 {
        Vec3::new(
            self.scale_xy[0] * q.x / q.z,
            self.scale_xy[1] * q.y / q.z,
            self.z_scale * (1.0 - 2.0 * self.near / q.z),
        )
    }
}

impl Space {
    /// A world point in space coordinates (NDC of a point behind the near plane: `None`).
    #[inline]
    pub fn map(&self, p: Vec3) -> Option<Vec3> {
        match self {
            Space::Box => Some(p),
            Space::Unbounded { center, radius } => {
                Some(contract((p - Vec3::from_array(*center)) / *radius))
            }
            Space::Ndc(n) => {
                let q = n.camera(p);
                (q.z >= n.near).then(|| n.ndc(q))
            }
        }
    }

    /// The world point at space coordinates `q` (the inverse of [`Space::map`]); `None` for a
    /// contracted point at infinity or an NDC point at or past z = +1.
    pub fn unmap(&self, q: Vec3) -> Option<Vec3> {
        match self {
            Space::Box => Some(q),
            Space::Unbounded { center, radius } => {
                let r = q.length();
                let x = if r <= 1.0 {
                    q
                } else if r < 2.0 {
                    q / r / (2.0 - r)
                } else {
                    return None;
                };
                Some(Vec3::from_array(*center) + x * *radius)
            }
            Space::Ndc(n) => {
                let w = 1.0 - q.z / n.z_scale;
                if w <= 1e-6 {
                    return None;
                }
                let z = 2.0 * n.near / w;
                let c = Vec3::new(q.x * z / n.scale_xy[0], q.y * z / n.scale_xy[1], z);
                Some(n.rot().transpose() * c + Vec3::from_array(n.center))
            }
        }
    }

    /// The path of the world ray `o + d t` (d unit) through the space box `lo..hi`, or `None`
    /// when it misses.
    pub fn ray_path(&self, o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> Option<RayPath> {
        match self {
            Space::Box => {
                let (s0, s1) = ray_box(o, d, lo, hi)?;
                Some(RayPath::Line {
                    o,
                    d,
                    s0,
                    s1,
                    t: LineDepth::Same,
                })
            }
            Space::Unbounded { center, radius } => Some(RayPath::Contracted {
                o,
                d,
                t0: 0.0,
                center: Vec3::from_array(*center),
                radius: *radius,
            }),
            Space::Ndc(n) => {
                let (q0, dq) = (n.camera(o), n.rot() * d);
                if dq.z <= 1e-6 {
                    return None;
                }
                let t_start = ((n.near - q0.z) / dq.z).max(0.0);
                let start = n.ndc(q0 + dq * t_start);
                let at_infinity = Vec3::new(
                    n.scale_xy[0] * dq.x / dq.z,
                    n.scale_xy[1] * dq.y / dq.z,
                    n.z_scale,
                );
                let span = at_infinity - start;
                let len = span.length();
                if len <= 1e-9 {
                    return None;
                }
                let dir = span / len;
                let (b0, b1) = ray_box(start, dir, lo, hi)?;
                let (s0, s1) = (b0.max(0.0), b1.min(len));
                (s1 > s0).then_some(RayPath::Line {
                    o: start,
                    d: dir,
                    s0,
                    s1,
                    t: LineDepth::Ndc {
                        z0: start.z,
                        dz: dir.z,
                        near: n.near,
                        z_scale: n.z_scale,
                        depth0: q0.z,
                        depth_rate: dq.z,
                    },
                })
            }
        }
    }

    /// Space length per world length along the ray `o + d t` (d unit) at `t`: how far a depth
    /// error of one world unit there moves a surface in the grid. 1 in a box; in NDC and the
    /// contraction it falls with distance, so that a depth error is weighed by the voxels it
    /// spans, not by world units (a stereo target 1% off at 30 m is a fraction of a voxel).
    pub fn space_per_world(&self, o: Vec3, d: Vec3, t: f32) -> f32 {
        match self {
            Space::Box => 1.0,
            Space::Unbounded { center, radius } => {
                let x = (o + d * t - Vec3::from_array(*center)) / *radius;
                let n = x.length();
                if n <= 1.0 {
                    return 1.0 / radius;
                }
                let xh = x / n;
                let along = xh * xh.dot(d);
                ((d - along) * ((2.0 - 1.0 / n) / n) + along / (n * n)).length() / radius
            }
            Space::Ndc(ndc) => {
                let (q, dq) = (ndc.camera(o + d * t), ndc.rot() * d);
                if q.z <= 1e-6 {
                    return 0.0;
                }
                let z2 = q.z * q.z;
                Vec3::new(
                    ndc.scale_xy[0] * (dq.x * q.z - q.x * dq.z) / z2,
                    ndc.scale_xy[1] * (dq.y * q.z - q.y * dq.z) / z2,
                    ndc.z_scale * 2.0 * ndc.near * dq.z / z2,
                )
                .length()
            }
        }
    }

    /// Whether the ray `o + d t` meets the space box at all (rays that miss carry no loss).
    pub fn ray_hits(&self, o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> bool {
        self.ray_path(o, d, lo, hi).is_some()
    }

    pub fn name(&self) -> &'static str {
        match self {
            Space::Box => "box",
            Space::Unbounded { .. } => "unbounded",
            Space::Ndc(_) => "forward",
        }
    }
}

/// The world distances of a contracted path's samples, `step` apart in contracted space (in
/// units of the inner radius), from `t0 + jitter * first step`; ends where the contraction
/// reaches [`MAX_CONTRACTED`]. Each sample comes with its contracted position.
pub struct ContractedSteps {
    o: Vec3,
    d: Vec3,
    center: Vec3,
    radius: f32,
    step: f32,
    t: f32,
    count: usize,
    max_r: f32,
}

impl ContractedSteps {
    pub fn new(
        o: Vec3,
        d: Vec3,
        t0: f32,
        center: Vec3,
        radius: f32,
        step: f32,
        jitter: f32,
    ) -> Self {
        let mut s = ContractedSteps {
            o,
            d,
            center,
            radius,
            step,
            t: t0,
            count: 0,
            max_r: 1.0 / (2.0 - MAX_CONTRACTED),
        };
        s.t += jitter * s.world_step(s.unit(t0));
        s
    }

    /// Position in units of the inner radius at world distance `t`.
    #[inline]
    fn unit(&self, t: f32) -> Vec3 {
        (self.o + self.d * t - self.center) / self.radius
    }

    /// The world step that moves `step` in contracted space from `x` along a radial ray: outside
    /// the inner ball the contracted radius is u = 2 - 1/r, so u + step is at r' = 1/(2 - u -
    /// step). (Tangential rays move a little less in contracted space.)
    #[inline]
    fn world_step(&self, x: Vec3) -> f32 {
        let r = x.length();
        if r <= 1.0 {
            return self.step * self.radius;
        }
        let u = 2.0 - 1.0 / r + self.step;
        if u >= 2.0 {
            return f32::INFINITY;
        }
        (1.0 / (2.0 - u) - r) * self.radius
    }
}

impl Iterator for ContractedSteps {
    /// (world distance t, contracted position)
    type Item = (f32, Vec3);

    #[inline]
    fn next(&mut self) -> Option<(f32, Vec3)> {
        let x = self.unit(self.t);
        if self.count >= MAX_CONTRACTED_SAMPLES || x.length() > self.max_r {
            return None;
        }
        self.count += 1;
        let t = self.t;
        self.t += self.world_step(x);
        Some((t, contract(x)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contraction_keeps_the_inner_ball_and_squeezes_the_rest() {
        let x = Vec3::new(0.3, -0.2, 0.1);
        assert_eq!(contract(x), x);
        assert!((contract(Vec3::new(2.0, 0.0, 0.0)) - Vec3::new(1.5, 0.0, 0.0)).length() < 1e-6);
        assert!(contract(Vec3::new(1e6, 0.0, 0.0)).x < 2.0);
    }

    #[test]
    fn contracted_samples_are_evenly_spaced_in_contracted_space() {
        let steps = ContractedSteps::new(Vec3::ZERO, Vec3::X, 0.0, Vec3::ZERO, 2.0, 0.01, 0.0);
        let pts: Vec<(f32, Vec3)> = steps.collect();
        assert!(pts.len() > 150 && pts.len() < 220, "{} samples", pts.len());
        for w in pts.windows(2).skip(10) {
            let gap = (w[1].1 - w[0].1).length();
            assert!(gap < 0.0105 && gap > 0.009, "gap {gap}");
        }
        assert!(pts.last().unwrap().0 > 100.0);
    }

    #[test]
    fn space_per_world_is_the_rate_at_which_the_map_moves_along_a_ray() {
        let ndc = Space::Ndc(NdcSpace {
            rotation: Mat3::from_rotation_y(0.1).to_cols_array_2d(),
            center: [0.2, -0.1, 0.0],
            scale_xy: [2.0, 1.5],
            near: 1.0,
            z_scale: 0.5,
        });
        let unbounded = Space::Unbounded {
            center: [0.1, 0.0, -0.2],
            radius: 2.0,
        };
        let (o, d) = (
            Vec3::new(0.3, 0.1, -0.5),
            Vec3::new(0.2, -0.1, 1.0).normalize(),
        );
        for space in [Space::Box, ndc, unbounded] {
            for t in [2.5f32, 4.0, 20.0] {
                let h = 1e-3 * t;
                let a = space.map(o + d * (t - h)).unwrap();
                let b = space.map(o + d * (t + h)).unwrap();
                let numeric = (b - a).length() / (2.0 * h);
                let exact = space.space_per_world(o, d, t);
                assert!(
                    (exact - numeric).abs() <= 2e-3 * numeric,
                    "{} at t {t}: {exact} against {numeric}",
                    space.name()
                );
            }
        }
    }

    #[test]
    fn ndc_rays_are_straight_and_give_back_world_depth() {
        let n = NdcSpace {
            rotation: Mat3::IDENTITY.to_cols_array_2d(),
            center: [0.0; 3],
            scale_xy: [2.0, 1.5],
            near: 1.0,
            z_scale: 0.5,
        };
        let space = Space::Ndc(n.clone());
        let o = Vec3::new(0.1, -0.05, 0.0);
        let d = Vec3::new(0.2, 0.1, 1.0).normalize();
        let lo = Vec3::splat(-4.0);
        let hi = Vec3::splat(4.0);
        let Some(RayPath::Line {
            o: so,
            d: sd,
            s0,
            s1,
            t,
        }) = space.ray_path(o, d, lo, hi)
        else {
            panic!("the ray is in front of the camera");
        };
        for k in 1..10 {
            let s = s0 + (s1 - s0) * k as f32 / 10.0;
            let tw = t.world_t(s);
            let world = o + d * tw;
            let mapped = space.map(world).unwrap();
            assert!(
                (mapped - (so + sd * s)).length() < 1e-4,
                "{mapped} vs {}",
                so + sd * s
            );
        }
    }

    #[test]
    fn unmap_inverts_map_in_every_space() {
        let ndc = Space::Ndc(NdcSpace {
            rotation: [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
            center: [0.1, -2.0, 0.5],
            scale_xy: [2.1, 2.8],
            near: 0.7,
            z_scale: 1.5,
        });
        let spaces = [
            Space::Box,
            Space::Unbounded {
                center: [0.2, -0.1, 0.3],
                radius: 1.7,
            },
            ndc,
        ];
        for sp in spaces {
            for p in [
                Vec3::new(0.3, 1.0, 0.2),
                Vec3::new(-2.0, 4.0, 1.5),
                Vec3::new(5.0, 9.0, -3.0),
            ] {
                let q = sp.map(p).unwrap();
                let back = sp.unmap(q).unwrap();
                assert!(
                    (back - p).length() < 1e-3 * (1.0 + p.length()),
                    "{sp:?}: {p} -> {q} -> {back}"
                );
            }
        }
    }
}
