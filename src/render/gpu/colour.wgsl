// The colour of a sample and its recolouring, for `march.wgsl` (the shader is the two files
// in one module; their globals are declared there): `sh::sh_basis`, the SH colour, the colour
// network (`field::colour_net`) and `edit::recolour`, each mirroring the CPU code named beside it.

// sh::sh_basis.
fn sh_basis(degree: u32, d: vec3<f32>) -> array<f32, 16> {
    var o: array<f32, 16>;
    o[0] = 0.2820948;
    if (degree >= 1u) {
        o[1] = -0.4886025 * d.y;
        o[2] = 0.4886025 * d.z;
        o[3] = -0.4886025 * d.x;
    }
    if (degree >= 2u) {
        let x = d.x;
        let y = d.y;
        let z = d.z;
        o[4] = 1.0925484 * x * y;
        o[5] = -1.0925484 * y * z;
        o[6] = 0.31539157 * (2.0 * z * z - x * x - y * y);
        o[7] = -1.0925484 * x * z;
        o[8] = 0.5462742 * (x * x - y * y);
    }
    if (degree >= 3u) {
        let x = d.x;
        let y = d.y;
        let z = d.z;
        let xx = x * x;
        let yy = y * y;
        let zz = z * z;
        o[9] = -0.5900436 * y * (3.0 * xx - yy);
        o[10] = 2.8906114 * x * y * z;
        o[11] = -0.4570458 * y * (4.0 * zz - xx - yy);
        o[12] = 0.37317633 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
        o[13] = -0.4570458 * x * (4.0 * zz - xx - yy);
        o[14] = 1.4453057 * z * (xx - yy);
        o[15] = -0.5900436 * x * (xx - 3.0 * yy);
    }
    return o;
}

// The SH colour of one channel: sum_j feat[off + j] * basis[j] for j < k, in order.
fn sh_dot(off: u32, k: u32) -> f32 {
    var s = 0.0;
    for (var i = 0u; i < k; i += 4u) {
        for (var m = 0u; m < 4u; m++) {
            let j = i + m;
            if (j < k) {
                s += feat[off + j] * basis[j];
            }
        }
    }
    return s;
}

// colour_net::reflect.
fn reflect_about(d: vec3<f32>, g: vec3<f32>) -> vec3<f32> {
    let len2 = g.x * g.x + g.y * g.y + g.z * g.z;
    if (len2 < 1e-12) {
        return d;
    }
    let k = 2.0 * (d.x * g.x + d.y * g.y + d.z * g.z) / len2;
    return d - g * k;
}

// Loops and the budget of a software device: Mesa's llvmpipe (lavapipe) gives each SIMD batch of
// invocations 65535 loop iterations over all its loops together (LP_MAX_TGSI_LOOP_ITERATIONS)
// and then ends every loop early, silently. A network-coloured ray spent that in the hidden
// units' inner loops and stopped half-way (lego 50x50: alpha 0.15 where the CPU has 0.53). So
// the direction's part of the first layer is computed once a ray (`ray_bias`, as the CPU's
// ColourNet::ray_bias does), a sample's inner loops take 4 or 8 terms an iteration (a fixed
// inner count a compiler can unroll), and `main` reports a ray whose loops were ended (`cut`),
// which the renderer turns into an error rather than a wrong pixel.

// sum_i x[i] * vals[w + i * stride] for i < n (n <= 32), in the order of i, starting from `a`,
// where x is `feat` (which = 0), `basis` (1) or `refl` (2). Four terms an iteration.
fn input_terms(a0: f32, which: u32, n: u32, w: u32, stride: u32) -> f32 {
    var a = a0;
    for (var i = 0u; i < n; i += 4u) {
        for (var k = 0u; k < 4u; k++) {
            let j = i + k;
            if (j < n) {
                var x = feat[j];
                if (which == 1u) {
                    x = basis[j];
                } else if (which == 2u) {
                    x = refl[j];
                }
                a += x * vals[w + j * stride];
            }
        }
    }
    return a;
}

