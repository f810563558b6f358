//! The ONNX protobuf messages this exporter writes, encoded by hand.
//!
//! Protocol buffers' wire format (varints, tag = field number << 3 | wire type; wire type 0 a
//! varint, 1 eight bytes, 2 a length-delimited byte string, 5 four bytes) and the field numbers
//! of `onnx.proto` (ONNX IR version 7 and 8) for the subset a graph of fixed-shape dense
//! tensors needs: `ModelProto`, `OperatorSetIdProto`, `StringStringEntryProto`, `GraphProto`,
//! `NodeProto`, `AttributeProto`, `TensorProto` (data in `raw_data`, little-endian),
//! `ValueInfoProto`, `TypeProto.Tensor` and `TensorShapeProto`. Nothing is read back: ONNX
//! Runtime is the reader the tests check against (`tests/interop`).

/// Element types (`TensorProto.DataType`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataType {
    /// 32-bit float.
    Float = 1,
    /// 32-bit signed integer.
    Int32 = 6,
    /// 64-bit signed integer.
    Int64 = 7,
    /// Boolean (one byte).
    Bool = 9,
    /// 64-bit float.
    Double = 11,
}

/// A protobuf message under construction.
#[derive(Debug, Default, Clone)]
pub struct Writer {
    buf: Vec<u8>,
}

impl Writer {
    /// The encoded bytes.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.buf.push((v as u8 & 0x7f) | 0x80);
            v >>= 7;
        }
        self.buf.push(v as u8);
    }

    fn tag(&mut self, field: u32, wire: u8) {
        self.varint(((field as u64) << 3) | wire as u64);
    }

    /// An integer field (`int32`, `int64`, an enum): a varint, negative values as 10 bytes.
    pub fn int(&mut self, field: u32, v: i64) {
        self.tag(field, 0);
        self.varint(v as u64);
    }

    /// A `float` field (four bytes).
    pub fn float(&mut self, field: u32, v: f32) {
        self.tag(field, 5);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `bytes` or `string` field.
    pub fn bytes(&mut self, field: u32, v: &[u8]) {
        self.tag(field, 2);
        self.varint(v.len() as u64);
        self.buf.extend_from_slice(v);
    }

    /// A `string` field.
    pub fn string(&mut self, field: u32, v: &str) {
        self.bytes(field, v.as_bytes());
    }

    /// An embedded message field.
    pub fn message(&mut self, field: u32, m: Writer) {
        self.bytes(field, &m.buf);
    }

    /// A packed repeated `int64` field.
    pub fn packed_ints(&mut self, field: u32, v: &[i64]) {
        let mut inner = Writer::default();
        for &x in v {
            inner.varint(x as u64);
        }
        self.bytes(field, &inner.buf);
    }
}

/// `TensorShapeProto` of fixed dimensions.
fn shape(dims: &[usize]) -> Writer {
    let mut w = Writer::default();
    for &d in dims {
        let mut dim = Writer::default();
        dim.int(1, d as i64); // dim_value
        w.message(1, dim);
    }
    w
}

/// A graph input or output: `ValueInfoProto` of a tensor of `ty` with a fixed shape, where a
/// leading `None` dimension is symbolic (`dim_param`, the batch).
pub fn value_info(name: &str, ty: DataType, batch: Option<&str>, dims: &[usize]) -> Writer {
    let mut s = Writer::default();
    if let Some(b) = batch {
        let mut dim = Writer::default();
        dim.string(2, b); // dim_param
        s.message(1, dim);
    }
    let fixed = shape(dims).into_bytes();
    s.buf.extend_from_slice(&fixed);
    let mut tensor = Writer::default();
    tensor.int(1, ty as i64); // elem_type
    tensor.message(2, s); // shape
    let mut t = Writer::default();
    t.message(1, tensor); // tensor_type
    let mut v = Writer::default();
    v.string(1, name);
    v.message(2, t);
    v
}

/// `TensorProto` named `name` of element type `ty`, dimensions `dims` and little-endian data
/// `raw` (in `raw_data`).
pub fn tensor(name: &str, ty: DataType, dims: &[usize], raw: &[u8]) -> Writer {
    let mut t = Writer::default();
    t.packed_ints(1, &dims.iter().map(|&d| d as i64).collect::<Vec<_>>());
    t.int(2, ty as i64);
    t.string(8, name);
    t.bytes(9, raw);
    t
}

/// An attribute value (`AttributeProto`).
#[derive(Debug, Clone, PartialEq)]
pub enum Attr {
    /// `INT` (type 2).
    Int(i64),
    /// `FLOAT` (type 1).
    Float(f32),
    /// `INTS` (type 7).
    Ints(Vec<i64>),
}

