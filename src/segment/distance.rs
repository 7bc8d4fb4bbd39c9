//! Exact Euclidean distance transforms of masks (Felzenszwalb & Huttenlocher's lower envelope of
//! parabolas), used to keep prompts and votes away from mask edges and to find a mask's most
//! interior point.

use crate::util::lattice::squared_distance_1d;
use crate::util::mask::is_object;
use image::GrayImage;

/// For every pixel, the distance (pixels) to the nearest pixel where `is_target` is false.
/// Pixels outside the image count as not-target when `outside_is_target` is false.
fn edt(mask: &GrayImage, is_target: impl Fn(u8) -> bool, outside_is_target: bool) -> Vec<f32> {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    const INF: f32 = 1e20;
    // Pad by one pixel so that the image border acts as background where asked.
    let (pw, ph) = (w + 2, h + 2);
    let mut f = vec![0f32; pw * ph];
    for y in 0..ph {
        for x in 0..pw {
            let inside = if x == 0 || y == 0 || x == pw - 1 || y == ph - 1 {
                outside_is_target
            } else {
                is_target(mask.get_pixel((x - 1) as u32, (y - 1) as u32)[0])
            };
            f[y * pw + x] = if inside { INF } else { 0.0 };
        }
    }
    let mut buf = vec![0f32; pw.max(ph)];
    for x in 0..pw {
        for y in 0..ph {
            buf[y] = f[y * pw + x];
        }
        let d = squared_distance_1d(&buf[..ph]);
        for y in 0..ph {
            f[y * pw + x] = d[y];
        }
    }
    for y in 0..ph {
        let d = squared_distance_1d(&f[y * pw..(y + 1) * pw]);
        f[y * pw..(y + 1) * pw].copy_from_slice(&d);
    }
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = f[(y + 1) * pw + x + 1].sqrt();
        }
    }
    out
}

/// Signed distance to the mask's edge: positive inside (distance to the nearest outside pixel,
/// the image border counting as outside), negative outside (minus the distance to the nearest
/// inside pixel). Object pixels ([`is_object`]) are inside.
pub fn signed_distance(mask: &GrayImage) -> Vec<f32> {
    let inside = edt(mask, is_object, false);
    let outside = edt(mask, |v| !is_object(v), true);
    inside
        .iter()
        .zip(&outside)
        .map(|(i, o)| if *i > 0.0 { *i } else { -*o })
        .collect()
}

/// The interior point farthest from the mask's edge (pixel centre), or `None` for an empty mask.
pub fn most_interior_point(mask: &GrayImage) -> Option<(f64, f64)> {
    let d = edt(mask, is_object, false);
    let (i, best) = d.iter().enumerate().fold(
        (0, 0f32),
        |acc, (i, v)| if *v > acc.1 { (i, *v) } else { acc },
    );
    (best > 0.0).then(|| {
        (
            (i % mask.width() as usize) as f64 + 0.5,
            (i / mask.width() as usize) as f64 + 0.5,
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    #[test]
    fn matches_brute_force() {
        let mut m = GrayImage::new(23, 17);
        for (x, y) in [(5, 5), (6, 5), (7, 6), (15, 10), (16, 11), (3, 14)] {
            m.put_pixel(x, y, Luma([255]));
        }
        for y in 4..12 {
            for x in 9..14 {
                m.put_pixel(x, y, Luma([255]));
            }
        }
        let sd = signed_distance(&m);
        for y in 0..17i32 {
            for x in 0..23i32 {
                let inside = is_object(m.get_pixel(x as u32, y as u32)[0]);
                let mut best = f32::INFINITY;
                for yy in -1..18i32 {
                    for xx in -1..24i32 {
                        let border = xx < 0 || yy < 0 || xx >= 23 || yy >= 17;
                        let other = if border {
                            !inside
                        } else {
                            is_object(m.get_pixel(xx as u32, yy as u32)[0]) != inside
                        };
                        // Outside the image is "outside the mask": it only bounds inside pixels.
                        if other && (!border || inside) {
                            best = best
                                .min((((xx - x) * (xx - x) + (yy - y) * (yy - y)) as f32).sqrt());
                        }
                    }
                }
                let want = if inside { best } else { -best };
                assert!(
                    (sd[(y * 23 + x) as usize] - want).abs() < 1e-4,
                    "({x},{y}) {} vs {want}",
                    sd[(y * 23 + x) as usize]
                );
            }
        }
        let c = most_interior_point(&m).unwrap();
        assert!((9.0..14.0).contains(&c.0) && (4.0..12.0).contains(&c.1));
    }
}
