// The composite ray march of `render::composite::render_ray` (and, for one layer in place, the
// single-field march of `field::march::forward`), one invocation a ray, in the same f32
// arithmetic in the same order: every line here mirrors a line of the CPU code named beside it.
//
// Each layer (field) is a generator of its kept samples: `advance` marches its line until the
// next kept sample (the CPU collects them all first, then merges; the merge only ever needs
// each layer's next one). The nearest pending sample of all layers is composited next.

const NONE: u32 = 0xffffffffu;
const BRICK: u32 = 4u;
const BLOCK: u32 = 4u;
const MAX_LAYERS: u32 = 16u;
const MAX_HIDDEN: u32 = 128u;
const MAX_CHANNELS: u32 = 28u;
const BIG: f32 = 3.4028235e38;

// One field of the composite (all 4-byte scalars: the Rust side writes them as words, in this
// order; see `upload.rs`).
struct Layer {
    // The camera centre in the field's frame (scale * rot * o + shift, on the CPU).
    ox: f32, oy: f32, oz: f32,
    // World -> field rotation, columns.
    r0x: f32, r0y: f32, r0z: f32,
    r1x: f32, r1y: f32, r1z: f32,
    r2x: f32, r2y: f32, r2z: f32,
    // 1 / scale, and whether the scale is not 1 (then t is multiplied by it).
    to_world: f32, scaled: u32,
    lo_x: f32, lo_y: f32, lo_z: f32,
    hi_x: f32, hi_y: f32, hi_z: f32,
    voxel: f32, step_w: f32, delta: f32, shift: f32, raw_min: f32, min_weight: f32,
    dim_x: u32, dim_y: u32, dim_z: u32, channels: u32,
    bd_x: u32, bd_y: u32, bd_z: u32,
    kd_x: u32, kd_y: u32, kd_z: u32,
    data_off: u32, fill_off: u32, index_off: u32, occ_off: u32, live_off: u32, block_off: u32,
    net_off: u32,
    sh_degree: u32, sh_k: u32, is_net: u32, features: u32, dir_terms: u32, refl_terms: u32,
    hidden: u32, hidden2: u32,
    index: u32,
    // 0: none; 1: towards the target a-b (rc0, rc1) by rc2; 2: a-b turned by (cos rc0, sin rc1).
    recolour: u32, rc0: f32, rc1: f32, rc2: f32,
};

struct Params {
    n_rays: u32,
    n_layers: u32,
    alpha_thresh: f32,
    term_thresh: f32,
    bg_r: f32, bg_g: f32, bg_b: f32,
    pad: u32,
};

