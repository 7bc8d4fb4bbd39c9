//! A small z-buffer rasteriser for meshes seen by a capture's cameras, to score an exported mesh
//! against the photos: each pixel centre takes the colour of the nearest triangle, perspective-
//! correct, from its vertex colours or its texture, with no lighting (what an unlit material
//! shows). A texture is read as the exported glTF's sampler asks a viewer to (trilinear over
//! mipmaps: the level from the pixel's footprint in texels), so a texture finer than the pixels
//! it lands on is averaged over each pixel, as in Blender or a web viewer, not point-sampled.

use super::Mesh;
use crate::field::{RayCamera, View};
use glam::{Vec2, Vec3};

/// The mesh (in the camera's world frame) drawn into `cam`'s image: per pixel the colour in 0..1
/// (the photos' sRGB values), None where no triangle covers the pixel centre.
pub fn render_mesh(mesh: &Mesh, cam: &RayCamera) -> Vec<Option<[f32; 3]>> {
    let (_, hits, proj) = zbuffer(mesh, cam);
    let texture = match (&mesh.uvs, &mesh.texture) {
        (Some(uvs), Some(img)) => Some((uvs, Mips::new(img))),
        _ => None,
    };
    let w = cam.width as usize;
    hits.into_iter()
        .enumerate()
        .map(|(i, hit)| {
            let (t, wts) = hit?;
            let tri = &mesh.triangles[t as usize];
            Some(match &texture {
                Some((uvs, mips)) => {
                    let corners = tri.map(|v| proj[v as usize].expect("a drawn triangle"));
                    let q = Vec2::new((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                    let uv_of = |b: [f32; 3]| {
                        (0..3).fold(Vec2::ZERO, |acc, k| {
                            acc + Vec2::from(uvs[tri[k] as usize]) * b[k]
                        })
                    };
                    // The pixel's own weights come from the z-buffer; its neighbours' (for the
                    // footprint) from the same plane, extended.
                    let uv = uv_of(wts);
                    let du = uv_of(perspective_weights(&corners, q + Vec2::X)) - uv;
                    let dv = uv_of(perspective_weights(&corners, q + Vec2::Y)) - uv;
                    mips.sample(uv, du, dv)
                }
                None => shade(mesh, tri, wts),
            })
        })
        .collect()
}

/// Perspective-correct barycentric weights at screen point `q` of a triangle given by its
/// corners' screen positions and 1/depth (outside the triangle: the same plane, extended).
fn perspective_weights(c: &[(Vec2, f32); 3], q: Vec2) -> [f32; 3] {
    let area = (c[1].0 - c[0].0).perp_dot(c[2].0 - c[0].0);
    let l0 = (c[1].0 - q).perp_dot(c[2].0 - q) / area;
    let l1 = (c[2].0 - q).perp_dot(c[0].0 - q) / area;
    let l = [l0, l1, 1.0 - l0 - l1];
    let iz = l[0] * c[0].1 + l[1] * c[1].1 + l[2] * c[2].1;
    [0, 1, 2].map(|k| l[k] * c[k].1 / iz)
}

/// The mesh's depth (along the camera's axis, world units) at each pixel centre of `cam`'s image,
/// infinity where no triangle covers it.
pub fn depth_map(mesh: &Mesh, cam: &RayCamera) -> Vec<f32> {
    zbuffer(mesh, cam)
        .0
        .into_iter()
        .map(|iz| if iz > 0.0 { 1.0 / iz } else { f32::INFINITY })
        .collect()
}

/// Each vertex's screen position and 1/depth (None: behind the camera).
type Projected = Vec<Option<(Vec2, f32)>>;

/// One z-buffer pass: per pixel the nearest triangle's 1/depth (0: none) and that triangle with
/// its perspective-correct barycentric weights; and the vertices' projections.
#[allow(clippy::type_complexity)]
fn zbuffer(mesh: &Mesh, cam: &RayCamera) -> (Vec<f32>, Vec<Option<(u32, [f32; 3])>>, Projected) {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut inv_z = vec![0f32; w * h];
    let mut out = vec![None; w * h];
    let centre = cam.center();
    let forward = cam.pose.camera_to_world_dir(glam::DVec3::Z).as_vec3();
    let proj: Projected = mesh
        .positions
        .iter()
        .map(|p| {
            let p = Vec3::from(*p);
            let z = (p - centre).dot(forward);
            cam.project(p)
                .filter(|_| z > 1e-6)
                .map(|(x, y)| (Vec2::new(x, y), 1.0 / z))
        })
        .collect();
    for (ti, t) in mesh.triangles.iter().enumerate() {
        let Some([a, b, c]) = t
            .iter()
            .map(|&i| proj[i as usize])
            .collect::<Option<Vec<_>>>()
            .map(|v| [v[0], v[1], v[2]])
        else {
            continue;
        };
        let area = (b.0 - a.0).perp_dot(c.0 - a.0);
        if area.abs() < 1e-12 {
            continue;
        }
        let lo = a.0.min(b.0).min(c.0);
        let hi = a.0.max(b.0).max(c.0);
        let x0 = (lo.x - 0.5).ceil().max(0.0) as i64;
        let y0 = (lo.y - 0.5).ceil().max(0.0) as i64;
        let x1 = ((hi.x - 0.5).floor() as i64).min(w as i64 - 1);
        let y1 = ((hi.y - 0.5).floor() as i64).min(h as i64 - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let l0 = (b.0 - q).perp_dot(c.0 - q) / area;
                let l1 = (c.0 - q).perp_dot(a.0 - q) / area;
                let l2 = 1.0 - l0 - l1;
                if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
                    continue;
                }
                let iz = l0 * a.1 + l1 * b.1 + l2 * c.1;
                let i = x as usize + w * y as usize;
                if iz <= inv_z[i] {
                    continue;
                }
                inv_z[i] = iz;
                // Perspective-correct weights.
                let pw = [l0 * a.1 / iz, l1 * b.1 / iz, l2 * c.1 / iz];
                out[i] = Some((ti as u32, pw));
            }
        }
    }
    (inv_z, out, proj)
}

