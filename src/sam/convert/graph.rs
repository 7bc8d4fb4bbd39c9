//! A small ONNX graph builder: nodes named by a scope path (like PyTorch's exporter, so a graph
//! reads like the model code), weights and constants as initializers (small constants shared),
//! and the layers MobileSAM is made of, written with the same operators the PyTorch exporter
//! emits, so ONNX Runtime fuses them the same way (GELU from Erf, LayerNormalization, MatMul+Add).

use super::onnx_proto::*;
use super::torch::Tensor;
use std::collections::HashMap;

/// The opset and IR version of the reference export.
pub const OPSET: i64 = 17;
pub const IR_VERSION: i64 = 8;
/// ONNX Runtime's own operators (e.g. `DynamicQuantizeMatMul`, `MultiHeadAttention`).
pub const MS_DOMAIN: &str = "com.microsoft";

/// An attribute value.
pub enum Attr {
    Int(i64),
    Ints(Vec<i64>),
    Float(f32),
    Str(&'static str),
}

/// A convolution's stride, padding (all sides) and groups.
#[derive(Clone, Copy)]
pub struct Conv {
    pub stride: i64,
    pub pad: i64,
    pub groups: i64,
}

/// A tensor dimension of a graph input or output.
#[derive(Clone)]
pub enum Dim {
    Fixed(i64),
    Named(&'static str),
}

#[derive(Default)]
pub struct Graph {
    nodes: Vec<NodeProto>,
    inits: Vec<TensorProto>,
    inputs: Vec<ValueInfoProto>,
    outputs: Vec<ValueInfoProto>,
    /// Constants by (type, dims, value bits), so each distinct constant is stored once.
    consts: HashMap<(i32, Vec<i64>, Vec<u8>), String>,
    /// Node counts per scope and operator, for unique names.
    counts: HashMap<String, usize>,
    scope: String,
    /// Whether any node is one of ONNX Runtime's own operators (then the model imports its domain).
    uses_ms_domain: bool,
}

impl Graph {
    pub fn new() -> Self {
        Self::default()
    }

    /// Run `f` with `name` appended to the node-name scope.
    pub fn scope<T>(&mut self, name: &str, f: impl FnOnce(&mut Self) -> T) -> T {
        let prev = self.scope.clone();
        self.scope = format!("{prev}/{name}");
        let r = f(self);
        self.scope = prev;
        r
    }

    pub fn input(&mut self, name: &str, elem: i32, dims: &[Dim]) -> String {
        self.inputs.push(value_info(name, elem, dims));
        name.to_string()
    }

    /// Mark `value` as the graph output `name` (through an Identity when the names differ).
    pub fn output(&mut self, value: &str, name: &str, elem: i32, dims: &[Dim]) {
        if value != name {
            self.nodes.push(NodeProto {
                input: vec![value.into()],
                output: vec![name.into()],
                name: format!("{}/Identity_{name}", self.scope),
                op_type: "Identity".into(),
                attribute: vec![],
                domain: String::new(),
            });
        }
        self.outputs.push(value_info(name, elem, dims));
    }

    /// A named float initializer (a weight).
    pub fn weight(&mut self, name: &str, t: &Tensor) -> String {
        self.inits.push(TensorProto {
            dims: t.shape.iter().map(|&d| d as i64).collect(),
            data_type: FLOAT,
            name: name.into(),
            raw_data: t.data.iter().flat_map(|v| v.to_le_bytes()).collect(),
        });
        name.to_string()
    }

    /// A named int8 initializer (a quantised weight).
    pub fn weight_i8(&mut self, name: &str, dims: &[usize], vals: &[i8]) -> String {
        self.inits.push(TensorProto {
            dims: dims.iter().map(|&d| d as i64).collect(),
            data_type: INT8,
            name: name.into(),
            raw_data: vals.iter().map(|&v| v as u8).collect(),
        });
        name.to_string()
    }

    /// A named uint8 initializer (a quantised weight or its zero points).
    pub fn weight_u8(&mut self, name: &str, dims: &[usize], vals: &[u8]) -> String {
        self.inits.push(TensorProto {
            dims: dims.iter().map(|&d| d as i64).collect(),
            data_type: UINT8,
            name: name.into(),
            raw_data: vals.to_vec(),
        });
        name.to_string()
    }

    /// A float constant of the given shape (shared with equal ones).
    pub fn f32s(&mut self, dims: &[i64], vals: &[f32]) -> String {
        let raw = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.constant(FLOAT, dims, raw)
    }
    /// A float scalar constant.
    pub fn scalar(&mut self, v: f32) -> String {
        self.f32s(&[], &[v])
    }
    /// A 1-D int64 constant (shapes, axes, pads).
    pub fn i64s(&mut self, vals: &[i64]) -> String {
        let raw = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.constant(INT64, &[vals.len() as i64], raw)
    }

