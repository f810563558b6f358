//! The Fourier neural operator of `pino_learn::model` as graph nodes, with the product's
//! input normalisation in front of it.
//!
//! Activations are time-major, `[T, B W]` (or `[T B, W]`, the same memory): a pointwise layer
//! is one `Gemm` over every design and time point, and the truncated DFT of the spectral
//! layers sums over the leading axis ([`crate::dft`]). Two forms of the spectral convolution
//! (`docs/export.md`):
//! - [`Spectral::Matmul`] (opset 13): fixed matrix products, directly or over a two-stage
//!   factorisation of the padded length ([`crate::dft::Plan`]);
//! - [`Spectral::Dft`] (opset 17): the `DFT` operator, one-sided forward transform of the real
//!   rows and inverse transform of the kept modes (weights 1 for mode 0, 2 above, so the real
//!   part of the inverse is the synthesis).
//!
//! Each layer's bias rides on its spectral path (`T` times the bias added to mode 0's real
//! part, which the synthesis spreads as the constant), the pointwise product takes the
//! spectral result as its `Gemm` addend, and GELU is written in the form ONNX Runtime fuses
//! into one kernel (`Pow(z, 3)` first).
//!
//! The inputs are normalised as `predict` does it: in double precision, `(x - mean) / std`,
//! then rounded to single precision; the network runs in single precision. The lifting layer
//! is split by input: the excitations' product per time point, the parameters' once per
//! design, the time grid's (with the bias) a constant.

use crate::dft::{Analysis, Plan, Synthesis};
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

/// The spectral layers' transforms: fixed matrices, or the `DFT` operator (`None`).
type Bases = Option<(Analysis, Synthesis)>;

