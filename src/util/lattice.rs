//! Grid and box arithmetic: face neighbours on dense x-fastest grids (images are grids with
//! `nz = 1`; the flood fills of mask regions and mesh cavities) and the corners of boxes.

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
}