// colour_net's dot: 8 lanes over whole chunks, their sum, plus the tail, of n weights at
// vals[w] with h1 (which = 0) or h2.
fn dot8(w: u32, n: u32, which: u32) -> f32 {
    var acc: array<f32, 8>;
    let whole = (n / 8u) * 8u;
    for (var c = 0u; c < whole; c += 8u) {
        for (var i = 0u; i < 8u; i++) {
            var x = h1[c + i];
            if (which == 1u) {
                x = h2[c + i];
            }
            acc[i] += vals[w + c + i] * x;
        }
    }
    var tail = 0.0;
    for (var i = 0u; i < 7u; i++) {
        let j = whole + i;
        if (j < n) {
            var x = h1[j];
            if (which == 1u) {
                x = h2[j];
            }
            tail += vals[w + j] * x;
        }
    }
    var s = 0.0;
    for (var i = 0u; i < 8u; i++) {
        s += acc[i];
    }
    return s + tail;
}

// ColourNet::ray_bias of layer l for the direction's `basis`: b1 plus the direction rows.
fn ray_bias(l: u32) {
    let L = &layers[l];
    let nf = (*L).features;
    let nd = (*L).dir_terms;
    let nr = (*L).refl_terms;
    let nh = (*L).hidden;
    let w1 = (*L).net_off;
    let b1 = w1 + (nf + nd + nr) * nh;
    for (var j = 0u; j < nh; j++) {
        bias[l * MAX_HIDDEN + j] = input_terms(vals[b1 + j], 1u, nd, w1 + nf * nh + j, nh);
    }
}

// The second layer's unit j: bm[j] plus the active first-layer units' terms, in their order
// (ColourNet::forward_features adds unit i's row to every unit; the sums are the same).
fn second_unit(wm: u32, bm: u32, nh: u32, nh2: u32, j: u32) -> f32 {
    var a = vals[bm + j];
    for (var i = 0u; i < nh; i += 8u) {
        for (var k = 0u; k < 8u; k++) {
            let u = i + k;
            if (u < nh) {
                let x = h1[u];
                if (x > 0.0) {
                    a += x * vals[wm + u * nh2 + j];
                }
            }
        }
    }
    return max(a, 0.0);
}

// ColourNet::forward_features on `feat` (and `refl`) from the ray's `bias` of layer l.
fn net_rgb(l: u32) -> vec3<f32> {
    let L = &layers[l];
    let nf = (*L).features;
    let nd = (*L).dir_terms;
    let nr = (*L).refl_terms;
    let nh = (*L).hidden;
    let nh2 = (*L).hidden2;
    let w1 = (*L).net_off;
    let b1 = w1 + (nf + nd + nr) * nh;
    let wm = b1 + nh;
    let bm = wm + nh * nh2;
    var wo = bm + nh2;
    if (nh2 == 0u) {
        wo = b1 + nh;
    }
    for (var j = 0u; j < nh; j++) {
        let a = input_terms(bias[l * MAX_HIDDEN + j], 0u, nf, w1 + j, nh);
        h1[j] = max(input_terms(a, 2u, nr, w1 + (nf + nd) * nh + j, nh), 0.0);
    }
    var rgb: vec3<f32>;
    if (nh2 == 0u) {
        let bo = wo + 3u * nh;
        rgb.x = sigmoid(vals[bo] + dot8(wo, nh, 0u));
        rgb.y = sigmoid(vals[bo + 1u] + dot8(wo + nh, nh, 0u));
        rgb.z = sigmoid(vals[bo + 2u] + dot8(wo + 2u * nh, nh, 0u));
        return rgb;
    }
    for (var j = 0u; j < nh2; j++) {
        h2[j] = second_unit(wm, bm, nh, nh2, j);
    }
    let bo = wo + 3u * nh2;
    rgb.x = sigmoid(vals[bo] + dot8(wo, nh2, 1u));
    rgb.y = sigmoid(vals[bo + 1u] + dot8(wo + nh2, nh2, 1u));
    rgb.z = sigmoid(vals[bo + 2u] + dot8(wo + 2u * nh2, nh2, 1u));
    return rgb;
}