struct RayOut {
    r: f32, g: f32, b: f32,
    alpha: f32,
    // Distance along the world ray where the opacity reaches 1/2; -1: never.
    t_half: f32,
    // sum w t over the composited samples (the single-field renderer's depth).
    depth: f32,
    index: u32,
    // 1: the device ended the march's loops early (the result is wrong).
    cut: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> layers: array<Layer>;
@group(0) @binding(2) var<storage, read> vals: array<f32>;
@group(0) @binding(3) var<storage, read> words: array<u32>;
@group(0) @binding(4) var<storage, read> rays: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> outs: array<RayOut>;

// Per layer: its line (field frame, grid units), lattice and march state, and the pending
// sample.
var<private> st_og: array<vec3<f32>, MAX_LAYERS>;
var<private> st_dg: array<vec3<f32>, MAX_LAYERS>;
var<private> st_d: array<vec3<f32>, MAX_LAYERS>;
var<private> st_t0: array<f32, MAX_LAYERS>;
var<private> st_t: array<f32, MAX_LAYERS>;
var<private> st_s1: array<f32, MAX_LAYERS>;
var<private> st_ks: array<u32, MAX_LAYERS>;
var<private> st_trans: array<f32, MAX_LAYERS>;
// 0: marching; 1: stopped (opaque or past the box).
var<private> st_done: array<u32, MAX_LAYERS>;
var<private> pend_ok: array<u32, MAX_LAYERS>;
var<private> pend_t: array<f32, MAX_LAYERS>;
var<private> pend_alpha: array<f32, MAX_LAYERS>;
var<private> pend_rgb: array<vec3<f32>, MAX_LAYERS>;
var<private> weights: array<f32, MAX_LAYERS>;
// Scratch for one sample's colour.
var<private> feat: array<f32, MAX_CHANNELS>;
var<private> cw: array<f32, 8>;
var<private> cidx: array<u32, 8>;
// Where the 8 corners' colour channels start in `vals`.
var<private> csrc: array<u32, 8>;
// The 8 corners' raw densities.
var<private> cd: array<f32, 8>;
var<private> basis: array<f32, 16>;
var<private> refl: array<f32, 16>;
var<private> h1: array<f32, MAX_HIDDEN>;
var<private> h2: array<f32, MAX_HIDDEN>;
// ColourNet::ray_bias of this ray's direction, MAX_HIDDEN a layer (MAX_LAYERS * MAX_HIDDEN).
var<private> bias: array<f32, 2048>;

fn sigmoid(x: f32) -> f32 {
    return 1.0 / (1.0 + exp(-x));
}

// ln(1 + x) to float precision for small x (Goldberg's trick; WGSL has no log1p).
fn ln_1p(x: f32) -> f32 {
    let u = 1.0 + x;
    if (u == 1.0) {
        return x;
    }
    return log(u) * (x / (u - 1.0));
}

// activation::alpha_and_slope's alpha.
fn alpha_of(raw: f32, delta: f32) -> f32 {
    if (raw > 15.0) {
        return 1.0 - exp(-raw * delta);
    }
    let e = exp(raw);
    if (delta == 1.0) {
        return e / (1.0 + e);
    }
    return 1.0 - exp(-ln_1p(e) * delta);
}

// Grid::vertex_slot.
fn vertex_slot(l: u32, x: u32, y: u32, z: u32) -> u32 {
    let L = &layers[l];
    let b = (x / BRICK) + (*L).bd_x * ((y / BRICK) + (*L).bd_y * (z / BRICK));
    let s = words[(*L).index_off + b];
    if (s == NONE) {
        return NONE;
    }
    return s * 64u + (x % BRICK + BRICK * (y % BRICK + BRICK * (z % BRICK)));
}

fn density_at(l: u32, v: u32) -> f32 {
    let L = &layers[l];
    if (v == NONE) {
        return vals[(*L).fill_off];
    }
    return vals[(*L).data_off + (v / 64u) * 64u * (*L).channels + v % 64u];
}

// Where slot index v's colour channels start in `vals` (the fill's where unallocated).
fn colour_at(l: u32, v: u32) -> u32 {
    let L = &layers[l];
    if (v == NONE) {
        return (*L).fill_off + 1u;
    }
    let ch = (*L).channels;
    return (*L).data_off + (v / 64u) * 64u * ch + 64u + (v % 64u) * (ch - 1u);
}

// Field::occupied: the cell's bit in its brick's occupancy word.
fn occupied(l: u32, b: vec3<u32>) -> bool {
    let L = &layers[l];
    let bi = (b.x / BRICK) + (*L).bd_x * ((b.y / BRICK) + (*L).bd_y * (b.z / BRICK));
    let s = words[(*L).index_off + bi];
    if (s == NONE) {
        return false;
    }
    let lo = b.x % BRICK + BRICK * (b.y % BRICK + BRICK * (b.z % BRICK));
    let w = words[(*L).occ_off + 2u * s + (lo >> 5u)];
    return ((w >> (lo & 31u)) & 1u) == 1u;
}

// LiveBricks::brick for the brick holding cell b.
fn brick_live(l: u32, b: vec3<u32>) -> bool {
    let L = &layers[l];
    let i = (b.x / BRICK) + (*L).bd_x * ((b.y / BRICK) + (*L).bd_y * (b.z / BRICK));
    return ((words[(*L).live_off + (i >> 5u)] >> (i & 31u)) & 1u) == 1u;
}

// LiveBricks::block for the block holding cell b.
fn block_live(l: u32, b: vec3<u32>) -> bool {
    let L = &layers[l];
    let s = BRICK * BLOCK;
    let j = (b.x / s) + (*L).kd_x * ((b.y / s) + (*L).kd_y * (b.z / s));
    return ((words[(*L).block_off + (j >> 5u)] >> (j & 31u)) & 1u) == 1u;
}

// Grid::locate, one axis.
fn locate_axis(p: f32, dim: u32) -> vec2<f32> {
    let q = clamp(p, 0.0, f32(dim) - 1.0);
    let b = min(u32(q), dim - 2u);
    return vec2<f32>(f32(b), q - f32(b));
}

// Grid::corners_of into cidx / cw.
fn corners(l: u32, b: vec3<u32>, f: vec3<f32>) {
    let gx = 1.0 - f.x;
    let gy = 1.0 - f.y;
    let gz = 1.0 - f.z;
    cw[0] = gx * gy * gz;
    cw[1] = f.x * gy * gz;
    cw[2] = gx * f.y * gz;
    cw[3] = f.x * f.y * gz;
    cw[4] = gx * gy * f.z;
    cw[5] = f.x * gy * f.z;
    cw[6] = gx * f.y * f.z;
    cw[7] = f.x * f.y * f.z;
    for (var i = 0u; i < 8u; i++) {
        cidx[i] = vertex_slot(l, b.x + (i & 1u), b.y + ((i >> 1u) & 1u), b.z + (i >> 2u));
    }
}

// Grid::density_gradient (corner densities in cd).
fn gradient_weight(i: u32, axis: u32, f: vec3<f32>) -> f32 {
    if (((i >> axis) & 1u) == 1u) {
        return f[axis];
    }
    return 1.0 - f[axis];
}

fn density_gradient(f: vec3<f32>) -> vec3<f32> {
    var g = vec3<f32>(0.0);
    for (var a = 0u; a < 3u; a++) {
        let b = (a + 1u) % 3u;
        let c = (a + 2u) % 3u;
        let stride = 1u << a;
        var s = 0.0;
        for (var i = 0u; i < 8u; i++) {
            if ((i & stride) == 0u) {
                s += gradient_weight(i, b, f) * gradient_weight(i, c, f) * (cd[i + stride] - cd[i]);
            }
        }
        g[a] = s;
    }
    return g;
}

// Marcher::visit: the sample at cell b, fraction f, world distance t. True when it is kept
// (then it is the layer's pending sample).
fn visit(l: u32, b: vec3<u32>, f: vec3<f32>, t: f32) -> bool {
    let L = &layers[l];
    if (!occupied(l, b)) {
        return false;
    }
    corners(l, b, f);
    var raw = 0.0;
    for (var i = 0u; i < 8u; i++) {
        cd[i] = density_at(l, cidx[i]);
        raw += cw[i] * cd[i];
    }
    raw += (*L).shift;
    if (raw < (*L).raw_min) {
        return false;
    }
    let alpha = alpha_of(raw, (*L).delta);
    if (alpha < params.alpha_thresh) {
        return false;
    }
    let trans = st_trans[l];
    let w = trans * alpha;
    var rgb = vec3<f32>(0.0);
    if ((*L).is_net == 0u || w >= (*L).min_weight) {
        // Grid::interp_colour: each channel the sum over the corners in their order.
        let n = (*L).channels - 1u;
        for (var i = 0u; i < 8u; i++) {
            csrc[i] = colour_at(l, cidx[i]);
        }
        for (var j = 0u; j < n; j++) {
            var a = 0.0;
            for (var i = 0u; i < 8u; i++) {
                a += cw[i] * vals[csrc[i] + j];
            }
            feat[j] = a;
        }
        if ((*L).is_net == 0u) {
            let k = (*L).sh_k;
            basis = sh_basis((*L).sh_degree, st_d[l]);
            rgb.x = sigmoid(sh_dot(0u, k));
            rgb.y = sigmoid(sh_dot(k, k));
            rgb.z = sigmoid(sh_dot(2u * k, k));
        } else {
            if ((*L).refl_terms > 0u) {
                let g = density_gradient(f);
                refl = sh_basis((*L).sh_degree, reflect_about(st_d[l], g));
            }
            rgb = net_rgb(l);
        }
    }
    pend_ok[l] = 1u;
    // render_ray scales a placed field's distances to the world's before the merge.
    if ((*L).scaled == 1u) {
        pend_t[l] = t * (*L).to_world;
    } else {
        pend_t[l] = t;
    }
    pend_alpha[l] = alpha;
    pend_rgb[l] = rgb;
    st_trans[l] = trans * (1.0 - alpha);
    return true;
}

// Marcher::line up to the next kept sample; false when the layer has none left.
fn advance(l: u32) -> bool {
    pend_ok[l] = 0u;
    if (st_done[l] == 1u) {
        return false;
    }
    let L = &layers[l];
    let og = st_og[l];
    let dg = st_dg[l];
    let t0 = st_t0[l];
    let step_w = (*L).step_w;
    let dims = vec3<u32>((*L).dim_x, (*L).dim_y, (*L).dim_z);
    var t = st_t[l];
    var ks = st_ks[l];
    loop {
        if (!(t < st_s1[l])) {
            break;
        }
        let p = og + dg * t;
        let lx = locate_axis(p.x, dims.x);
        let ly = locate_axis(p.y, dims.y);
        let lz = locate_axis(p.z, dims.z);
        let b = vec3<u32>(u32(lx.x), u32(ly.x), u32(lz.x));
        let f = vec3<f32>(lx.y, ly.y, lz.y);
        if (!brick_live(l, b)) {
            var size = BRICK * BLOCK;
            if (block_live(l, b)) {
                size = BRICK;
            }
            let bb = b / size;
            var t_exit = BIG;
            for (var a = 0u; a < 3u; a++) {
                if (dg[a] != 0.0) {
                    let inv = 1.0 / dg[a];
                    let lo = f32(bb[a] * size);
                    let hi = f32(min((bb[a] + 1u) * size, dims[a] - 1u));
                    var bound = lo;
                    if (inv > 0.0) {
                        bound = hi;
                    }
                    t_exit = min(t_exit, (bound - og[a]) * inv);
                }
            }
            let kf = ceil((t_exit - t0) / step_w);
            var kn = 0u;
            if (kf >= 4294967040.0) {
                kn = NONE;
            } else if (kf > 0.0) {
                kn = u32(kf);
            }
            ks = max(kn, ks + 1u);
            t = t0 + f32(ks) * step_w;
            continue;
        }
        ks += 1u;
        let t_next = t0 + f32(ks) * step_w;
        let kept = visit(l, b, f, t);
        t = t_next;
        if (kept) {
            st_t[l] = t;
            st_ks[l] = ks;
            if (!(st_trans[l] >= params.term_thresh)) {
                st_done[l] = 1u;
            }
            return true;
        }
    }
    st_done[l] = 1u;
    return false;
}

// space::ray_box and Marcher::line's set-up for layer l and the world direction d.
fn start(l: u32, d: vec3<f32>) {
    let L = &layers[l];
    let o = vec3<f32>((*L).ox, (*L).oy, (*L).oz);
    let r0 = vec3<f32>((*L).r0x, (*L).r0y, (*L).r0z);
    let r1 = vec3<f32>((*L).r1x, (*L).r1y, (*L).r1z);
    let r2 = vec3<f32>((*L).r2x, (*L).r2y, (*L).r2z);
    let dl = r0 * d.x + r1 * d.y + r2 * d.z;
    st_d[l] = dl;
    st_trans[l] = 1.0;
    st_done[l] = 1u;
    pend_ok[l] = 0u;
    weights[l] = 0.0;
    let lo = vec3<f32>((*L).lo_x, (*L).lo_y, (*L).lo_z);
    let hi = vec3<f32>((*L).hi_x, (*L).hi_y, (*L).hi_z);
    var tn = 0.0;
    var tf = BIG;
    for (var a = 0u; a < 3u; a++) {
        if (dl[a] == 0.0) {
            // 1 / 0 is infinite on the CPU: no constraint strictly inside the slab, a miss
            // otherwise (on its faces the NaNs fall the way of a miss).
            if (!(lo[a] < o[a] && o[a] < hi[a])) {
                return;
            }
        } else {
            let inv = 1.0 / dl[a];
            let ta = (lo[a] - o[a]) * inv;
            let tb = (hi[a] - o[a]) * inv;
            tn = max(tn, min(ta, tb));
            tf = min(tf, max(ta, tb));
        }
    }
    if (!(tf > tn)) {
        return;
    }
    let voxel = (*L).voxel;
    st_og[l] = (o - lo) / voxel;
    st_dg[l] = dl / voxel;
    st_t0[l] = tn + 0.5 * (*L).step_w;
    st_t[l] = st_t0[l];
    st_ks[l] = 0u;
    st_s1[l] = tf;
    st_done[l] = 0u;
    if ((*L).is_net == 1u) {
        basis = sh_basis((*L).sh_degree, dl);
        ray_bias(l);
    }
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let ray = gid.x + gid.y * groups.x * 64u;
    if (ray >= params.n_rays) {
        return;
    }
    let d = rays[ray].xyz;
    let n = params.n_layers;
    for (var l = 0u; l < n; l++) {
        start(l, d);
        advance(l);
    }
    var trans = 1.0;
    var rgb = vec3<f32>(0.0);
    var depth = 0.0;
    var t_half = -1.0;
    loop {
        var best = NONE;
        var best_t = 0.0;
        for (var l = 0u; l < n; l++) {
            if (pend_ok[l] == 1u && (best == NONE || pend_t[l] < best_t)) {
                best = l;
                best_t = pend_t[l];
            }
        }
        if (best == NONE) {
            break;
        }
        let L = &layers[best];
        let t = pend_t[best];
        let alpha = pend_alpha[best];
        var col = pend_rgb[best];
        if ((*L).recolour != 0u) {
            col = recolour(best, col);
        }
        let w = trans * alpha;
        rgb += w * col;
        depth += w * t;
        weights[best] += w;
        let next = trans * (1.0 - alpha);
        if (t_half < 0.0 && next <= 0.5) {
            t_half = t;
        }
        trans = next;
        if (trans < params.term_thresh) {
            break;
        }
        advance(best);
    }
    rgb += trans * vec3<f32>(params.bg_r, params.bg_g, params.bg_b);
    var bg_w = trans;
    for (var l = 0u; l < n; l++) {
        if (layers[l].index == 0u) {
            bg_w += weights[l];
        }
    }
    var index = 0u;
    var best_w = bg_w;
    for (var l = 0u; l < n; l++) {
        if (layers[l].index != 0u && weights[l] > best_w) {
            index = layers[l].index;
            best_w = weights[l];
        }
    }
    // A loop of n_layers + 1 (at least 2) iterations: a device that ended loops early (see the
    // note on loops above) ends this one after the first, and the ray is reported cut.
    var probe = 0u;
    for (var i = 0u; i <= n; i++) {
        probe += 1u;
    }
    var cut = 0u;
    if (probe != n + 1u) {
        cut = 1u;
    }
    outs[ray] = RayOut(rgb.x, rgb.y, rgb.z, 1.0 - trans, t_half, depth, index, cut);
}
