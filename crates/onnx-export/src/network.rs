//! The Fourier neural operator of `pino_learn::model` as graph nodes, with the product's
//! input normalisation in front of it.
//!
//! Activations are channel-major per design, `[B, C, T]`: a pointwise layer is `MatMul(W^T,
//! x) + b`, and the spectral convolution reads every row `(b, c)` along time. Two forms of the
//! spectral convolution (`docs/export.md`):
//! - [`Spectral::Matmul`] (opset 13): the truncated DFT as the product with the same fixed
//!   bases `pino_learn::spectral::Dft` builds for its matrix form, `[T_p, 2M]` and `[2M, T_p]`;
//! - [`Spectral::Dft`] (opset 17): the `DFT` operator, one-sided forward transform of the real
//!   rows and inverse transform of the kept modes (weights 1 for mode 0, 2 above, so the real
//!   part of the inverse is the synthesis).
//!
//! The inputs are normalised as `predict` does it: in double precision, `(x - mean) / std`,
//! then rounded to single precision; the network runs in single precision.

use crate::graph::{Graph, Value};
use crate::proto::{Attr, DataType};
use crate::{Error, Result};
use pino_learn::checkpoint::ModelMeta;
use pino_learn::config::ModelConfig;
use std::collections::HashMap;
use std::f64::consts::PI;

/// How the spectral layers are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spectral {
    /// Fixed truncated-DFT bases and matrix products (opset 13, every runtime).
    Matmul,
    /// The `DFT` operator (opset 17).
    Dft,
}

impl Spectral {
    /// The operator set the form needs.
    pub fn opset(self) -> i64 {
        match self {
            Spectral::Matmul => 13,
            Spectral::Dft => 17,
        }
    }

    /// The ONNX IR version of that operator set.
    pub fn ir_version(self) -> i64 {
        match self {
            Spectral::Matmul => 7,
            Spectral::Dft => 8,
        }
    }

    /// Its name in parameters and metadata.
    pub fn as_str(self) -> &'static str {
        match self {
            Spectral::Matmul => "matmul",
            Spectral::Dft => "dft",
        }
    }

    /// The form named `s`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "matmul" => Ok(Spectral::Matmul),
            "dft" => Ok(Spectral::Dft),
            other => Err(Error::Unsupported(format!(
                "spectral form `{other}`: allowed `matmul` (opset 13) or `dft` (opset 17)"
            ))),
        }
    }
}

/// A model's parameters by name, f32, with their shapes.
pub type Weights = HashMap<String, (Vec<usize>, Vec<f32>)>;

/// The network of one model in a graph.
pub struct Network<'a> {
    /// The model's metadata (sizes, statistics, grid, layout).
    pub meta: &'a ModelMeta,
    /// Its parameters.
    pub weights: &'a Weights,
    /// The spectral form.
    pub spectral: Spectral,
}