    /// An int64 scalar constant (a Gather index).
    pub fn i64_scalar(&mut self, v: i64) -> String {
        self.constant(INT64, &[], v.to_le_bytes().to_vec())
    }

    fn constant(&mut self, ty: i32, dims: &[i64], raw: Vec<u8>) -> String {
        let key = (ty, dims.to_vec(), raw);
        if let Some(n) = self.consts.get(&key) {
            return n.clone();
        }
        let name = format!("const_{}", self.consts.len());
        self.inits.push(TensorProto {
            dims: key.1.clone(),
            data_type: ty,
            name: name.clone(),
            raw_data: key.2.clone(),
        });
        self.consts.insert(key, name.clone());
        name
    }

    /// One node with one output; returns the output's name.
    pub fn op(&mut self, op: &str, inputs: &[&str], attrs: Vec<(&str, Attr)>) -> String {
        self.op_n(op, inputs, 1, attrs).remove(0)
    }

    /// One node of ONNX Runtime's own operators ([`MS_DOMAIN`]) with one output.
    pub fn op_ms(&mut self, op: &str, inputs: &[&str], attrs: Vec<(&str, Attr)>) -> String {
        let out = self.op_n(op, inputs, 1, attrs).remove(0);
        if let Some(node) = self.nodes.last_mut() {
            node.domain = MS_DOMAIN.into();
        }
        self.uses_ms_domain = true;
        out
    }

    /// One node with `n` outputs.
    pub fn op_n(
        &mut self,
        op: &str,
        inputs: &[&str],
        n: usize,
        attrs: Vec<(&str, Attr)>,
    ) -> Vec<String> {
        let key = format!("{}/{op}", self.scope);
        let k = self.counts.entry(key.clone()).or_insert(0);
        let name = if *k == 0 { key } else { format!("{key}_{k}") };
        *k += 1;
        let outputs: Vec<String> = (0..n).map(|i| format!("{name}_output_{i}")).collect();
        self.nodes.push(NodeProto {
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: outputs.clone(),
            name,
            op_type: op.into(),
            attribute: attrs.into_iter().map(|(n, a)| attribute(n, a)).collect(),
            domain: String::new(),
        });
        outputs
    }

    pub fn into_model(self, name: &str, doc: &str) -> ModelProto {
        let mut opset_import = vec![OperatorSetIdProto {
            domain: String::new(),
            version: OPSET,
        }];
        if self.uses_ms_domain {
            opset_import.push(OperatorSetIdProto {
                domain: MS_DOMAIN.into(),
                version: 1,
            });
        }
        ModelProto {
            ir_version: IR_VERSION,
            opset_import,
            producer_name: "objnerf".into(),
            producer_version: env!("CARGO_PKG_VERSION").into(),
            doc_string: doc.into(),
            graph: Some(GraphProto {
                node: self.nodes,
                name: name.into(),
                initializer: self.inits,
                input: self.inputs,
                output: self.outputs,
            }),
        }
    }

    // ---- layers ----

    pub fn add(&mut self, a: &str, b: &str) -> String {
        self.op("Add", &[a, b], vec![])
    }
    pub fn mul(&mut self, a: &str, b: &str) -> String {
        self.op("Mul", &[a, b], vec![])
    }
    pub fn reshape(&mut self, x: &str, shape: &[i64]) -> String {
        let s = self.i64s(shape);
        self.op("Reshape", &[x, &s], vec![])
    }
    pub fn transpose(&mut self, x: &str, perm: &[i64]) -> String {
        self.op("Transpose", &[x], vec![("perm", Attr::Ints(perm.to_vec()))])
    }
    pub fn matmul(&mut self, a: &str, b: &str) -> String {
        self.op("MatMul", &[a, b], vec![])
    }
    pub fn relu(&mut self, x: &str) -> String {
        self.op("Relu", &[x], vec![])
    }

    /// Exact GELU as PyTorch exports it: x * (1 + erf(x / sqrt 2)) * 0.5.
    pub fn gelu(&mut self, x: &str) -> String {
        let sqrt2 = self.scalar(std::f32::consts::SQRT_2);
        let one = self.scalar(1.0);
        let half = self.scalar(0.5);
        let d = self.op("Div", &[x, &sqrt2], vec![]);
        let e = self.op("Erf", &[&d], vec![]);
        let a = self.add(&e, &one);
        let m = self.mul(x, &a);
        self.mul(&m, &half)
    }

    /// `nn.Linear` on the last axis: MatMul with the transposed weight, then the bias.
    pub fn linear(&mut self, x: &str, name: &str, w: &Tensor, b: &Tensor) -> String {
        let wt = self.weight(&format!("{name}.weight_t"), &w.t());
        let bias = self.weight(&format!("{name}.bias"), b);
        let mm = self.matmul(x, &wt);
        self.add(&bias, &mm)
    }

