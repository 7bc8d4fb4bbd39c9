//! Grid and box arithmetic: face neighbours on dense x-fastest grids (images are grids with
//! `nz = 1`; the flood fills of mask regions and mesh cavities), exact Euclidean distance
//! transforms on them (mask edges, the closing of a mesh's solid) and the corners of boxes.

use glam::DVec3;

/// The 8 corners of the axis-aligned box `lo..hi`; corner `i` takes `hi` on x, y, z where bits
/// 0, 1, 2 of `i` are set.
pub fn box_corners(lo: DVec3, hi: DVec3) -> [DVec3; 8] {
    std::array::from_fn(|i| {
        DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// Call `visit` with the index of every face neighbour (4 in 2D, 6 in 3D) of sample `i` in a
/// grid of `[nx, ny, nz]` samples stored x fastest.
#[inline]
pub fn face_neighbours(i: usize, [nx, ny, nz]: [usize; 3], mut visit: impl FnMut(usize)) {
    let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
    if x > 0 {
        visit(i - 1);
    }
    if x + 1 < nx {
        visit(i + 1);
    }
    if y > 0 {
        visit(i - nx);
    }
    if y + 1 < ny {
        visit(i + nx);
    }
    if z > 0 {
        visit(i - nx * ny);
    }
    if z + 1 < nz {
        visit(i + nx * ny);
    }
}

/// Squared distance transform in 1-D (Felzenszwalb & Huttenlocher's lower envelope of
/// parabolas): for every sample q, min over p of (q - p)^2 + f[p]. With f = 0 on targets and a
/// large value elsewhere, the squared distance to the nearest target.
pub fn squared_distance_1d(f: &[f32]) -> Vec<f32> {
    let n = f.len();
    let mut d = vec![0f32; n];
    let mut v = vec![0usize; n];
    let mut z = vec![0f32; n + 1];
    let mut k = 0usize;
    z[0] = f32::NEG_INFINITY;
    z[1] = f32::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f32) - (f[p] + (p * p) as f32))
                / (2.0 * q as f32 - 2.0 * p as f32);
            if s <= z[k] && k > 0 {
                k -= 1;
            } else if s <= z[k] {
                // k == 0 and the new parabola dominates from -inf: replace.
                v[0] = q;
                z[1] = f32::INFINITY;
                break;
            } else {
                k += 1;
                v[k] = q;
                z[k] = s;
                z[k + 1] = f32::INFINITY;
                break;
            }
        }
    }
    k = 0;
    for (q, dq) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f32 {
            k += 1;
        }
        let p = v[k];
        *dq = (q as f32 - p as f32).powi(2) + f[p];
    }
    d
}

/// For every sample of a dense x-fastest grid, the squared distance (in samples) to the nearest
/// sample where `target` is true; about 1e20 where there is none.
pub fn squared_distance_to(target: &[bool], [nx, ny, nz]: [usize; 3]) -> Vec<f32> {
    const FAR: f32 = 1e20;
    let mut f: Vec<f32> = target.iter().map(|&t| if t { 0.0 } else { FAR }).collect();
    let dims = [nx, ny, nz];
    let strides = [1, nx, nx * ny];
    let mut line = Vec::new();
    for axis in 0..3 {
        let (n, s) = (dims[axis], strides[axis]);
        if n < 2 {
            continue;
        }
        for start in 0..f.len() {
            // The first sample of each line along this axis.
            if (start / s) % n != 0 {
                continue;
            }
            line.clear();
            line.extend((0..n).map(|k| f[start + k * s]));
            for (k, d) in squared_distance_1d(&line).into_iter().enumerate() {
                f[start + k * s] = d.min(FAR);
            }
        }
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_and_centres_have_the_right_neighbours() {
        let collect = |i, dims| {
            let mut v = Vec::new();
            face_neighbours(i, dims, |j| v.push(j));
            v.sort();
            v
        };
        assert_eq!(collect(0, [3, 3, 1]), vec![1, 3]);
        assert_eq!(collect(4, [3, 3, 1]), vec![1, 3, 5, 7]);
        assert_eq!(collect(13, [3, 3, 3]), vec![4, 10, 12, 14, 16, 22]);
    }

    #[test]
    fn squared_distances_match_brute_force() {
        let dims = [7, 5, 6];
        let n = dims[0] * dims[1] * dims[2];
        let pos = |i: usize| [i % 7, (i / 7) % 5, i / 35].map(|c| c as f32);
        let target: Vec<bool> = (0..n).map(|i| (i * 37 + 11) % 23 == 0).collect();
        let d = squared_distance_to(&target, dims);
        for (i, &got) in d.iter().enumerate() {
            let want = (0..n)
                .filter(|&j| target[j])
                .map(|j| {
                    let (a, b) = (pos(i), pos(j));
                    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f32>()
                })
                .fold(f32::MAX, f32::min);
            assert_eq!(got, want, "sample {i}");
        }
    }
}
