//! Procedural textures, evaluated in each object's local frame (world frame for the floor and the
//! backdrop): multi-octave value noise, stripes and checks in a distinct palette per surface. The
//! aim is many well-spread corners and blobs at a few pixels' scale, so that SIFT finds and
//! matches features on every surface and the real COLMAP can register all views.

use super::geometry::{Hit, Shape, World, BACKDROP, BACKDROP_RADIUS, FLOOR};
use crate::util::Rng;
use glam::DVec3;
use std::f64::consts::PI;

/// Lattice size of the noise (a power of two): the pattern repeats every this many lattice
/// cells, far more than any surface spans at the frequencies used.
const LATTICE: usize = 1024;

/// Texture noise keyed by the demo seed (a different seed gives different images). Lattice
/// values are hashed with Perlin's permutation table: three table loads per lattice point, the
/// cheapest hash for the renderer's hottest path.
#[derive(Clone, Debug)]
pub struct Textures {
    perm: Vec<u16>,
    values: Vec<f64>,
}

/// floor() as an integer without a libm call (the default x86-64 target has no SSE4.1 round);
/// noise lattice lookups are the renderer's hottest path.
fn floor_i(x: f64) -> i64 {
    let i = x as i64;
    i - (x < i as f64) as i64
}

fn smooth(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

fn lerp3(a: DVec3, b: DVec3, t: f64) -> DVec3 {
    a + (b - a) * t.clamp(0.0, 1.0)
}

impl Textures {
    pub fn new(seed: u64) -> Self {
        let mut rng = Rng::fork(seed, 0x7E47);
        let mut perm: Vec<u16> = (0..LATTICE as u16).collect();
        rng.shuffle(&mut perm);
        let values = (0..LATTICE).map(|_| rng.f64()).collect();
        Textures { perm, values }
    }

    fn lattice(&self, salt: u64, x: i64, y: i64, z: i64) -> f64 {
        let m = LATTICE - 1;
        // Salts shift the lattice far apart, so each use of the noise looks unrelated.
        let x = (x as usize).wrapping_add(salt as usize * 317);
        let h = self.perm[x & m] as usize;
        let h = self.perm[h.wrapping_add(y as usize) & m] as usize;
        let h = self.perm[h.wrapping_add(z as usize) & m] as usize;
        self.values[h]
    }

    /// Value noise in [0, 1), smooth, with unit lattice spacing.
    pub fn noise(&self, salt: u64, p: DVec3) -> f64 {
        let (ix, iy, iz) = (floor_i(p.x), floor_i(p.y), floor_i(p.z));
        let (tx, ty, tz) = (
            smooth(p.x - ix as f64),
            smooth(p.y - iy as f64),
            smooth(p.z - iz as f64),
        );
        let v = |dx, dy, dz| self.lattice(salt, ix + dx, iy + dy, iz + dz);
        let c = [
            v(0, 0, 0),
            v(1, 0, 0),
            v(0, 1, 0),
            v(1, 1, 0),
            v(0, 0, 1),
            v(1, 0, 1),
            v(0, 1, 1),
            v(1, 1, 1),
        ];
        let x00 = c[0] + (c[1] - c[0]) * tx;
        let x10 = c[2] + (c[3] - c[2]) * tx;
        let x01 = c[4] + (c[5] - c[4]) * tx;
        let x11 = c[6] + (c[7] - c[6]) * tx;
        let y0 = x00 + (x10 - x00) * ty;
        let y1 = x01 + (x11 - x01) * ty;
        y0 + (y1 - y0) * tz
    }

    /// Fractal sum of `octaves` octaves, normalised to [0, 1).
    pub fn fbm(&self, salt: u64, p: DVec3, octaves: u32) -> f64 {
        let (mut sum, mut amp, mut norm, mut q) = (0.0, 1.0, 0.0, p);
        for k in 0..octaves {
            sum += amp * self.noise(salt + k as u64, q);
            norm += amp;
            amp *= 0.55;
            q *= 2.03;
        }
        sum / norm
    }

    /// Contrast stretch of noise around 0.5, so textures have strong local extrema.
    fn contrast(&self, v: f64, k: f64) -> f64 {
        (0.5 + (v - 0.5) * k).clamp(0.0, 1.0)
    }

    /// The surface colour (albedo, 0-1) at a hit.
    pub fn albedo(&self, world: &World, hit: &Hit) -> DVec3 {
        match hit.id {
            FLOOR => self.floor(hit.p),
            BACKDROP => self.backdrop(hit.p),
            id => {
                let obj = &world.objects[id as usize];
                let p = obj.place.to_local(hit.p);
                match obj.shape {
                    _ if obj.plain => DVec3::new(0.86, 0.52, 0.42),
                    Shape::Mug { .. } => self.mug(p),
                    Shape::Sphere { radius } => self.sphere(p, radius),
                    Shape::Cuboid { .. } => self.cuboid(p),
                    Shape::Torus { .. } => self.torus(p),
                }
            }
        }
    }

    fn detail(&self, salt: u64, p: DVec3, freq: f64) -> f64 {
        0.55 + 0.9 * self.contrast(self.fbm(salt, p * freq, 3), 2.2)
    }

    fn mug(&self, p: DVec3) -> DVec3 {
        let red = DVec3::new(0.78, 0.14, 0.1);
        let cream = DVec3::new(0.96, 0.9, 0.74);
        let warp = 2.5 * self.fbm(11, p * 9.0, 2);
        let band = (2.0 * PI * p.z / 0.04 + warp).sin();
        let c = lerp3(red, cream, 0.5 + 2.0 * band);
        c * self.detail(12, p, 30.0)
    }

    fn sphere(&self, p: DVec3, radius: f64) -> DVec3 {
        let q = p - DVec3::new(0.0, 0.0, radius);
        let lon = q.y.atan2(q.x);
        let lat = (q.z / radius).clamp(-1.0, 1.0).asin();
        let warp = 0.6 * self.fbm(21, p * 8.0, 2);
        let check = ((lon / (PI / 8.0) + warp).floor() + (lat / (PI / 8.0) + warp).floor()) as i64;
        let c = if check.rem_euclid(2) == 0 {
            DVec3::new(0.12, 0.28, 0.85)
        } else {
            DVec3::new(0.95, 0.82, 0.18)
        };
        c * self.detail(22, p, 28.0)
    }

    fn cuboid(&self, p: DVec3) -> DVec3 {
        let warp = 0.5 * self.fbm(31, p * 10.0, 2);
        let s = 0.055;
        let check =
            ((p.x / s + warp).floor() + (p.y / s + warp).floor() + (p.z / s + warp).floor()) as i64;
        let c = if check.rem_euclid(2) == 0 {
            DVec3::new(0.16, 0.62, 0.22)
        } else {
            DVec3::new(0.96, 0.52, 0.12)
        };
        c * self.detail(32, p, 30.0)
    }

    fn torus(&self, p: DVec3) -> DVec3 {
        let a = p.y.atan2(p.x);
        let warp = 1.5 * self.fbm(41, p * 10.0, 2);
        let band = (11.0 * a + warp).sin();
        let c = lerp3(
            DVec3::new(0.52, 0.16, 0.62),
            DVec3::new(0.12, 0.78, 0.82),
            0.5 + 2.0 * band,
        );
        c * self.detail(42, p, 30.0)
    }

    fn floor(&self, p: DVec3) -> DVec3 {
        let s = 0.3;
        let (u, v) = (p.x / s, p.y / s);
        let tile = (u.floor() + v.floor()) as i64;
        let base = if tile.rem_euclid(2) == 0 {
            DVec3::new(0.78, 0.72, 0.6)
        } else {
            DVec3::new(0.5, 0.44, 0.38)
        };
        let grout = (u - u.round()).abs().min((v - v.round()).abs()) < 0.03;
        let g = if grout { 0.45 } else { 1.0 };
        // Blotches at tile scale, speckle at a few pixels.
        let tint = lerp3(
            DVec3::new(1.0, 0.85, 0.75),
            DVec3::new(0.75, 0.9, 1.0),
            self.fbm(51, p * 2.0, 2),
        );
        base * tint * g * self.detail(52, p, 14.0)
    }

    fn backdrop(&self, p: DVec3) -> DVec3 {
        // Unrolled wall coordinates, so the texture does not stretch with the angle.
        let a = p.y.atan2(p.x);
        let q = DVec3::new(a * BACKDROP_RADIUS, p.z, 0.0);
        let palette = [
            DVec3::new(0.85, 0.3, 0.25),
            DVec3::new(0.25, 0.6, 0.3),
            DVec3::new(0.25, 0.35, 0.8),
            DVec3::new(0.9, 0.75, 0.3),
            DVec3::new(0.6, 0.3, 0.7),
        ];
        let h = self.fbm(61, q * 0.9, 2) * palette.len() as f64 * 1.6;
        let i = (h as usize) % palette.len();
        let j = (i + 1) % palette.len();
        let c = lerp3(palette[i], palette[j], smooth(h.fract()));
        let blobs = self.contrast(self.fbm(62, q * 4.0, 3), 2.6);
        c * (0.35 + 0.95 * blobs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_seeded_and_bounded() {
        let a = Textures::new(1);
        let b = Textures::new(2);
        let mut differ = false;
        for k in 0..200 {
            let p = DVec3::new(k as f64 * 0.173, k as f64 * -0.31, 0.5 + k as f64 * 0.07);
            let v = a.fbm(3, p, 4);
            assert!((0.0..1.0).contains(&v));
            assert_eq!(v, a.fbm(3, p, 4));
            differ |= v != b.fbm(3, p, 4);
        }
        assert!(differ);
    }
}