/// The colour at barycentric `w` of triangle `t` of a mesh without a texture: vertex colours,
/// else grey.
fn shade(mesh: &Mesh, t: &[u32; 3], w: [f32; 3]) -> [f32; 3] {
    if let Some(cols) = &mesh.colors {
        let mut c = [0f32; 3];
        for (&i, wi) in t.iter().zip(w) {
            (0..3).for_each(|k| c[k] += cols[i as usize][k] * wi);
        }
        return c;
    }
    [0.5; 3]
}

/// A texture and its mipmaps (each level the 2 x 2 mean of the one before, down to 1 x 1), 0..1.
struct Mips {
    levels: Vec<(usize, usize, Vec<[f32; 3]>)>,
}

impl Mips {
    fn new(img: &image::RgbImage) -> Mips {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let base: Vec<[f32; 3]> = img
            .pixels()
            .map(|p| p.0.map(|v| v as f32 / 255.0))
            .collect();
        let mut levels = vec![(w, h, base)];
        while let Some((w, h, px)) = levels.last().filter(|l| l.0 > 1 || l.1 > 1) {
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            let at = |x: usize, y: usize| px[x.min(w - 1) + w * y.min(h - 1)];
            let next = (0..nw * nh)
                .map(|i| {
                    let (x, y) = (2 * (i % nw), 2 * (i / nw));
                    let q = [at(x, y), at(x + 1, y), at(x, y + 1), at(x + 1, y + 1)];
                    [0, 1, 2].map(|k| 0.25 * (q[0][k] + q[1][k] + q[2][k] + q[3][k]))
                })
                .collect();
            levels.push((nw, nh, next));
        }
        Mips { levels }
    }