impl Network<'_> {
    fn config(&self) -> &ModelConfig {
        &self.meta.model
    }

    fn weight(&self, name: &str) -> Result<&(Vec<usize>, Vec<f32>)> {
        self.weights
            .get(name)
            .ok_or_else(|| Error::Unsupported(format!("the model has no tensor `{name}`")))
    }

    /// `W^T` of a stored `[in, out]` weight as a `[out, in]` constant.
    fn transposed(&self, g: &mut Graph, name: &str) -> Result<Value> {
        let (shape, w) = self.weight(name)?;
        let (i, o) = (shape[0], shape[1]);
        let mut t = vec![0.0f32; w.len()];
        for r in 0..i {
            for c in 0..o {
                t[c * i + r] = w[r * o + c];
            }
        }
        Ok(g.f32s(&[o, i], &t))
    }

    /// `act(W^T x + b [+ extra])` of channel-major `x [B, in, N]`.
    fn pointwise(
        &self,
        g: &mut Graph,
        x: &str,
        prefix: &str,
        extra: Option<&str>,
        gelu: bool,
    ) -> Result<Value> {
        let w = self.transposed(g, &format!("{prefix}.weight"))?;
        let (shape, b) = self.weight(&format!("{prefix}.bias"))?;
        let bias = g.f32s(&[shape[0], 1], b);
        let mut z = g.matmul(&w, x);
        if let Some(e) = extra {
            z = g.add(e, &z);
        }
        let z = g.add(&z, &bias);
        Ok(if gelu { gelu_of(g, &z) } else { z })
    }

    /// The normalised network input `[B, T, 1 + E + P]` (f32) of the graph inputs `eta [B, T,
    /// E]` and `params [B, P]` (f64, physical units).
    pub fn input(&self, g: &mut Graph, eta: &str, params: &str) -> Value {
        let stats = &self.meta.norm.inputs;
        let t_points = self.meta.grid.t_points;
        let ranges = self.meta.layout.input_ranges();
        let time: Vec<f32> = self
            .meta
            .grid
            .times()
            .iter()
            .map(|t| ((t - stats.mean[0]) / stats.std[0]) as f32)
            .collect();
        let time = g.f32s(&[1, t_points, 1], &time);
        let normalise = |g: &mut Graph, x: &str, r: std::ops::Range<usize>, dims: &[usize]| {
            let mean = g.f64s(dims, &stats.mean[r.clone()]);
            let std = g.f64s(dims, &stats.std[r]);
            let centred = g.sub(x, &mean);
            let z = g.div(&centred, &std);
            g.cast(&z, DataType::Float)
        };
        let e = ranges.excitations.len();
        let p = ranges.params.len();
        let eta_n = normalise(g, eta, ranges.excitations, &[e]);
        let p_n = normalise(g, params, ranges.params, &[p]);
        let p_n = g.unsqueeze(&p_n, &[1]);
        // The batch size, from the parameters' shape, for the broadcasts over it.
        let shape = g.op("Shape", &[params], &[]);
        let batch = g.slice(&shape, 0, 0, 1);
        let rest = g.i64s(&[t_points as i64, 1]);
        let tb = g.concat(0, &[&batch, &rest]);
        let time = g.op("Expand", &[&time, &tb], &[]);
        let along = g.i64s(&[1, t_points as i64, 1]);
        let p_n = g.op("Expand", &[&p_n, &along], &[]);
        g.concat(2, &[&time, &eta_n, &p_n])
    }

    /// The z-scored outputs `[B, T, O]` (f32) of the network input `x [B, T, C_in]`.
    pub fn forward(&self, g: &mut Graph, x: &str) -> Result<Value> {
        let c = *self.config();
        let t = self.meta.grid.t_points;
        let t_pad = c.padded_points(t);
        let x = g.transpose(x, &[0, 2, 1]);
        let mut v = self.pointwise(g, &x, "lift", None, false)?;
        if t_pad > t {
            v = g.pad_last(&v, t_pad - t);
        }
        let bases = match self.spectral {
            Spectral::Matmul => Some(bases(g, t_pad, c.modes)),
            Spectral::Dft => None,
        };
        for l in 0..c.depth {
            let prefix = format!("layers.{l}");
            let k = self.spectral_conv(g, &v, &prefix, bases.as_ref(), t_pad)?;
            v = self.pointwise(g, &v, &prefix, Some(&k), l + 1 < c.depth)?;
        }
        if t_pad > t {
            v = g.slice(&v, 2, 0, t);
        }
        let h = self.pointwise(g, &v, "proj1", None, true)?;
        let u = self.pointwise(g, &h, "proj2", None, false)?;
        Ok(g.transpose(&u, &[0, 2, 1]))
    }

    /// `K v` of `v [B, W, T_p]`: analysis, complex mode mixing, synthesis.
    fn spectral_conv(
        &self,
        g: &mut Graph,
        v: &str,
        prefix: &str,
        bases: Option<&(Value, Value)>,
        t_pad: usize,
    ) -> Result<Value> {
        let (m, w) = (self.config().modes, self.config().width);
        let mix = self.mixing(g, prefix)?;
        let xm = match bases {
            Some((fwd, _)) => {
                let spec = g.matmul(v, fwd); // [B, W, 2M]: Re 0..M, Im 0..M
                let parts = g.reshape(&spec, &[0, w as i64, 2, m as i64]);
                g.transpose(&parts, &[3, 0, 2, 1]) // [M, B, 2, W]
            }
            None => {
                let rows = g.reshape(v, &[-1, t_pad as i64, 1]);
                let spec = g.op(
                    "DFT",
                    &[&rows],
                    &[("axis", Attr::Int(1)), ("onesided", Attr::Int(1))],
                ); // [B W, T_p/2 + 1, 2]
                let kept = g.slice(&spec, 1, 0, m);
                let parts = g.reshape(&kept, &[-1, w as i64, m as i64, 2]);
                g.transpose(&parts, &[2, 0, 3, 1]) // [M, B, 2, W]
            }
        };
        let xm = g.reshape(&xm, &[m as i64, -1, 2 * w as i64]);
        let y = g.matmul(&xm, &mix); // [M, B, 2W']
        let y = g.reshape(&y, &[m as i64, -1, 2, w as i64]);
        Ok(match bases {
            Some((_, inv)) => {
                let y = g.transpose(&y, &[1, 3, 2, 0]); // [B, W', 2, M]
                let y = g.reshape(&y, &[0, w as i64, 2 * m as i64]);
                g.matmul(&y, inv)
            }
            None => {
                let y = g.transpose(&y, &[1, 3, 0, 2]); // [B, W', M, 2]
                let weights: Vec<f32> = (0..m).map(|k| if k == 0 { 1.0 } else { 2.0 }).collect();
                let weights = g.f32s(&[m, 1], &weights);
                let y = g.mul(&y, &weights);
                let pads = g.i64s(&[0, 0, 0, 0, 0, 0, (t_pad - m) as i64, 0]);
                let full = g.op("Pad", &[&y, &pads], &[]);
                let rows = g.reshape(&full, &[-1, t_pad as i64, 2]);
                let back = g.op(
                    "DFT",
                    &[&rows],
                    &[("axis", Attr::Int(1)), ("inverse", Attr::Int(1))],
                );
                let re = g.slice(&back, 2, 0, 1);
                g.reshape(&re, &[-1, w as i64, t_pad as i64])
            }
        })
    }

    /// The real block form `[[wr, wi], [-wi, wr]]` of layer `prefix`'s complex weights:
    /// `[M, 2W, 2W']`.
    fn mixing(&self, g: &mut Graph, prefix: &str) -> Result<Value> {
        let (shape, wr) = self.weight(&format!("{prefix}.wr"))?;
        let (_, wi) = self.weight(&format!("{prefix}.wi"))?;
        let (m, c, o) = (shape[0], shape[1], shape[2]);
        let mut out = vec![0.0f32; m * 4 * c * o];
        for k in 0..m {
            for i in 0..c {
                for j in 0..o {
                    let src = (k * c + i) * o + j;
                    let at = |row: usize, col: usize| (k * 2 * c + row) * 2 * o + col;
                    out[at(i, j)] = wr[src];
                    out[at(i, o + j)] = wi[src];
                    out[at(c + i, j)] = -wi[src];
                    out[at(c + i, o + j)] = wr[src];
                }
            }
        }
        Ok(g.f32s(&[m, 2 * c, 2 * o], &out))
    }
}

