//! A similarity transform: a uniform scale, a rotation and a translation, `x = s R p + t`.

use crate::util::lattice::box_corners;
use glam::{DMat3, DMat4, DQuat, DVec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similarity {
    /// Positive.
    pub scale: f64,
    /// Unit quaternion.
    pub rotation: DQuat,
    pub translation: DVec3,
}

impl Similarity {
    pub const IDENTITY: Similarity = Similarity {
        scale: 1.0,
        rotation: DQuat::IDENTITY,
        translation: DVec3::ZERO,
    };

    /// The edit file's transform of a model point `p`: `k pivot + translation + scale k R (p -
    /// pivot)`, with `k` the model's unit length over the file's (docs/edit-format.md).
    pub fn from_edit(
        pivot: DVec3,
        translation: DVec3,
        rotation: DQuat,
        scale: f64,
        k: f64,
    ) -> Self {
        let s = scale * k;
        Similarity {
            scale: s,
            rotation,
            translation: k * pivot + translation - s * (rotation * pivot),
        }
    }

    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.scale * (self.rotation * p) + self.translation
    }

    /// A direction (rotated only).
    #[inline]
    pub fn apply_dir(&self, d: DVec3) -> DVec3 {
        self.rotation * d
    }

    pub fn inverse(&self) -> Similarity {
        let r = self.rotation.conjugate();
        Similarity {
            scale: 1.0 / self.scale,
            rotation: r,
            translation: -(r * self.translation) / self.scale,
        }
    }

    /// `self` after `first`: p -> self(first(p)).
    pub fn after(&self, first: &Similarity) -> Similarity {
        Similarity {
            scale: self.scale * first.scale,
            rotation: (self.rotation * first.rotation).normalize(),
            translation: self.apply(first.translation),
        }
    }

    pub fn matrix(&self) -> DMat4 {
        DMat4::from_scale_rotation_translation(
            DVec3::splat(self.scale),
            self.rotation,
            self.translation,
        )
    }

    /// The scaled rotation as a 3x3 matrix.
    pub fn linear(&self) -> DMat3 {
        DMat3::from_quat(self.rotation) * self.scale
    }

    /// The world box around the box `lo..hi` transformed.
    pub fn apply_box(&self, lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
        let mut a = DVec3::splat(f64::INFINITY);
        let mut b = DVec3::splat(f64::NEG_INFINITY);
        for c in box_corners(lo, hi) {
            let w = self.apply(c);
            a = a.min(w);
            b = b.max(w);
        }
        (a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pivot_stays_put_and_inverse_undoes() {
        let pivot = DVec3::new(0.4, -0.3, 0.1);
        let q = DQuat::from_rotation_z(1.1) * DQuat::from_rotation_x(0.3);
        let t = DVec3::new(0.15, 0.0, 0.02);
        let s = Similarity::from_edit(pivot, t, q, 1.5, 1.0);
        assert!((s.apply(pivot) - (pivot + t)).length() < 1e-12);
        let p = DVec3::new(0.7, 0.2, -0.5);
        assert!((s.inverse().apply(s.apply(p)) - p).length() < 1e-12);
        // Scale and k: distances scale by scale * k, the pivot lands at k * pivot + t.
        let s2 = Similarity::from_edit(pivot, t, q, 2.0, 0.25);
        assert!((s2.apply(pivot) - (0.25 * pivot + t)).length() < 1e-12);
        let d = (s2.apply(p) - s2.apply(pivot)).length() / (p - pivot).length();
        assert!((d - 0.5).abs() < 1e-12);
        let c = s.after(&s2);
        assert!((c.apply(p) - s.apply(s2.apply(p))).length() < 1e-12);
    }
}