    /// Trilinear sample at `uv` (glTF convention) for a pixel whose neighbours to the right and
    /// below are `du`, `dv` away in uv (OpenGL's level of detail: log2 of the longer footprint).
    fn sample(&self, uv: Vec2, du: Vec2, dv: Vec2) -> [f32; 3] {
        let (w, h, _) = &self.levels[0];
        let size = Vec2::new(*w as f32, *h as f32);
        let rho = (du * size).length().max((dv * size).length());
        let lod = rho
            .max(1.0)
            .log2()
            .clamp(0.0, (self.levels.len() - 1) as f32);
        let (l0, f) = (lod.floor() as usize, lod.fract());
        let a = self.bilinear(l0, uv);
        if f == 0.0 || l0 + 1 >= self.levels.len() {
            return a;
        }
        let b = self.bilinear(l0 + 1, uv);
        [0, 1, 2].map(|k| a[k] * (1.0 - f) + b[k] * f)
    }

    /// Bilinear sample of one level at `uv`, clamped to the edge.
    fn bilinear(&self, level: usize, uv: Vec2) -> [f32; 3] {
        let (w, h, px) = &self.levels[level];
        let (w, h) = (*w, *h);
        let x = (uv.x * w as f32 - 0.5).clamp(0.0, (w - 1) as f32);
        let y = (uv.y * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let (a, b, c, d) = (
            px[x0 + w * y0],
            px[x1 + w * y0],
            px[x0 + w * y1],
            px[x1 + w * y1],
        );
        [0, 1, 2].map(|k| {
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
        })
    }
}

/// Samples a side of each pixel when a mesh is scored: a photo's pixel is the mean of what its
/// square sees (renderers and cameras antialias), so the mesh drawn for it is too, each sample
/// reading the texture at its own footprint.
pub const SCORE_SUBPIXELS: u32 = 4;

/// The mesh drawn over white into `cam`'s image, each pixel the mean of `k` x `k` samples
/// spread evenly over its square.
pub fn render_mesh_antialiased(mesh: &Mesh, cam: &RayCamera, k: u32) -> Vec<[f32; 3]> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let k = k.max(1) as usize;
    let fine_cam = cam.camera.resized((w * k) as u32, (h * k) as u32);
    let fine = render_mesh(mesh, &RayCamera::new(cam.name.clone(), fine_cam, cam.pose));
    let inv = 1.0 / (k * k) as f32;
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let mut c = [0f32; 3];
            for dy in 0..k {
                for dx in 0..k {
                    let s = fine[x * k + dx + w * k * (y * k + dy)].unwrap_or([1.0; 3]);
                    (0..3).for_each(|j| c[j] += s[j] * inv);
                }
            }
            c
        })
        .collect()
}

/// Squared error summed over the pixels inside `view`'s mask (fully opaque) and their count,
/// the mesh drawn over white (a hole costs what white against the photo costs), antialiased
/// ([`SCORE_SUBPIXELS`]).
pub fn masked_squared_error(mesh: &Mesh, view: &View) -> (f64, usize) {
    let img = render_mesh_antialiased(mesh, &view.cam, SCORE_SUBPIXELS);
    let mut se = 0f64;
    let mut n = 0usize;
    for (c, target) in img.iter().zip(&view.rgba) {
        if target[3] != 255 {
            continue;
        }
        for k in 0..3 {
            let d = c[k].clamp(0.0, 1.0) as f64 - target[k] as f64 / 255.0;
            se += d * d;
        }
        n += 1;
    }
    (se, n)
}

