//! A scene restricted to some of its images: features, points and tracks re-indexed so the
//! result is a scene in its own right (points seen by fewer than two kept images are dropped,
//! as a reconstruction from those images alone would never have triangulated them).

use super::{Scene, TrackElement};

impl Scene {
    /// The scene with only the images at `keep` (scene indices, in the order given). Points
    /// keep the observations in kept images and survive with at least two of them.
    pub fn subset(&self, keep: &[usize]) -> Scene {
        let mut new_index = vec![None; self.images.len()];
        for (n, &i) in keep.iter().enumerate() {
            new_index[i] = Some(n);
        }
        let mut point_index = vec![None; self.points.len()];
        let mut points = Vec::new();
        for (pi, p) in self.points.iter().enumerate() {
            let track: Vec<TrackElement> = p
                .track
                .iter()
                .filter_map(|t| {
                    new_index[t.image].map(|image| TrackElement {
                        image,
                        feature: t.feature,
                    })
                })
                .collect();
            if track.len() >= 2 {
                point_index[pi] = Some(points.len());
                let mut q = p.clone();
                q.track = track;
                points.push(q);
            }
        }
        let images = keep
            .iter()
            .map(|&i| {
                let mut im = self.images[i].clone();
                for f in &mut im.features {
                    f.point = f.point.and_then(|p| point_index[p]);
                }
                im
            })
            .collect();
        Scene {
            images,
            points,
            ..self.clone_without_views()
        }
    }

    /// Everything but the images and points (cameras, source, format, depth scale).
    fn clone_without_views(&self) -> Scene {
        Scene {
            source: self.source.clone(),
            format: self.format,
            cameras: self.cameras.clone(),
            images: vec![],
            points: vec![],
            depth_scale: self.depth_scale,
            applied_transform: self.applied_transform,
        }
    }
}
