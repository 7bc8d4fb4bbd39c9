//! The sparse grid's tests: interpolation, its gradient and transpose, fill, resampling,
//! compaction and the layout conversion.

use super::*;

fn ramp(keep: impl Fn([usize; 3]) -> bool) -> Grid {
    let mut g = Grid::with_bricks([6, 5, 9], 2, &[0.0, 0.0], keep);
    for z in 0..9 {
        for y in 0..5 {
            for x in 0..6 {
                let v = g.vertex_slot(x, y, z);
                if v == NONE {
                    continue;
                }
                let v = v as usize;
                *g.density_mut(v) = 1.0 + 2.0 * x as f32 - 0.5 * y as f32 + 3.0 * z as f32;
                g.colour_mut(v)[0] = (x * y + z) as f32;
            }
        }
    }
    g
}

#[test]
fn trilinear_reproduces_linear_functions_and_vertices() {
    let g = ramp(|_| true);
    let mut out = [0.0; 2];
    for p in [
        [0.3, 1.7, 2.2],
        [5.0, 4.0, 8.0],
        [0.0, 0.0, 0.0],
        [3.5, 3.5, 3.9],
        [2.5, 0.5, 7.9],
    ] {
        g.sample(p, &mut out);
        let want = 1.0 + 2.0 * p[0] - 0.5 * p[1] + 3.0 * p[2];
        assert!((out[0] - want).abs() < 1e-4, "{p:?}: {} vs {want}", out[0]);
    }
    g.sample([2.0, 1.0, 3.0], &mut out);
    assert_eq!(out[1], 5.0);
    let k = g.corners([1.25, 0.5, 2.75]);
    assert!((k.w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    // Slot indices and coordinates agree, across brick borders too.
    for (x, y, z) in [(0, 0, 0), (3, 4, 4), (5, 4, 8)] {
        assert_eq!(g.vertex_coords(g.vertex_slot(x, y, z)), [x, y, z]);
    }
}

#[test]
fn interpolation_gradient_matches_finite_differences() {
    let mut g = ramp(|_| true);
    // A field that is not linear, so the bilinear weights of each axis's slope matter.
    g.data
        .iter_mut()
        .enumerate()
        .for_each(|(i, v)| *v = (i as f32 * 0.37).sin());
    for p in [[0.3f32, 1.7, 2.2], [3.6, 3.2, 3.9], [2.5, 0.5, 7.4]] {
        let (b, f) = g.locate(p);
        let grad = g.density_gradient(&g.corners_of(b, f), f);
        for a in 0..3 {
            let eps = 1e-2;
            let (mut hi, mut lo) = (f, f);
            hi[a] += eps;
            lo[a] -= eps;
            let at = |fr: [f32; 3]| g.interp_density(&g.corners_of(b, fr));
            let num = (at(hi) - at(lo)) / (2.0 * eps);
            assert!(
                (num - grad[a]).abs() < 1e-3,
                "{p:?} axis {a}: {num} vs {}",
                grad[a]
            );
        }
    }
}

#[test]
fn bricks_stored_vertex_by_vertex_convert_to_the_layout() {
    // Channel c of slot index v held i = v * 3 + c when every channel of a vertex sat
    // together; after conversion each reads back where it was, density and colour.
    let mut g = Grid::new([6, 5, 9], 3, &[0.0; 3]);
    g.data
        .iter_mut()
        .enumerate()
        .for_each(|(i, x)| *x = i as f32);
    from_interleaved(&mut g.data, 3);
    for v in 0..g.num_vertices() {
        assert_eq!(g.vertex_values(v), [0, 1, 2].map(|c| (v * 3 + c) as f32));
    }
    let [x, y, z] = g.vertex_coords(70);
    assert_eq!(g.get(x, y, z, 2), 212.0);
}

#[test]
fn missing_bricks_read_as_fill() {
    let g = ramp(|b| b[2] == 0);
    assert_eq!(g.num_slots(), 4);
    assert_eq!(g.vertex_slot(0, 0, 5), NONE);
    assert_eq!(g.get(1, 1, 6, 0), 0.0);
    assert_eq!(g.get(1, 1, 2, 0), 1.0 + 2.0 - 0.5 + 6.0);
}

#[test]
fn scatter_is_the_transpose_of_interpolation() {
    // <interp(data), g> == <data, scatter(g)> for any data and g, across a brick border.
    let g = ramp(|_| true);
    let k = g.corners([3.3, 0.6, 3.9]);
    let mut out = [0.0; 2];
    out[0] = g.interp_density(&k);
    g.interp_colour(&k, &mut out[1..]);
    let up = [0.7f32, -1.3];
    let lhs = out[0] * up[0] + out[1] * up[1];
    let mut grad = vec![0.0; g.data.len()];
    Grid::scatter(&mut grad, 2, &k, &up);
    let rhs: f32 = grad.iter().zip(&g.data).map(|(a, b)| a * b).sum();
    assert!((lhs - rhs).abs() < 1e-3, "{lhs} vs {rhs}");
}

#[test]
fn resampling_keeps_linear_functions() {
    let g = ramp(|_| true);
    let h = g.resampled([11, 9, 17], |_| true);
    let mut a = [0.0; 2];
    let mut b = [0.0; 2];
    // Grid point (x, y, z) of h is (x/2, y/2, z/2) of g.
    h.sample([3.0, 1.0, 5.0], &mut a);
    g.sample([1.5, 0.5, 2.5], &mut b);
    assert!((a[0] - b[0]).abs() < 1e-4);
}

#[test]
fn compaction_keeps_values_and_layers_stay_contiguous() {
    let mut g = ramp(|_| true);
    let before = g.get(5, 4, 8, 0);
    let keep: Vec<bool> = (0..g.num_slots()).map(|s| s % 3 != 1).collect();
    let mut state: Vec<f32> = (0..g.data.len()).map(|i| i as f32).collect();
    let kept_value = state[(g.num_slots() - 1) * BRICK_VERTICES * 2];
    let map = g.compact(&keep);
    compact_buffer(&mut state, &map, BRICK_VERTICES * 2);
    assert_eq!(state.len(), g.data.len());
    let last = map[map.len() - 1] as usize;
    assert_eq!(state[last * BRICK_VERTICES * 2], kept_value);
    if g.vertex_slot(5, 4, 8) != NONE {
        assert_eq!(g.get(5, 4, 8, 0), before);
    }
    let starts = g.layer_starts();
    assert_eq!(*starts.last().unwrap(), g.num_slots());
    for z in 0..g.brick_dims[2] {
        for s in starts[z]..starts[z + 1] {
            assert_eq!(g.brick_of_slot(s)[2], z);
        }
    }
}
