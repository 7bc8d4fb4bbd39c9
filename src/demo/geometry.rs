//! The demo scene's geometry: four analytic objects on a floor inside a cylindrical backdrop,
//! world z-up, metres. Sphere, box, floor and backdrop are hit by closed-form intersection; the
//! mug and the torus by sphere tracing their signed distance functions, then bisecting the sign
//! change so that depth is exact to ~1e-9 m (the truth depth maps and tracks rely on it).

use crate::util::lattice::box_corners;
use glam::{DMat3, DVec3};

/// The standard scene's object names, in id order (id = index; variants add objects after them).
pub const OBJECT_NAMES: [&str; 4] = ["mug", "sphere", "box", "torus"];
/// Surface ids past the objects (objects take ids 0, 1, ... in their order).
pub const FLOOR: u8 = 250;
pub const BACKDROP: u8 = 251;
/// No surface (sky above the backdrop).
pub const NONE: u8 = 255;

/// The inner radius and height of the backdrop wall; the floor is the disc inside it.
pub const BACKDROP_RADIUS: f64 = 4.0;
pub const BACKDROP_HEIGHT: f64 = 3.5;

#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: DVec3,
    /// Unit length, so `t` is a distance in metres.
    pub d: DVec3,
}

impl Ray {
    pub fn at(&self, t: f64) -> DVec3 {
        self.o + self.d * t
    }
}

#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f64,
    pub id: u8,
    pub p: DVec3,
    /// Unit outward normal (for the backdrop: pointing into the scene).
    pub n: DVec3,
}

/// Where an object sits: world = scale * R * local + origin. The demo's objects rest on the floor
/// turned about the vertical ([`Placement::new`]); an edit moves, turns and scales them
/// ([`Placement::then`]).
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    origin: DVec3,
    /// Local -> world rotation.
    rot: DMat3,
    scale: f64,
}

impl Placement {
    pub fn new(origin: DVec3, yaw_deg: f64) -> Self {
        Placement {
            origin,
            rot: DMat3::from_rotation_z(yaw_deg.to_radians()),
            scale: 1.0,
        }
    }
    /// This placement followed by `x -> scale * rot * x + shift` (an edit's transform).
    pub fn then(&self, scale: f64, rot: DMat3, shift: DVec3) -> Self {
        Placement {
            origin: scale * (rot * self.origin) + shift,
            rot: rot * self.rot,
            scale: scale * self.scale,
        }
    }
    pub fn scale(&self) -> f64 {
        self.scale
    }
    pub fn dir_to_local(&self, d: DVec3) -> DVec3 {
        self.rot.transpose() * d
    }
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.dir_to_local(p - self.origin) / self.scale
    }
    pub fn dir_to_world(&self, d: DVec3) -> DVec3 {
        self.rot * d
    }
    pub fn to_world(&self, p: DVec3) -> DVec3 {
        self.scale * self.dir_to_world(p) + self.origin
    }
}

/// Shapes in their local frame, resting on z = 0 and centred on the z axis.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    /// A cup (outer radius, height, wall and base thickness) with a handle: a torus tube in the
    /// x-z plane centred on the outer wall at height `handle_z`, kept only outside the wall.
    Mug {
        radius: f64,
        height: f64,
        wall: f64,
        base: f64,
        handle_major: f64,
        handle_minor: f64,
        handle_z: f64,
    },
    Sphere {
        radius: f64,
    },
    Cuboid {
        half: DVec3,
    },
    /// Lying flat: axis z, centre at height `minor`.
    Torus {
        major: f64,
        minor: f64,
    },
}

#[derive(Clone, Debug)]
pub struct Object {
    pub name: &'static str,
    pub shape: Shape,
    pub place: Placement,
    /// Local axis-aligned bounds (exact for every shape).
    pub local_min: DVec3,
    pub local_max: DVec3,
    /// One plain colour instead of its texture (the textureless variant).
    pub plain: bool,
}

fn capped_cylinder(p: DVec3, r: f64, z0: f64, z1: f64) -> f64 {
    let dx = (p.x * p.x + p.y * p.y).sqrt() - r;
    let dz = (p.z - 0.5 * (z0 + z1)).abs() - 0.5 * (z1 - z0);
    dx.max(dz).min(0.0) + (dx.max(0.0).powi(2) + dz.max(0.0).powi(2)).sqrt()
}