    /// `nn.Linear` on a matrix: Gemm with the weight as stored (transB).
    pub fn gemm(&mut self, x: &str, name: &str, w: &Tensor, b: &Tensor) -> String {
        let wn = self.weight(&format!("{name}.weight"), w);
        let bn = self.weight(&format!("{name}.bias"), b);
        self.op(
            "Gemm",
            &[x, &wn, &bn],
            vec![
                ("alpha", Attr::Float(1.0)),
                ("beta", Attr::Float(1.0)),
                ("transB", Attr::Int(1)),
            ],
        )
    }

    /// `nn.LayerNorm` over the last axis.
    pub fn layer_norm(&mut self, x: &str, name: &str, w: &Tensor, b: &Tensor, eps: f32) -> String {
        let wn = self.weight(&format!("{name}.weight"), w);
        let bn = self.weight(&format!("{name}.bias"), b);
        self.op(
            "LayerNormalization",
            &[x, &wn, &bn],
            vec![("axis", Attr::Int(-1)), ("epsilon", Attr::Float(eps))],
        )
    }

    /// SAM's `LayerNorm2d` over the channels of NCHW, op for op as exported (mean, centred
    /// square mean, sqrt, divide, per-channel affine).
    pub fn layer_norm_2d(&mut self, x: &str, name: &str, w: &Tensor, b: &Tensor) -> String {
        let c = w.len();
        let wn = self.weight(&format!("{name}.weight"), &w.reshape(&[c, 1, 1]));
        let bn = self.weight(&format!("{name}.bias"), &b.reshape(&[c, 1, 1]));
        let two = self.scalar(2.0);
        let eps = self.scalar(1e-6);
        let mean_attrs = || vec![("axes", Attr::Ints(vec![1])), ("keepdims", Attr::Int(1))];
        let u = self.op("ReduceMean", &[x], mean_attrs());
        let d = self.op("Sub", &[x, &u], vec![]);
        let p = self.op("Pow", &[&d, &two], vec![]);
        let s = self.op("ReduceMean", &[&p], mean_attrs());
        let se = self.add(&s, &eps);
        let r = self.op("Sqrt", &[&se], vec![]);
        let n = self.op("Div", &[&d, &r], vec![]);
        let m = self.mul(&wn, &n);
        self.add(&m, &bn)
    }

    /// A 2-D convolution (square kernel from the weight's shape).
    pub fn conv(
        &mut self,
        x: &str,
        name: &str,
        w: &Tensor,
        b: Option<&Tensor>,
        Conv {
            stride,
            pad,
            groups,
        }: Conv,
    ) -> String {
        let k = w.shape[2] as i64;
        let wn = self.weight(&format!("{name}.weight"), w);
        let mut inputs = vec![x.to_string(), wn];
        if let Some(b) = b {
            inputs.push(self.weight(&format!("{name}.bias"), b));
        }
        let refs: Vec<&str> = inputs.iter().map(String::as_str).collect();
        self.op(
            "Conv",
            &refs,
            vec![
                ("dilations", Attr::Ints(vec![1, 1])),
                ("group", Attr::Int(groups)),
                ("kernel_shape", Attr::Ints(vec![k, k])),
                ("pads", Attr::Ints(vec![pad; 4])),
                ("strides", Attr::Ints(vec![stride, stride])),
            ],
        )
    }
}

fn attribute(name: &str, a: Attr) -> AttributeProto {
    let mut p = AttributeProto {
        name: name.into(),
        ..Default::default()
    };
    match a {
        Attr::Int(i) => {
            p.r#type = ATTR_INT;
            p.i = i;
        }
        Attr::Ints(v) => {
            p.r#type = ATTR_INTS;
            p.ints = v;
        }
        Attr::Float(f) => {
            p.r#type = ATTR_FLOAT;
            p.f = f;
        }
        Attr::Str(s) => {
            p.r#type = ATTR_STRING;
            p.s = s.as_bytes().to_vec();
        }
    }
    p
}

fn value_info(name: &str, elem: i32, dims: &[Dim]) -> ValueInfoProto {
    ValueInfoProto {
        name: name.into(),
        r#type: Some(TypeProto {
            tensor_type: Some(TensorTypeProto {
                elem_type: elem,
                shape: Some(TensorShapeProto {
                    dim: dims
                        .iter()
                        .map(|d| Dimension {
                            value: Some(match d {
                                Dim::Fixed(v) => DimValue::Value(*v),
                                Dim::Named(s) => DimValue::Param(s.to_string()),
                            }),
                        })
                        .collect(),
                }),
            }),
        }),
    }
}
