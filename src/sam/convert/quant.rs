//! int8 layers for the quantised graphs: a Linear layer whose weight is quantised to 8 bits with
//! one scale per output channel, run by ONNX Runtime's `DynamicQuantizeMatMul` (the activations are
//! quantised to uint8 per call, from their own range, so no calibration data is needed).
//!
//! The weights are stored as uint8 with zero point 128 (the int8 value + 128), not as int8: with
//! uint8 activations and int8 weights, ONNX Runtime's x86 kernel on CPUs without VNNI (AVX2)
//! multiplies with `vpmaddubsw`, whose int16 sums of two products saturate, which ONNX Runtime's
//! quantisation guide names as the cause of accuracy drops and answers with the U8U8 format. On
//! this project's AVX2 machine the int8 weights gave the embeddings 4-6 % relative RMS error
//! against fp32 and uint8 weights 3-4 %, for 3-11 % more encoder time
//! (`examples/results/bench_sam.md`).

use super::graph::Graph;
use super::torch::Tensor;

/// Largest magnitude of a symmetric int8 weight (-127..=127: -128 is left out so that the range
/// is symmetric and 0.0 is exact).
const Q_MAX: f32 = 127.0;

/// A Linear weight (`out x in`, as PyTorch stores it) quantised per output channel, laid out as
/// MatMul's `in x out` right-hand side: the int8 values and the `out` scales.
pub fn quantize_per_column(w: &Tensor) -> (Vec<i8>, Vec<f32>) {
    let [out, inp] = w.shape[..] else {
        panic!("a Linear weight is a matrix, not {:?}", w.shape)
    };
    let scales: Vec<f32> = (0..out)
        .map(|o| {
            let m = w.data[o * inp..(o + 1) * inp]
                .iter()
                .fold(0f32, |m, v| m.max(v.abs()));
            if m > 0.0 {
                m / Q_MAX
            } else {
                1.0
            }
        })
        .collect();
    let mut q = vec![0i8; out * inp];
    for o in 0..out {
        for i in 0..inp {
            let v = (w.data[o * inp + i] / scales[o]).round();
            q[i * out + o] = v.clamp(-Q_MAX, Q_MAX) as i8;
        }
    }
    (q, scales)
}

/// The zero point of a weight stored as uint8: the int8 value + 128.
const U8_ZERO: u8 = 128;

/// `nn.Linear` on the last axis with an 8-bit weight (per output channel) and a uint8 activation
/// quantised on the fly: ONNX Runtime's `DynamicQuantizeMatMul`, the bias added in the same node.
/// `unsigned`: the weight as uint8 with zero point 128 (see the module's note), else as int8.
pub fn linear_int8(
    g: &mut Graph,
    x: &str,
    name: &str,
    w: &Tensor,
    b: &Tensor,
    unsigned: bool,
) -> String {
    let (q, scales) = quantize_per_column(w);
    let (out, inp) = (w.shape[0], w.shape[1]);
    let (wq, zero) = if unsigned {
        let u: Vec<u8> = q
            .iter()
            .map(|&v| (v as i16 + U8_ZERO as i16) as u8)
            .collect();
        let wq = g.weight_u8(&format!("{name}.weight_q"), &[inp, out], &u);
        let zero = g.weight_u8(&format!("{name}.weight_zero"), &[out], &vec![U8_ZERO; out]);
        (wq, zero)
    } else {
        let wq = g.weight_i8(&format!("{name}.weight_q"), &[inp, out], &q);
        (wq, String::new())
    };
    let ws = g.weight(
        &format!("{name}.weight_scale"),
        &Tensor::new(vec![out], scales),
    );
    let bias = g.weight(&format!("{name}.bias"), b);
    g.op_ms(
        "DynamicQuantizeMatMul",
        &[x, &wq, &ws, &zero, &bias],
        vec![],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_column_quantisation_round_trips_within_half_a_step() {
        // 2 outputs x 3 inputs; the second row is ten times larger and must get its own scale.
        let w = Tensor::new(vec![2, 3], vec![0.5, -1.0, 0.25, 5.0, -10.0, 2.5]);
        let (q, s) = quantize_per_column(&w);
        assert_eq!(s.len(), 2);
        assert!((s[0] - 1.0 / 127.0).abs() < 1e-9 && (s[1] - 10.0 / 127.0).abs() < 1e-9);
        // Laid out in x out: column 0 is output 0.
        assert_eq!(q, vec![64, 64, -127, -127, 32, 32]);
        for o in 0..2 {
            for i in 0..3 {
                let back = q[i * 2 + o] as f32 * s[o];
                assert!((back - w.data[o * 3 + i]).abs() <= s[o] / 2.0 + 1e-7);
            }
        }
    }

    #[test]
    fn an_all_zero_channel_gets_a_unit_scale() {
        let w = Tensor::new(vec![1, 2], vec![0.0, 0.0]);
        assert_eq!(quantize_per_column(&w), (vec![0, 0], vec![1.0]));
    }
}