impl Network<'_> {
    fn config(&self) -> &ModelConfig {
        &self.meta.model
    }

    fn weight(&self, name: &str) -> Result<&(Vec<usize>, Vec<f32>)> {
        self.weights
            .get(name)
            .ok_or_else(|| Error::Unsupported(format!("the model has no tensor `{name}`")))
    }

    /// `x [N, in] W [in, out] + c` (`c`: the layer's bias, or another addend).
    fn gemm(&self, g: &mut Graph, x: &str, prefix: &str, c: Option<&str>) -> Result<Value> {
        let (shape, w) = self.weight(&format!("{prefix}.weight"))?;
        let w = g.f32s(shape, w);
        let c = match c {
            Some(c) => c.to_owned(),
            None => {
                let (shape, b) = self.weight(&format!("{prefix}.bias"))?;
                g.f32s(shape, b)
            }
        };
        Ok(g.op("Gemm", &[x, &w, &c], &[]))
    }

    /// The z-scored outputs, channel-major `[O, B, T]` (f32), of the graph inputs `eta [B,
    /// T, E]` and `params [B, P]` (f64, physical units).
    pub fn forward(&self, g: &mut Graph, eta: &str, params: &str) -> Result<Value> {
        let c = *self.config();
        let t = self.meta.grid.t_points;
        let t_pad = c.padded_points(t);
        let w = c.width as i64;
        let mut v = self.lift(g, eta, params)?; // [T, B W]
        if t_pad > t {
            let pads = g.i64s(&[0, 0, (t_pad - t) as i64, 0]);
            v = g.op("Pad", &[&v, &pads], &[]);
        }
        let plan = match self.spectral {
            Spectral::Matmul => Plan::for_layer(t_pad, c.modes, c.width),
            Spectral::Dft => Plan::direct(t_pad, c.modes),
        };
        let bases = self.bases(g, &plan);
        for l in 0..c.depth {
            let prefix = format!("layers.{l}");
            let k = self.spectral_conv(g, &v, &prefix, &bases, &plan)?;
            let rows = g.reshape(&v, &[-1, w]);
            let k = g.reshape(&k, &[-1, w]);
            let z = self.gemm(g, &rows, &prefix, Some(&k))?;
            let z = if l + 1 < c.depth { gelu_of(g, &z) } else { z };
            v = g.reshape(&z, &[t_pad as i64, -1]);
        }
        if t_pad > t {
            v = g.slice(&v, 0, 0, t);
        }
        let rows = g.reshape(&v, &[-1, w]);
        let h = self.gemm(g, &rows, "proj1", None)?;
        let h = gelu_of(g, &h);
        // The last product transposed, `W^T h^T + b`: the outputs come channel-major.
        let (shape, w2) = self.weight("proj2.weight")?;
        let (_, b2) = self.weight("proj2.bias")?;
        let (i, o) = (shape[0], shape[1]);
        let mut w2t = vec![0.0f32; w2.len()];
        for r in 0..i {
            for c in 0..o {
                w2t[c * i + r] = w2[r * o + c];
            }
        }
        let (w2t, b2) = (g.f32s(&[o, i], &w2t), g.f32s(&[o, 1], b2));
        let u = g.op("Gemm", &[&w2t, &h, &b2], &[("transB", Attr::Int(1))]);
        let u = g.reshape(&u, &[o as i64, t as i64, -1]);
        Ok(g.transpose(&u, &[0, 2, 1]))
    }

    /// The lifted input `[T, B W]` (f32): the excitations' product per time point, plus the
    /// parameters' per design, plus the time grid's with the bias (a constant `[T, 1, W]`).
    fn lift(&self, g: &mut Graph, eta: &str, params: &str) -> Result<Value> {
        let stats = &self.meta.norm.inputs;
        let ranges = self.meta.layout.input_ranges();
        let (shape, lw) = self.weight("lift.weight")?;
        let (_, bias) = self.weight("lift.bias")?;
        let w = shape[1];
        let rows = |r: std::ops::Range<usize>| lw[r.start * w..r.end * w].to_vec();
        let normalise = |g: &mut Graph, x: &str, r: std::ops::Range<usize>, dims: &[usize]| {
            let mean = g.f64s(dims, &stats.mean[r.clone()]);
            let std = g.f64s(dims, &stats.std[r]);
            let centred = g.sub(x, &mean);
            let z = g.div(&centred, &std);
            g.cast(&z, DataType::Float)
        };
        let (e, p) = (ranges.excitations.len(), ranges.params.len());
        let t = self.meta.grid.t_points;
        // Time and bias: a constant, in double precision then rounded.
        let wt = &lw[ranges.time * w..(ranges.time + 1) * w];
        let mut fixed = Vec::with_capacity(t * w);
        for time in self.meta.grid.times() {
            let tn = ((time - stats.mean[ranges.time]) / stats.std[ranges.time]) as f32;
            for j in 0..w {
                fixed.push((f64::from(tn) * f64::from(wt[j]) + f64::from(bias[j])) as f32);
            }
        }
        let mut sum = g.f32s(&[t, 1, w], &fixed);
        // Excitations: normalised as `[B, T E]` against their statistics repeated over `T` (a
        // broadcast over the designs alone), then `[T B, E] x [E, W] -> [T, B, W]`.
        if e > 0 {
            let r = ranges.excitations.clone();
            let flat = g.reshape(eta, &[-1, (t * e) as i64]);
            let mean = stats.mean[r.clone()].repeat(t);
            let std = stats.std[r.clone()].repeat(t);
            let (mean, std) = (g.f64s(&[t * e], &mean), g.f64s(&[t * e], &std));
            let centred = g.sub(&flat, &mean);
            let z = g.div(&centred, &std);
            let z = g.cast(&z, DataType::Float);
            let z = g.reshape(&z, &[-1, t as i64, e as i64]);
            let z = g.transpose(&z, &[1, 0, 2]);
            let eta_rows = g.reshape(&z, &[-1, e as i64]);
            let we = g.f32s(&[e, w], &rows(r));
            let from_eta = g.matmul(&eta_rows, &we);
            let from_eta = g.reshape(&from_eta, &[t as i64, -1, w as i64]);
            sum = g.add(&from_eta, &sum);
        }
        // Parameters: [B, P] x [P, W], once per design.
        if p > 0 {
            let p_n = normalise(g, params, ranges.params.clone(), &[p]);
            let wp = g.f32s(&[p, w], &rows(ranges.params));
            let from_p = g.matmul(&p_n, &wp);
            sum = g.add(&sum, &from_p);
        }
        if e == 0 && p == 0 {
            return Err(Error::Unsupported(
                "a model that reads neither an excitation nor a parameter".into(),
            ));
        }
        Ok(g.reshape(&sum, &[t as i64, -1]))
    }

    /// The fixed matrices of the spectral layers.
    fn bases(&self, g: &mut Graph, plan: &Plan) -> Bases {
        match self.spectral {
            Spectral::Matmul => Some((Analysis::new(g, plan), Synthesis::new(g, plan))),
            Spectral::Dft => None,
        }
    }

    /// `K v + b` of `v [T_p, B W]`: analysis into the slots, complex mode mixing (with the
    /// layer's bias on mode 0), synthesis; `[T_p, B W']`.
    fn spectral_conv(
        &self,
        g: &mut Graph,
        v: &str,
        prefix: &str,
        bases: &Bases,
        plan: &Plan,
    ) -> Result<Value> {
        let w = self.config().width as i64;
        let k = plan.n_slots() as i64;
        let spec = match bases {
            Some((a, _)) => a.apply(g, plan, v),
            None => self.dft_analysis(g, v, plan),
        };
        // [K, 2, B, W] -> [K, B, 2W]
        let parts = g.reshape(&spec, &[k, 2, -1, w]);
        let parts = g.transpose(&parts, &[0, 2, 1, 3]);
        let xm = g.reshape(&parts, &[k, -1, 2 * w]);
        let (mix, bias) = self.mixing(g, prefix, plan)?;
        let y = g.matmul(&xm, &mix); // [K, B, 2W']
        let y = g.add(&y, &bias);
        let y = g.reshape(&y, &[k, -1, 2, w]);
        let y = g.transpose(&y, &[0, 2, 1, 3]); // [K, 2, B, W']
        Ok(match bases {
            Some((_, s)) => s.apply(g, plan, &y),
            None => self.dft_synthesis(g, &y, plan),
        })
    }

    /// The kept modes `[M, 2, B W]` of `v [T_p, B W]` by the `DFT` operator.
    fn dft_analysis(&self, g: &mut Graph, v: &str, plan: &Plan) -> Value {
        let rows = g.transpose(v, &[1, 0]);
        let rows = g.unsqueeze(&rows, &[2]); // [B W, T_p, 1]
        let spec = g.op(
            "DFT",
            &[&rows],
            &[("axis", Attr::Int(1)), ("onesided", Attr::Int(1))],
        ); // [B W, T_p/2 + 1, 2]
        let kept = g.slice(&spec, 1, 0, plan.n_slots());
        g.transpose(&kept, &[1, 2, 0])
    }

    /// The real series `[T_p, B W']` of the modes `y [M, 2, B, W']` by the inverse `DFT`.
    fn dft_synthesis(&self, g: &mut Graph, y: &str, plan: &Plan) -> Value {
        let (m, t) = (plan.n_slots(), plan.t);
        let y = g.reshape(y, &[m as i64, 2, -1]);
        let y = g.transpose(y.as_str(), &[2, 0, 1]); // [B W', M, 2]
        let weights: Vec<f32> = (0..m).map(|k| if k == 0 { 1.0 } else { 2.0 }).collect();
        let weights = g.f32s(&[m, 1], &weights);
        let y = g.mul(&y, &weights);
        let pads = g.i64s(&[0, 0, 0, 0, (t - m) as i64, 0]);
        let full = g.op("Pad", &[&y, &pads], &[]);
        let back = g.op(
            "DFT",
            &[&full],
            &[("axis", Attr::Int(1)), ("inverse", Attr::Int(1))],
        );
        let re = g.slice(&back, 2, 0, 1);
        let re = g.reshape(&re, &[-1, t as i64]);
        g.transpose(&re, &[1, 0])
    }

    /// The real block form `[[wr, wi], [-wi, wr]]` of layer `prefix`'s complex weights in the
    /// plan's slots, `[K, 2W, 2W']` (zero for an empty slot), and the layer's bias as `T`
    /// times itself on mode 0's real part, `[K, 1, 2W']`.
    fn mixing(&self, g: &mut Graph, prefix: &str, plan: &Plan) -> Result<(Value, Value)> {
        let (shape, wr) = self.weight(&format!("{prefix}.wr"))?;
        let (_, wi) = self.weight(&format!("{prefix}.wi"))?;
        let (_, bias) = self.weight(&format!("{prefix}.bias"))?;
        let (c, o) = (shape[1], shape[2]);
        let slots = plan.n_slots();
        let mut out = vec![0.0f32; slots * 4 * c * o];
        for (s, k) in plan.slots.iter().enumerate() {
            let Some(k) = *k else { continue };
            for i in 0..c {
                for j in 0..o {
                    let src = (k * c + i) * o + j;
                    let at = |row: usize, col: usize| (s * 2 * c + row) * 2 * o + col;
                    out[at(i, j)] = wr[src];
                    out[at(i, o + j)] = wi[src];
                    out[at(c + i, j)] = -wi[src];
                    out[at(c + i, o + j)] = wr[src];
                }
            }
        }
        let mut b = vec![0.0f32; slots * 2 * o];
        let zero = plan
            .slot_of(0)
            .ok_or_else(|| Error::Unsupported(format!("`{prefix}` keeps no mode 0")))?;
        for j in 0..o {
            b[zero * 2 * o + j] = (plan.t as f64 * f64::from(bias[j])) as f32;
        }
        Ok((
            g.f32s(&[slots, 2 * c, 2 * o], &out),
            g.f32s(&[slots, 1, 2 * o], &b),
        ))
    }
}

/// GELU in its tanh form (the project's, `pino_learn::kernels::simd`):
/// `z/2 (1 + tanh(sqrt(2/pi) (z + 0.044715 z^3)))`, the cube by `Pow` and the constants in
/// single precision, as ONNX Runtime's `FastGelu` fusion recognises it.
fn gelu_of(g: &mut Graph, z: &str) -> Value {
    let three = g.f32s(&[], &[3.0]);
    let half = g.f32s(&[], &[0.5]);
    let one = g.f32s(&[], &[1.0]);
    let cubic = g.f32s(&[], &[0.044_715]);
    let scale = g.f32s(&[], &[(2.0 / PI).sqrt() as f32]);
    let z3 = g.op("Pow", &[z, &three], &[]);
    let c = g.mul(&z3, &cubic);
    let inner = g.add(z, &c);
    let u = g.mul(&inner, &scale);
    let t = g.unary("Tanh", &u);
    let t1 = g.add(&t, &one);
    let hz = g.mul(z, &half);
    g.mul(&hz, &t1)
}
