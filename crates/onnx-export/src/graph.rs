//! A small builder of ONNX graphs: values are named by the builder, every node has one
//! output, constants are initializers (deduplicated by content), and only operators whose
//! signature is the same from opset 13 to 17 are emitted (`ReduceSum` with its axes as an
//! input, `ReduceMax`/`ReduceMin` with theirs as an attribute, `Slice`, `Unsqueeze`, `Pad`
//! with inputs), so one graph serves both opsets the exporter writes.

use crate::proto::{self, Attr, DataType, GraphParts};
use std::collections::HashMap;

/// A value of the graph (its name).
pub type Value = String;

/// A graph under construction.
#[derive(Debug, Default)]
pub struct Graph {
    parts: GraphParts,
    counter: usize,
    constants: HashMap<(i32, Vec<usize>, Vec<u8>), Value>,
}

impl Graph {
    fn fresh(&mut self, hint: &str) -> Value {
        self.counter += 1;
        format!("{hint}_{}", self.counter)
    }

    /// Declares a graph input of element type `ty` and shape `[batch, dims..]`.
    pub fn input(&mut self, name: &str, ty: DataType, dims: &[usize]) -> Value {
        self.parts
            .inputs
            .push(proto::value_info(name, ty, Some("batch"), dims));
        name.to_owned()
    }

    /// Names `value` as graph output `name` (element type `ty`, shape `[batch, dims..]`).
    pub fn output(&mut self, name: &str, value: &str, ty: DataType, dims: &[usize]) {
        self.node("Identity", &[value], &[], Some(name));
        self.parts
            .outputs
            .push(proto::value_info(name, ty, Some("batch"), dims));
    }

    fn node(
        &mut self,
        op: &str,
        inputs: &[&str],
        attrs: &[(&str, Attr)],
        out: Option<&str>,
    ) -> Value {
        let out = out.map_or_else(|| self.fresh(op), str::to_owned);
        let name = format!("node_{}", self.parts.nodes.len());
        let inputs: Vec<String> = inputs.iter().map(|s| (*s).to_owned()).collect();
        self.parts.nodes.push(proto::node(
            &name,
            op,
            &inputs,
            std::slice::from_ref(&out),
            attrs,
        ));
        out
    }

    /// Node `op` on `inputs` with `attrs`: its one output.
    pub fn op(&mut self, op: &str, inputs: &[&str], attrs: &[(&str, Attr)]) -> Value {
        self.node(op, inputs, attrs, None)
    }

    fn constant(&mut self, ty: DataType, dims: &[usize], raw: Vec<u8>) -> Value {
        let key = (ty as i32, dims.to_vec(), raw);
        if let Some(v) = self.constants.get(&key) {
            return v.clone();
        }
        let name = self.fresh("const");
        self.parts
            .initializers
            .push(proto::tensor(&name, ty, dims, &key.2));
        self.constants.insert(key, name.clone());
        name
    }

    /// A constant f32 tensor.
    pub fn f32s(&mut self, dims: &[usize], data: &[f32]) -> Value {
        debug_assert_eq!(dims.iter().product::<usize>(), data.len());
        let raw = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.constant(DataType::Float, dims, raw)
    }

    /// A constant f64 tensor.
    pub fn f64s(&mut self, dims: &[usize], data: &[f64]) -> Value {
        debug_assert_eq!(dims.iter().product::<usize>(), data.len());
        let raw = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.constant(DataType::Double, dims, raw)
    }

    /// A constant i64 tensor (shapes, axes, indices).
    pub fn i64s(&mut self, data: &[i64]) -> Value {
        let raw = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.constant(DataType::Int64, &[data.len()], raw)
    }

    /// A constant i32 tensor.
    pub fn i32s(&mut self, data: &[i32]) -> Value {
        let raw = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.constant(DataType::Int32, &[data.len()], raw)
    }

    /// An f64 scalar (rank 0).
    pub fn scalar(&mut self, v: f64) -> Value {
        self.constant(DataType::Double, &[], v.to_le_bytes().to_vec())
    }

    /// `a + b` (broadcasting).
    pub fn add(&mut self, a: &str, b: &str) -> Value {
        self.op("Add", &[a, b], &[])
    }

    /// `a - b`.
    pub fn sub(&mut self, a: &str, b: &str) -> Value {
        self.op("Sub", &[a, b], &[])
    }

    /// `a * b`.
    pub fn mul(&mut self, a: &str, b: &str) -> Value {
        self.op("Mul", &[a, b], &[])
    }

    /// `a / b`.
    pub fn div(&mut self, a: &str, b: &str) -> Value {
        self.op("Div", &[a, b], &[])
    }

    /// Matrix product (numpy broadcasting over leading dimensions).
    pub fn matmul(&mut self, a: &str, b: &str) -> Value {
        self.op("MatMul", &[a, b], &[])
    }

    /// A one-input operator (`Abs`, `Sqrt`, `Exp`, ...).
    pub fn unary(&mut self, op: &str, a: &str) -> Value {
        self.op(op, &[a], &[])
    }