impl Object {
    pub fn new(name: &'static str, shape: Shape, place: Placement) -> Self {
        let (local_min, local_max) = match shape {
            Shape::Mug {
                radius,
                height,
                handle_major,
                handle_minor,
                handle_z,
                ..
            } => (
                DVec3::new(-radius, -radius, 0.0),
                DVec3::new(
                    radius + handle_major + handle_minor,
                    radius,
                    height.max(handle_z + handle_major + handle_minor),
                ),
            ),
            Shape::Sphere { radius } => (
                DVec3::new(-radius, -radius, 0.0),
                DVec3::new(radius, radius, 2.0 * radius),
            ),
            Shape::Cuboid { half } => (
                DVec3::new(-half.x, -half.y, 0.0),
                DVec3::new(half.x, half.y, 2.0 * half.z),
            ),
            Shape::Torus { major, minor } => (
                DVec3::new(-major - minor, -major - minor, 0.0),
                DVec3::new(major + minor, major + minor, 2.0 * minor),
            ),
        };
        Object {
            name,
            shape,
            place,
            local_min,
            local_max,
            plain: false,
        }
    }

    /// Signed distance in the local frame (exact for sphere, box and torus; a lower bound with the
    /// right sign for the mug, which is what sphere tracing needs).
    pub fn sdf_local(&self, p: DVec3) -> f64 {
        match self.shape {
            Shape::Mug {
                radius,
                height,
                wall,
                base,
                handle_major,
                handle_minor,
                handle_z,
            } => {
                let outer = capped_cylinder(p, radius, 0.0, height);
                // The cavity reaches above the rim so that the cup is open.
                let cavity = capped_cylinder(p, radius - wall, base, height + 1.0);
                let cup = outer.max(-cavity);
                let q = DVec3::new(p.x - radius, p.y, p.z - handle_z);
                let ring = (q.x * q.x + q.z * q.z).sqrt() - handle_major;
                let tube = (ring * ring + q.y * q.y).sqrt() - handle_minor;
                // The handle exists only outside the outer wall.
                let outside = radius - (p.x * p.x + p.y * p.y).sqrt();
                cup.min(tube.max(outside))
            }
            Shape::Sphere { radius } => (p - DVec3::new(0.0, 0.0, radius)).length() - radius,
            Shape::Cuboid { half } => {
                let q = (p - DVec3::new(0.0, 0.0, half.z)).abs() - half;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
            Shape::Torus { major, minor } => {
                let ring = (p.x * p.x + p.y * p.y).sqrt() - major;
                (ring * ring + (p.z - minor).powi(2)).sqrt() - minor
            }
        }
    }

    /// Distance from a world point to the surface (|SDF|; exact near the surface).
    pub fn distance(&self, p: DVec3) -> f64 {
        self.place.scale() * self.sdf_local(self.place.to_local(p)).abs()
    }

    /// World axis-aligned bounds.
    pub fn world_bbox(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for c in box_corners(self.local_min, self.local_max) {
            let w = self.place.to_world(c);
            lo = lo.min(w);
            hi = hi.max(w);
        }
        (lo, hi)
    }

    fn sdf_normal(&self, p: DVec3) -> DVec3 {
        let h = 1e-6;
        let g = DVec3::new(
            self.sdf_local(p + DVec3::X * h) - self.sdf_local(p - DVec3::X * h),
            self.sdf_local(p + DVec3::Y * h) - self.sdf_local(p - DVec3::Y * h),
            self.sdf_local(p + DVec3::Z * h) - self.sdf_local(p - DVec3::Z * h),
        );
        g.normalize_or_zero()
    }

    /// Outward unit normal at a world point on (or near) the surface.
    pub fn normal(&self, p: DVec3) -> DVec3 {
        let l = self.place.to_local(p);
        self.place.dir_to_world(self.sdf_normal(l))
    }

    /// The nearest intersection with `t` in (0, t_max): (t, world normal).
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<(f64, DVec3)> {
        // In the local frame distances are divided by the placement's scale.
        let s = self.place.scale();
        let o = self.place.to_local(ray.o);
        let d = self.place.dir_to_local(ray.d);
        let t_max = t_max / s;
        let (t0, t1) = slab(o, d, self.local_min, self.local_max)?;
        let t1 = t1.min(t_max);
        if t1 <= t0.max(0.0) {
            return None;
        }
        let (t, n) = match self.shape {
            Shape::Sphere { radius } => {
                let oc = o - DVec3::new(0.0, 0.0, radius);
                let b = oc.dot(d);
                let c = oc.length_squared() - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                let t = if -b - s > 1e-9 { -b - s } else { -b + s };
                (t, (oc + d * t) / radius)
            }
            Shape::Cuboid { half } => {
                let lo = DVec3::new(-half.x, -half.y, 0.0);
                let hi = DVec3::new(half.x, half.y, 2.0 * half.z);
                let (ta, tb) = slab(o, d, lo, hi)?;
                let t = if ta > 1e-9 { ta } else { tb };
                let p = o + d * t;
                let q = (p - DVec3::new(0.0, 0.0, half.z)) / half;
                let a = q.abs();
                let n = if a.x >= a.y && a.x >= a.z {
                    DVec3::new(q.x.signum(), 0.0, 0.0)
                } else if a.y >= a.z {
                    DVec3::new(0.0, q.y.signum(), 0.0)
                } else {
                    DVec3::new(0.0, 0.0, q.z.signum())
                };
                (t, n)
            }
            Shape::Mug { .. } | Shape::Torus { .. } => {
                let t = sphere_trace(|p| self.sdf_local(p), o, d, t0.max(0.0), t1)?;
                (t, self.sdf_normal(o + d * t))
            }
        };
        if t > 1e-9 && t < t_max {
            Some((t * s, self.place.dir_to_world(n)))
        } else {
            None
        }
    }
}

/// Ray-box slab test: the parameter interval inside the box, if any.
fn slab(o: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    for a in 0..3 {
        if d[a].abs() < 1e-300 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (mut ta, mut tb) = ((lo[a] - o[a]) * inv, (hi[a] - o[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    (t0 <= t1 && t1 > 0.0).then_some((t0, t1))
}

/// First root of `sdf` along the ray in [t0, t1]. Sphere tracing brackets the surface, and
/// the Illinois variant of regula falsi then pins the sign change down to ~1e-12 m in a few
/// evaluations. A grazing ray that comes close without crossing keeps marching (a miss there).
fn sphere_trace(sdf: impl Fn(DVec3) -> f64, o: DVec3, d: DVec3, t0: f64, t1: f64) -> Option<f64> {
    let f = |t: f64| sdf(o + d * t);
    let mut t = t0;
    let mut prev = (t0, f64::INFINITY);
    for _ in 0..400 {
        if t > t1 {
            return None;
        }
        let s = f(t);
        if s <= 0.0 {
            return Some(refine(&f, prev, (t, s)));
        }
        if s < 1e-4 {
            // Close: look just past the surface for the sign change.
            let probe = t + 4.0 * s + 1e-6;
            let sp = f(probe);
            if sp <= 0.0 {
                return Some(refine(&f, (t, s), (probe, sp)));
            }
        }
        prev = (t, s);
        t += s.max(1e-7);
    }
    None
}

/// Root of `f` in a bracket (f(lo) > 0 >= f(hi)), by Illinois regula falsi.
fn refine(f: &impl Fn(f64) -> f64, lo: (f64, f64), hi: (f64, f64)) -> f64 {
    let ((mut a, mut fa), (mut b, mut fb)) = (lo, hi);
    if !fa.is_finite() {
        // No value before the first step (the ray started on the surface).
        return b;
    }
    let mut side = 0;
    for _ in 0..60 {
        if (b - a).abs() < 1e-12 || fb == 0.0 {
            break;
        }
        let c = (a * fb - b * fa) / (fb - fa);
        let fc = f(c);
        if fc > 0.0 {
            a = c;
            fa = fc;
            if side == 1 {
                fb *= 0.5;
            }
            side = 1;
        } else {
            b = c;
            fb = fc;
            if side == -1 {
                fa *= 0.5;
            }
            side = -1;
        }
    }
    // The last point at or just past the surface (never in front of it).
    b
}

/// The whole scene: objects, floor, backdrop, light.
#[derive(Clone, Debug)]
pub struct World {
    pub objects: Vec<Object>,
    /// Unit direction towards the light.
    pub light: DVec3,
    /// Objects left out of the render (indices into `objects`; ids and textures unchanged): the
    /// truth of a removal (the demo has no cast shadows, so nothing else changes).
    pub hidden: Vec<usize>,
    /// Whether the floor and the backdrop are there (an edit over a plain colour has neither).
    pub scenery: bool,
}

impl World {
    /// The demo layout. Seen from view 0 (camera on the -y side) every object is clear; from the
    /// -x side the box stands in front of the sphere and hides most of it.
    pub fn demo() -> World {
        let objects = vec![
            Object::new(
                "mug",
                Shape::Mug {
                    radius: 0.1,
                    height: 0.22,
                    wall: 0.014,
                    base: 0.02,
                    handle_major: 0.06,
                    handle_minor: 0.013,
                    handle_z: 0.115,
                },
                // Handle towards -x so that view 0 sees it side-on.
                Placement::new(DVec3::new(-0.42, 0.32, 0.0), 180.0),
            ),
            Object::new(
                "sphere",
                Shape::Sphere { radius: 0.14 },
                Placement::new(DVec3::new(0.42, 0.08, 0.0), 0.0),
            ),
            Object::new(
                "box",
                Shape::Cuboid {
                    half: DVec3::new(0.13, 0.11, 0.12),
                },
                Placement::new(DVec3::new(0.02, -0.02, 0.0), 25.0),
            ),
            Object::new(
                "torus",
                Shape::Torus {
                    major: 0.13,
                    minor: 0.045,
                },
                Placement::new(DVec3::new(-0.28, -0.45, 0.0), 0.0),
            ),
        ];
        World {
            objects,
            light: DVec3::new(0.45, -0.55, 0.75).normalize(),
            hidden: Vec::new(),
            scenery: true,
        }
    }

    pub fn object(&self, name: &str) -> Option<&Object> {
        self.objects.iter().find(|o| o.name == name)
    }

    /// The first surface along the ray. `only`: trace that object alone (no floor or backdrop),
    /// for unoccluded silhouettes.
    pub fn trace(&self, ray: &Ray, only: Option<usize>) -> Option<Hit> {
        let mut best: Option<(f64, u8, DVec3)> = None;
        let mut t_max = f64::INFINITY;
        for (i, obj) in self.objects.iter().enumerate() {
            if only.is_some_and(|k| k != i) || self.hidden.contains(&i) {
                continue;
            }
            if let Some((t, n)) = obj.intersect(ray, t_max) {
                t_max = t;
                best = Some((t, i as u8, n));
            }
        }
        if only.is_none() && self.scenery {
            // Floor: the disc z = 0 inside the backdrop.
            if ray.d.z < 0.0 {
                let t = -ray.o.z / ray.d.z;
                let p = ray.at(t);
                if t > 1e-9 && t < t_max && p.x * p.x + p.y * p.y < BACKDROP_RADIUS.powi(2) {
                    t_max = t;
                    best = Some((t, FLOOR, DVec3::Z));
                }
            }
            // Backdrop: the inside of a vertical cylinder (the camera is inside, so the far root).
            let a = ray.d.x * ray.d.x + ray.d.y * ray.d.y;
            if a > 1e-300 {
                let b = ray.o.x * ray.d.x + ray.o.y * ray.d.y;
                let c = ray.o.x * ray.o.x + ray.o.y * ray.o.y - BACKDROP_RADIUS.powi(2);
                let disc = b * b - a * c;
                if disc >= 0.0 {
                    let t = (-b + disc.sqrt()) / a;
                    let p = ray.at(t);
                    if t > 1e-9 && t < t_max && (0.0..=BACKDROP_HEIGHT).contains(&p.z) {
                        best = Some((t, BACKDROP, -DVec3::new(p.x, p.y, 0.0) / BACKDROP_RADIUS));
                    }
                }
            }
        }
        best.map(|(t, id, n)| Hit {
            t,
            id,
            p: ray.at(t),
            n,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn traced_hits_lie_on_the_surface() {
        let w = World::demo();
        for obj in &w.objects {
            // A point inside the solid: any ray from outside towards it crosses the surface.
            let inside = match obj.shape {
                Shape::Mug { .. } => DVec3::new(0.0, 0.0, 0.01),
                Shape::Sphere { radius } => DVec3::new(0.0, 0.0, radius),
                Shape::Cuboid { half } => DVec3::new(0.0, 0.0, half.z),
                Shape::Torus { major, minor } => DVec3::new(major, 0.0, minor),
            };
            let c = obj.place.to_world(inside);
            for k in 0..64 {
                let a = k as f64 * 0.37;
                let eye = c + DVec3::new(2.0 * a.cos(), 2.0 * a.sin(), 0.3 + 0.02 * k as f64);
                let target = c + DVec3::new(0.002 * (k % 5) as f64, -0.001 * (k % 7) as f64, 0.0);
                let ray = Ray {
                    o: eye,
                    d: (target - eye).normalize(),
                };
                let (t, n) = obj
                    .intersect(&ray, f64::INFINITY)
                    .expect("aimed at the object");
                let p = ray.at(t);
                assert!(obj.distance(p) < 1e-7, "{}: {}", obj.name, obj.distance(p));
                assert!(n.dot(ray.d) < 0.0, "{}: normal faces the ray", obj.name);
            }
        }
    }

    #[test]
    fn placement_round_trips() {
        let pl = Placement::new(DVec3::new(0.3, -0.2, 0.0), 37.0);
        let p = DVec3::new(0.1, 0.7, 0.4);
        assert!((pl.to_world(pl.to_local(p)) - p).length() < 1e-15);
    }
}