/// PSNR (dB) of the mesh inside the views' masks, over all their pixels together.
pub fn masked_psnr(mesh: &Mesh, views: &[View]) -> f64 {
    let (se, n) = views
        .iter()
        .map(|v| masked_squared_error(mesh, v))
        .fold((0.0, 0), |(s, n), (a, b)| (s + a, n + b));
    let mse = se / (3 * n.max(1)) as f64;
    -10.0 * mse.max(1e-12).log10()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Camera, Pose};
    use glam::DVec3;

    /// A 2 x 2 quad at z = 0 (two triangles), textured with `texture` or red vertex colours.
    fn quad(texture: Option<image::RgbImage>) -> Mesh {
        let textured = texture.is_some();
        Mesh {
            positions: vec![
                [-1.0, -1.0, 0.0],
                [1.0, -1.0, 0.0],
                [1.0, 1.0, 0.0],
                [-1.0, 1.0, 0.0],
            ],
            uvs: textured.then(|| vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
            texture: texture.map(std::sync::Arc::new),
            colors: (!textured).then(|| vec![[1.0, 0.0, 0.0]; 4]),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    /// A 64 x 64 camera (f = 64) at height `z` looking down at the quad.
    fn camera_above(z: f64) -> RayCamera {
        let cam = Camera::pinhole(64, 64, 64.0, 64.0, 32.0, 32.0);
        let pose = Pose::look_at(DVec3::new(0.0, 0.0, z), DVec3::ZERO, DVec3::Y);
        RayCamera::new("v".into(), cam, pose)
    }

    #[test]
    fn a_quad_in_front_fills_its_pixels_with_its_texture() {
        // The quad seen from z = 4 looking down: covers the middle of the image.
        let mesh = quad(Some(image::RgbImage::from_pixel(
            4,
            4,
            image::Rgb([255, 0, 0]),
        )));
        let rc = camera_above(4.0);
        let img = render_mesh(&mesh, &rc);
        // Half-width 1 at distance 4 with f = 64: 16 px either side of the centre.
        let covered = img.iter().filter(|p| p.is_some()).count();
        assert!((covered as i64 - 32 * 32).abs() < 70, "{covered}");
        assert_eq!(img[32 + 64 * 32], Some([1.0, 0.0, 0.0]));
        assert_eq!(img[2 + 64 * 2], None);
        let depth = depth_map(&mesh, &rc);
        assert!((depth[32 + 64 * 32] - 4.0).abs() < 1e-5);
        assert_eq!(depth[2 + 64 * 2], f32::INFINITY);
    }

    #[test]
    fn a_texture_finer_than_the_pixels_is_averaged_not_point_sampled() {
        // A 256 x 256 checker of single black and white texels on a quad 32 px wide: each pixel
        // covers 8 x 8 texels, so a viewer's trilinear sampling shows mid grey; one bilinear
        // tap at the pixel centre would show near black or white.
        let checker = image::RgbImage::from_fn(256, 256, |x, y| {
            image::Rgb([if (x + y) % 2 == 0 { 255 } else { 0 }; 3])
        });
        let mesh = quad(Some(checker));
        let img = render_mesh(&mesh, &camera_above(4.0));
        let drawn: Vec<[f32; 3]> = img.into_iter().flatten().collect();
        assert!(drawn.len() > 900, "{}", drawn.len());
        for c in drawn {
            assert!((c[0] - 0.5).abs() < 0.05, "{c:?}");
        }
    }

    #[test]
    fn an_antialiased_edge_pixel_mixes_the_mesh_with_white() {
        // A red quad seen from 4.5: its left edge at x = 32 - 64 / 4.5 = 17.78 px, so pixel 17
        // is a fifth covered (a quarter of its samples), pixel 20 wholly.
        let mesh = quad(None);
        let img = render_mesh_antialiased(&mesh, &camera_above(4.5), 4);
        assert_eq!(img[20 + 64 * 32], [1.0, 0.0, 0.0]);
        let edge = img[17 + 64 * 32];
        assert!(edge[0] == 1.0 && (edge[1] - 0.75).abs() < 1e-6, "{edge:?}");
        assert_eq!(img[10 + 64 * 32], [1.0; 3]);
    }
}