/// The truncated DFT bases of `pino_learn::spectral::Dft` for `t` points and `m` modes:
/// forward `[T, 2M]` and inverse `[2M, T]`, computed in f64 and rounded to f32.
fn bases(g: &mut Graph, t: usize, m: usize) -> (Value, Value) {
    let mut fwd = vec![0.0f32; t * 2 * m];
    let mut inv = vec![0.0f32; 2 * m * t];
    for k in 0..m {
        let c = if k == 0 { 1.0 } else { 2.0 } / t as f64;
        for n in 0..t {
            let theta = 2.0 * PI * ((k * n) % t) as f64 / t as f64;
            let (s, co) = theta.sin_cos();
            fwd[n * 2 * m + k] = co as f32;
            fwd[n * 2 * m + m + k] = -s as f32;
            inv[k * t + n] = (c * co) as f32;
            inv[(m + k) * t + n] = (-c * s) as f32;
        }
    }
    (g.f32s(&[t, 2 * m], &fwd), g.f32s(&[2 * m, t], &inv))
}

/// GELU in its tanh form (the project's, `pino_learn::kernels::simd`):
/// `z/2 (1 + tanh(sqrt(2/pi) (z + 0.044715 z^3)))`.
fn gelu_of(g: &mut Graph, z: &str) -> Value {
    let half = g.f32s(&[], &[0.5]);
    let one = g.f32s(&[], &[1.0]);
    let cubic = g.f32s(&[], &[0.044_715]);
    let scale = g.f32s(&[], &[(2.0 / PI).sqrt() as f32]);
    let z2 = g.mul(z, z);
    let z3 = g.mul(&z2, z);
    let c = g.mul(&z3, &cubic);
    let inner = g.add(z, &c);
    let u = g.mul(&inner, &scale);
    let t = g.unary("Tanh", &u);
    let t1 = g.add(&t, &one);
    let hz = g.mul(z, &half);
    g.mul(&hz, &t1)
}