fn attribute(name: &str, a: &Attr) -> Writer {
    let mut w = Writer::default();
    w.string(1, name);
    match a {
        Attr::Float(f) => {
            w.float(2, *f);
            w.int(20, 1);
        }
        Attr::Int(i) => {
            w.int(3, *i);
            w.int(20, 2);
        }
        Attr::Ints(v) => {
            // Repeated scalars of an attribute are written unpacked, as onnx writes them.
            for &i in v {
                w.int(8, i);
            }
            w.int(20, 7);
        }
    }
    w
}

/// `NodeProto`: `op` of the default domain with `inputs`, `outputs` and `attributes`.
pub fn node(
    name: &str,
    op: &str,
    inputs: &[String],
    outputs: &[String],
    attributes: &[(&str, Attr)],
) -> Writer {
    let mut w = Writer::default();
    for i in inputs {
        w.string(1, i);
    }
    for o in outputs {
        w.string(2, o);
    }
    w.string(3, name);
    w.string(4, op);
    for (n, a) in attributes {
        w.message(5, attribute(n, a));
    }
    w
}

/// The parts of a `GraphProto`, each already encoded.
#[derive(Debug, Default)]
pub struct GraphParts {
    /// Nodes in topological order.
    pub nodes: Vec<Writer>,
    /// Constant tensors.
    pub initializers: Vec<Writer>,
    /// Inputs.
    pub inputs: Vec<Writer>,
    /// Outputs.
    pub outputs: Vec<Writer>,
}

/// `ModelProto` of one graph `name` (`doc` its description) at IR version `ir` with the default
/// domain at `opset`, produced by `producer` and carrying `metadata` as `metadata_props`.
pub fn model(
    ir: i64,
    opset: i64,
    producer: (&str, &str),
    name: &str,
    doc: &str,
    graph: GraphParts,
    metadata: &[(String, String)],
) -> Vec<u8> {
    let mut g = Writer::default();
    for n in graph.nodes {
        g.message(1, n);
    }
    g.string(2, name);
    for t in graph.initializers {
        g.message(5, t);
    }
    g.string(10, doc);
    for i in graph.inputs {
        g.message(11, i);
    }
    for o in graph.outputs {
        g.message(12, o);
    }
    let mut m = Writer::default();
    m.int(1, ir);
    m.string(2, producer.0);
    m.string(3, producer.1);
    m.string(6, doc);
    m.message(7, g);
    let mut op = Writer::default();
    op.string(1, "");
    op.int(2, opset);
    m.message(8, op);
    for (k, v) in metadata {
        let mut e = Writer::default();
        e.string(1, k);
        e.string(2, v);
        m.message(14, e);
    }
    m.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wire format's own examples: 150 as the varint `96 01`, the string "testing" in
    /// field 2 as `12 07 74 65 73 74 69 6e 67`, -1 as ten bytes, a float in four.
    #[test]
    fn the_wire_format_matches_the_protobuf_encoding_examples() {
        let mut w = Writer::default();
        w.int(1, 150);
        assert_eq!(w.clone().into_bytes(), [0x08, 0x96, 0x01]);
        let mut s = Writer::default();
        s.string(2, "testing");
        assert_eq!(
            s.into_bytes(),
            [0x12, 0x07, 0x74, 0x65, 0x73, 0x74, 0x69, 0x6e, 0x67]
        );
        let mut n = Writer::default();
        n.int(3, -1);
        let b = n.into_bytes();
        assert_eq!(b.len(), 11);
        assert_eq!((b[0], b[10]), (0x18, 0x01));
        let mut f = Writer::default();
        f.float(2, 1.0);
        assert_eq!(f.into_bytes(), [0x15, 0x00, 0x00, 0x80, 0x3f]);
        let mut p = Writer::default();
        p.packed_ints(1, &[3, 270]);
        assert_eq!(p.into_bytes(), [0x0a, 0x03, 0x03, 0x8e, 0x02]);
    }

    /// A tensor's fields in `onnx.proto`'s numbering: dims (1, packed), data_type (2), name
    /// (8), raw_data (9).
    #[test]
    fn a_tensor_is_dims_type_name_and_raw_data() {
        let t = tensor("w", DataType::Float, &[2], &[0, 0, 128, 63, 0, 0, 0, 64]).into_bytes();
        let want = [
            0x0a, 0x01, 0x02, // dims [2]
            0x10, 0x01, // FLOAT
            0x42, 0x01, b'w', // name
            0x4a, 0x08, 0, 0, 128, 63, 0, 0, 0, 64, // raw_data
        ];
        assert_eq!(t, want);
    }
}
