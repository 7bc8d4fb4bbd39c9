//! How a set of 3D points spreads: its centroid and principal axes (the covariance's
//! eigenvectors, by Jacobi rotations), for planes through points and the plane the cameras
//! moved in.

use glam::{DMat3, DVec3};

/// The centroid of some points and their principal axes, widest first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spread {
    pub centroid: DVec3,
    /// Unit axes, by decreasing spread.
    pub axes: [DVec3; 3],
    /// The standard deviation along each axis.
    pub std: [f64; 3],
}

impl Spread {
    /// `None` for fewer than 3 points or any non-finite coordinate.
    pub fn of(points: &[DVec3]) -> Option<Spread> {
        if points.len() < 3 || points.iter().any(|p| !p.is_finite()) {
            return None;
        }
        let n = points.len() as f64;
        let centroid = points.iter().copied().sum::<DVec3>() / n;
        let mut cov = [[0.0f64; 3]; 3];
        for p in points {
            let q = (*p - centroid).to_array();
            for (i, row) in cov.iter_mut().enumerate() {
                for (j, c) in row.iter_mut().enumerate() {
                    *c += q[i] * q[j] / n;
                }
            }
        }
        let (values, vectors) = symmetric_eigen(cov);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| values[b].total_cmp(&values[a]));
        Some(Spread {
            centroid,
            axes: order.map(|k| vectors.col(k).normalize()),
            std: order.map(|k| values[k].max(0.0).sqrt()),
        })
    }

    /// The axis of least spread: a plane's normal through the points.
    pub fn normal(&self) -> DVec3 {
        self.axes[2]
    }

    /// How flat the points lie: the least spread over the middle one (0 for a plane; `None`
    /// when the points gather on a line or a point, where no plane is defined).
    pub fn flatness(&self) -> Option<f64> {
        (self.std[1] > 1e-12 * self.std[0].max(1e-300)).then(|| self.std[2] / self.std[1])
    }
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 3x3 matrix by cyclic Jacobi rotations.
fn symmetric_eigen(m: [[f64; 3]; 3]) -> ([f64; 3], DMat3) {
    let mut a = m;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let diag = a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2);
        if off <= 1e-30 * diag.max(1e-300) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // a <- J^T a J with J the rotation in the (p, q) plane; v <- v J.
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * row_p[k] - s * row_q[k];
                a[q][k] = s * row_p[k] + c * row_q[k];
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let cols = DMat3::from_cols(
        DVec3::new(v[0][0], v[1][0], v[2][0]),
        DVec3::new(v[0][1], v[1][1], v[2][1]),
        DVec3::new(v[0][2], v[1][2], v[2][2]),
    );
    ([a[0][0], a[1][1], a[2][2]], cols)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tilted_ellipse_of_points_gives_its_axes_and_normal() {
        // Points on an ellipse (radii 3 and 1) in a plane tilted about x, plus a little
        // thickness along the plane's normal.
        let normal = DVec3::new(0.0, -0.3, 1.0).normalize();
        let e1 = DVec3::X;
        let e2 = normal.cross(e1);
        let points: Vec<DVec3> = (0..72)
            .map(|i| {
                let a = i as f64 * 5f64.to_radians();
                let h = if i % 2 == 0 { 0.01 } else { -0.01 };
                DVec3::new(1.0, 2.0, 3.0) + e1 * 3.0 * a.cos() + e2 * a.sin() + normal * h
            })
            .collect();
        let s = Spread::of(&points).unwrap();
        assert!((s.centroid - DVec3::new(1.0, 2.0, 3.0)).length() < 1e-9);
        assert!(s.axes[0].dot(e1).abs() > 1.0 - 1e-9);
        assert!(s.axes[1].dot(e2).abs() > 1.0 - 1e-9);
        assert!(s.normal().dot(normal).abs() > 1.0 - 1e-9);
        // An ellipse's std along a radius r is r / sqrt(2).
        assert!((s.std[0] - 3.0 / 2f64.sqrt()).abs() < 1e-6);
        assert!((s.std[2] - 0.01).abs() < 1e-9);
        assert!(s.flatness().unwrap() < 0.02);
        for i in 0..3 {
            for j in 0..3 {
                let d = s.axes[i].dot(s.axes[j]);
                assert!((d - f64::from(u8::from(i == j))).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn too_few_or_collinear_points_give_no_plane() {
        assert!(Spread::of(&[DVec3::ZERO, DVec3::X]).is_none());
        assert!(Spread::of(&[DVec3::ZERO, DVec3::X, DVec3::NAN]).is_none());
        let line: Vec<DVec3> = (0..5).map(|i| DVec3::X * i as f64).collect();
        assert!(Spread::of(&line).unwrap().flatness().is_none());
    }
}