    /// Reorders dimensions.
    pub fn transpose(&mut self, a: &str, perm: &[i64]) -> Value {
        self.op("Transpose", &[a], &[("perm", Attr::Ints(perm.to_vec()))])
    }

    /// Reshapes (`0` keeps a dimension, `-1` infers one).
    pub fn reshape(&mut self, a: &str, shape: &[i64]) -> Value {
        let s = self.i64s(shape);
        self.op("Reshape", &[a, &s], &[])
    }

    /// `a[.., start..end, ..]` on `axis`.
    pub fn slice(&mut self, a: &str, axis: i64, start: usize, end: usize) -> Value {
        let (s, e, ax) = (
            self.i64s(&[start as i64]),
            self.i64s(&[end as i64]),
            self.i64s(&[axis]),
        );
        self.op("Slice", &[a, &s, &e, &ax], &[])
    }

    /// Concatenation on `axis`.
    pub fn concat(&mut self, axis: i64, parts: &[&str]) -> Value {
        self.op("Concat", parts, &[("axis", Attr::Int(axis))])
    }

    /// The entries `index` of `a` on `axis`.
    pub fn gather(&mut self, a: &str, axis: i64, index: &[i64]) -> Value {
        let i = self.i64s(index);
        self.op("Gather", &[a, &i], &[("axis", Attr::Int(axis))])
    }

    /// The entries `index` of `a` on `axis`, as slices of its consecutive runs (ONNX Runtime
    /// copies a slice far faster than it gathers on an inner axis).
    pub fn pick(&mut self, a: &str, axis: i64, index: &[usize]) -> Value {
        let mut runs: Vec<(usize, usize)> = Vec::new();
        for &i in index {
            match runs.last_mut() {
                Some((_, end)) if *end == i => *end += 1,
                _ => runs.push((i, i + 1)),
            }
        }
        let parts: Vec<Value> = runs
            .iter()
            .map(|&(s, e)| self.slice(a, axis, s, e))
            .collect();
        if parts.len() == 1 {
            return parts[0].clone();
        }
        let refs: Vec<&str> = parts.iter().map(String::as_str).collect();
        self.concat(axis, &refs)
    }

    /// Converts to element type `to`.
    pub fn cast(&mut self, a: &str, to: DataType) -> Value {
        self.op("Cast", &[a], &[("to", Attr::Int(to as i64))])
    }

    /// Inserts size-1 dimensions at `axes`.
    pub fn unsqueeze(&mut self, a: &str, axes: &[i64]) -> Value {
        let ax = self.i64s(axes);
        self.op("Unsqueeze", &[a, &ax], &[])
    }

    /// `ReduceMax`/`ReduceMin` over `axes` (attribute form, opsets 13-17).
    pub fn reduce(&mut self, op: &str, a: &str, axes: &[i64], keep: bool) -> Value {
        self.op(
            op,
            &[a],
            &[
                ("axes", Attr::Ints(axes.to_vec())),
                ("keepdims", Attr::Int(keep as i64)),
            ],
        )
    }

    /// `ReduceSum` over `axes` (input form, opset 13 on).
    pub fn reduce_sum(&mut self, a: &str, axes: &[i64], keep: bool) -> Value {
        let ax = self.i64s(axes);
        self.op(
            "ReduceSum",
            &[a, &ax],
            &[("keepdims", Attr::Int(keep as i64))],
        )
    }

    /// Zero padding of the last axis of a rank-3 tensor by `after` points.
    pub fn pad_last(&mut self, a: &str, after: usize) -> Value {
        let pads = self.i64s(&[0, 0, 0, 0, 0, after as i64]);
        self.op("Pad", &[a, &pads], &[])
    }

    /// The finished graph's parts.
    pub fn into_parts(self) -> GraphParts {
        self.parts
    }

    /// Number of nodes so far.
    pub fn len(&self) -> usize {
        self.parts.nodes.len()
    }

    /// Whether the graph has no node.
    pub fn is_empty(&self) -> bool {
        self.parts.nodes.is_empty()
    }
}

/// Encoded bytes of a finished graph: see [`proto::model`].
pub fn encode(
    graph: Graph,
    ir: i64,
    opset: i64,
    name: &str,
    doc: &str,
    metadata: &[(String, String)],
) -> Vec<u8> {
    let producer = ("pino-mbd", env!("CARGO_PKG_VERSION"));
    proto::model(ir, opset, producer, name, doc, graph.into_parts(), metadata)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_are_shared_by_content_and_values_are_unique() {
        let mut g = Graph::default();
        let a = g.scalar(2.0);
        let b = g.scalar(2.0);
        let c = g.scalar(3.0);
        assert_eq!(a, b);
        assert_ne!(a, c);
        let x = g.input("x", DataType::Double, &[3]);
        let y = g.mul(&x, &a);
        let z = g.mul(&x, &a);
        assert_ne!(y, z);
        g.output("y", &z, DataType::Double, &[3]);
        let parts = g.into_parts();
        assert_eq!(
            (
                parts.initializers.len(),
                parts.nodes.len(),
                parts.inputs.len()
            ),
            (2, 3, 1)
        );
    }
}