fn to_linear(c: f32) -> f32 {
    if (c <= 0.04045) {
        return c / 12.92;
    }
    return pow((c + 0.055) / 1.055, 2.4);
}

fn to_srgb(c: f32) -> f32 {
    if (c <= 0.0031308) {
        return 12.92 * c;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

fn cbrt(x: f32) -> f32 {
    if (x == 0.0) {
        return 0.0;
    }
    return sign(x) * pow(abs(x), 1.0 / 3.0);
}

// edit::recolour's OKLab conversions.
fn srgb_to_oklab(c: vec3<f32>) -> vec3<f32> {
    let r = to_linear(c.x);
    let g = to_linear(c.y);
    let b = to_linear(c.z);
    let l = cbrt(0.41222146 * r + 0.53633255 * g + 0.051445995 * b);
    let m = cbrt(0.2119035 * r + 0.6806995 * g + 0.10739696 * b);
    let s = cbrt(0.08830246 * r + 0.28171885 * g + 0.6299787 * b);
    return vec3<f32>(
        0.21045426 * l + 0.7936178 * m - 0.004072047 * s,
        1.9779985 * l - 2.4285922 * m + 0.4505937 * s,
        0.025904037 * l + 0.78277177 * m - 0.80867577 * s,
    );
}

fn oklab_to_linear(lab: vec3<f32>) -> vec3<f32> {
    let l0 = lab.x + 0.39633778 * lab.y + 0.21580376 * lab.z;
    let m0 = lab.x - 0.105561346 * lab.y - 0.06385417 * lab.z;
    let s0 = lab.x - 0.08948418 * lab.y - 1.2914855 * lab.z;
    let l = l0 * l0 * l0;
    let m = m0 * m0 * m0;
    let s = s0 * s0 * s0;
    return vec3<f32>(
        4.0767417 * l - 3.3077116 * m + 0.23096994 * s,
        -1.268438 * l + 2.6097574 * m - 0.34131938 * s,
        -0.0041960863 * l - 0.7034186 * m + 1.7076147 * s,
    );
}

fn in_gamut(c: vec3<f32>) -> bool {
    let e = 1e-5;
    return all(c >= vec3<f32>(-e)) && all(c <= vec3<f32>(1.0 + e));
}

fn oklab_to_srgb(lab: vec3<f32>) -> vec3<f32> {
    var lin = oklab_to_linear(lab);
    if (!in_gamut(lin)) {
        var lo = 0.0;
        var hi = 1.0;
        for (var i = 0; i < 12; i++) {
            let mid = 0.5 * (lo + hi);
            if (in_gamut(oklab_to_linear(vec3<f32>(lab.x, lab.y * mid, lab.z * mid)))) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        if (lo > 0.0) {
            lin = oklab_to_linear(vec3<f32>(lab.x, lab.y * lo, lab.z * lo));
        } else {
            lin = oklab_to_linear(vec3<f32>(clamp(lab.x, 0.0, 1.0), 0.0, 0.0));
        }
    }
    return vec3<f32>(
        to_srgb(clamp(lin.x, 0.0, 1.0)),
        to_srgb(clamp(lin.y, 0.0, 1.0)),
        to_srgb(clamp(lin.z, 0.0, 1.0)),
    );
}

// PreparedRecolour::apply.
fn recolour(l: u32, rgb: vec3<f32>) -> vec3<f32> {
    let L = &layers[l];
    let lab = srgb_to_oklab(rgb);
    var a: f32;
    var b: f32;
    if ((*L).recolour == 1u) {
        a = lab.y + (*L).rc2 * ((*L).rc0 - lab.y);
        b = lab.z + (*L).rc2 * ((*L).rc1 - lab.z);
    } else {
        let c = (*L).rc0;
        let s = (*L).rc1;
        a = c * lab.y - s * lab.z;
        b = s * lab.y + c * lab.z;
    }
    return oklab_to_srgb(vec3<f32>(lab.x, a, b));
}
