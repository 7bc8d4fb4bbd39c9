//! How low the demo mug's mesh Chamfer can go from its own views: the part of the cup's inside
//! that no camera of the demo ring sees, and the Chamfer of a mesh that is exact everywhere
//! else and solid under what is seen (what `mesh::fill` makes of unseen space).
//!
//!     objnerf demo --out runs/demo      # writes runs/demo/scene
//!     cargo run --release --example mug_cup_bound -- runs/demo/scene
//!
//! Visibility is traced in the demo's exact geometry from every view's camera centre (the
//! training views are a subset, so the seen part is if anything overstated and the bound low).
//! The lid (the lowest air point some camera sees, column by column in the cup) is sampled on
//! its footprint, so its slope's extra area is left out: the bound is low there too.

use glam::DVec3;
use objnerf::demo::geometry::{Ray, Shape, World};
use objnerf::mesh::chamfer::{sample_surface, PointGrid};
use objnerf::util::Rng;
use objnerf::Scene;
use rayon::prelude::*;
use std::f64::consts::TAU;

const RINGS: usize = 24;
const ANGLES: usize = 96;
const POINTS: usize = 50_000;

fn main() -> objnerf::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "runs/demo/scene".into());
    let scene = Scene::load(std::path::Path::new(&dir))?;
    let cameras: Vec<DVec3> = scene.images.iter().map(|v| v.pose.center()).collect();
    let world = World::demo();
    let mug = world.object("mug").expect("the demo has a mug");
    let Shape::Mug {
        radius,
        height,
        wall,
        base,
        ..
    } = mug.shape
    else {
        unreachable!("the demo's mug is a mug")
    };
    let cavity = radius - wall;
    let seen = |p: DVec3| {
        cameras.iter().any(|&c| {
            let dist = (p - c).length();
            let ray = Ray {
                o: c,
                d: (p - c) / dist,
            };
            world.trace(&ray, None).is_none_or(|h| h.t > dist - 1e-6)
        })
    };
    // The lid: in each column of the cup (polar cells, local frame), the lowest seen air point.
    let lid: Vec<f64> = (0..RINGS * ANGLES)
        .into_par_iter()
        .map(|k| {
            let r = cavity * ((k / ANGLES) as f64 + 0.5) / RINGS as f64;
            let a = TAU * ((k % ANGLES) as f64 + 0.5) / ANGLES as f64;
            // Seen from the rim down to the lid (a cup's column is): bisect for it to 0.5 mm.
            let at = |z: f64| mug.place.to_world(DVec3::new(r * a.cos(), r * a.sin(), z));
            let (mut lo, mut hi) = (base, height);
            while hi - lo > 5e-4 {
                let mid = 0.5 * (lo + hi);
                if seen(at(mid)) {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            hi
        })
        .collect();
    let lid_at = |p: DVec3| {
        let r = (p.x * p.x + p.y * p.y).sqrt();
        let ring = ((r / cavity * RINGS as f64) as usize).min(RINGS - 1);
        let angle = (p.y.atan2(p.x).rem_euclid(TAU) / TAU * ANGLES as f64) as usize % ANGLES;
        lid[ring * ANGLES + angle]
    };
    let truth = objnerf::demo::mesh::tessellate(mug).to_mesh("mug");
    let truth_points = sample_surface(&truth, POINTS, 7);
    // Exact but for the cup: its inner wall and floor under the lid are inside the solid.
    let mut bound: Vec<DVec3> = truth_points
        .iter()
        .copied()
        .filter(|&p| {
            let l = mug.place.to_local(p);
            let inside = (l.x * l.x + l.y * l.y).sqrt() < cavity + 1e-4 && l.z > base - 1e-4;
            !(inside && l.z < lid_at(l))
        })
        .collect();
    let area = |m: &objnerf::mesh::Mesh| -> f64 {
        let p = |i: u32| DVec3::from_array(m.positions[i as usize].map(|x| x as f64));
        m.triangles
            .iter()
            .map(|t| 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length())
            .sum()
    };
    let scale = mug.place.scale();
    let lid_area = std::f64::consts::PI * (cavity * scale).powi(2);
    let n_lid = (POINTS as f64 * lid_area / area(&truth)) as usize;
    let mut rng = Rng::new(11);
    for _ in 0..n_lid {
        let (r, a) = (cavity * rng.f64().sqrt(), TAU * rng.f64());
        let l = DVec3::new(r * a.cos(), r * a.sin(), 0.0);
        bound.push(mug.place.to_world(DVec3::new(l.x, l.y, lid_at(l))));
    }
    let (lo, hi) = truth.bounds();
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) as f64;
    let mean = |from: &[DVec3], to: &PointGrid| {
        from.par_iter().map(|&p| to.nearest(p)).sum::<f64>() / from.len() as f64
    };
    let to_bound = mean(&truth_points, &PointGrid::new(&bound));
    let to_truth = mean(&bound, &PointGrid::new(&truth_points));
    let mut heights: Vec<f64> = lid.clone();
    heights.sort_by(f64::total_cmp);
    let pct = |q: f64| heights[((heights.len() - 1) as f64 * q) as usize];
    println!(
        "{} cameras; the cup (cavity radius {cavity:.3}, floor at {base:.3}, rim at {height:.3}) is seen \
         down to the lid: lowest {:.3}, median {:.3}, highest {:.3} (local z)",
        cameras.len(),
        pct(0.0),
        pct(0.5),
        pct(1.0)
    );
    println!(
        "a mesh exact but for the unseen cup, solid under the lid: Chamfer {:.3}% of the true box \
         diagonal (truth -> it {:.3}%, it -> truth {:.3}%)",
        50.0 * (to_bound + to_truth) / diag,
        100.0 * to_bound / diag,
        100.0 * to_truth / diag
    );
    Ok(())
}
