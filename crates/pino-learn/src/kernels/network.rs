//! The whole Fourier neural operator as one fused CPU op, with its backward pass.
//!
//! Input `x [B, T, C_in]`, all parameters as one flat tensor (per layer `[W | b | wr | wi]`,
//! layers in order lift, Fourier layers, proj1, proj2), output `u [B, T, C_out]`. Inside,
//! activations are channel-major and the layers are [`super::layer::FusedLayer`]s; the lift's
//! output is zero-padded to the plan's length before the Fourier layers and cropped after them.
//! The op keeps every layer's input for its backward pass, so candle's graph holds one node for
//! the network (and one for the parameter concatenation) instead of dozens whose gradients it
//! would allocate, zero-fill and accumulate one by one.

use super::layer::FusedLayer;
use super::RealDft;
use candle_core::{CpuStorage, CustomOp2, Layout, Shape, Tensor};
use rayon::prelude::*;
use std::sync::{Arc, Mutex};

/// Sizes of a fused network.
#[derive(Debug, Clone, Copy)]
pub struct NetworkShape {
    /// Input channels.
    pub c_in: usize,
    /// Width `W` of the Fourier layers.
    pub width: usize,
    /// Hidden width of the projection.
    pub projection: usize,
    /// Output channels.
    pub c_out: usize,
    /// Fourier layers.
    pub depth: usize,
}

/// The network over one contiguous part of a batch (its own layers and saved state).
struct NetworkPart {
    shape: NetworkShape,
    batch: usize,
    t: usize,
    t_pad: usize,
    layers: Vec<FusedLayer>,
    inputs: Mutex<Vec<Vec<f32>>>,
}

impl NetworkPart {
    /// The network for `batch` samples of `t` points, Fourier layers on the plan `dft`
    /// (length `T_p >= t`).
    fn new(shape: NetworkShape, dft: &Arc<RealDft>, batch: usize, t: usize) -> Self {
        let NetworkShape {
            c_in,
            width,
            projection,
            c_out,
            depth,
        } = shape;
        let mut layers = vec![FusedLayer::pointwise(c_in, width, false)];
        for l in 0..depth {
            layers.push(FusedLayer::fourier(width, l + 1 < depth, dft, batch));
        }
        layers.push(FusedLayer::pointwise(width, projection, true));
        layers.push(FusedLayer::pointwise(projection, c_out, false));
        Self {
            shape,
            batch,
            t,
            t_pad: dft.len(),
            layers,
            inputs: Mutex::new(Vec::new()),
        }
    }

    /// Length of the flat parameter vector.
    fn param_len(&self) -> usize {
        self.layers.iter().map(FusedLayer::param_len).sum()
    }

    fn param_slices<'a>(&self, p: &'a [f32]) -> Vec<&'a [f32]> {
        let mut out = Vec::with_capacity(self.layers.len());
        let mut rest = p;
        for layer in &self.layers {
            let (head, tail) = rest.split_at(layer.param_len());
            out.push(head);
            rest = tail;
        }
        out
    }

    /// `[W, B, T]` -> `[W, B, T_p]` with zeros after each row.
    fn pad(&self, v: &[f32], channels: usize) -> Vec<f32> {
        if self.t_pad == self.t {
            return v.to_vec();
        }
        let mut out = vec![0.0f32; channels * self.batch * self.t_pad];
        for (dst, src) in out.chunks_mut(self.t_pad).zip(v.chunks(self.t)) {
            dst[..self.t].copy_from_slice(src);
        }
        out
    }

    /// `[W, B, T_p]` -> `[W, B, T]` (the adjoint of [`Self::pad`]).
    fn crop(&self, v: &[f32]) -> Vec<f32> {
        if self.t_pad == self.t {
            return v.to_vec();
        }
        v.chunks(self.t_pad)
            .flat_map(|row| row[..self.t].iter().copied())
            .collect()
    }

    /// `[B, T, C_in]` -> channel-major `[C_in, B T]`.
    fn to_columns(&self, x: &[f32]) -> Vec<f32> {
        let c_in = self.shape.c_in;
        let n = self.batch * self.t;
        let mut columns = vec![0.0f32; x.len()];
        for (k, row) in x.chunks(c_in).enumerate() {
            for (c, &v) in row.iter().enumerate() {
                columns[c * n + k] = v;
            }
        }
        columns
    }

    /// Channel-major `[C_out, B T]` -> `[B, T, C_out]`.
    fn columns_to_rows(&self, u: &[f32]) -> Vec<f32> {
        let (n, c_out) = (self.batch * self.t, self.shape.c_out);
        let mut out = vec![0.0f32; u.len()];
        for (c, row) in u.chunks(n).enumerate() {
            for (k, &v) in row.iter().enumerate() {
                out[k * c_out + c] = v;
            }
        }
        out
    }

    fn forward(&self, x: &[f32], p: &[f32]) -> Vec<f32> {
        let (b, t) = (self.batch, self.t);
        let NetworkShape { width, depth, .. } = self.shape;
        let params = self.param_slices(p);
        let n = b * t;
        let columns = self.to_columns(x);
        let mut inputs = Vec::with_capacity(self.layers.len());
        let lifted = self.layers[0].forward(&columns, params[0], n);
        inputs.push(columns);
        let mut v = self.pad(&lifted, width);
        let n_pad = b * self.t_pad;
        for l in 0..depth {
            let next = self.layers[1 + l].forward(&v, params[1 + l], n_pad);
            inputs.push(std::mem::replace(&mut v, next));
        }
        let cropped = self.crop(&v);
        let h = self.layers[depth + 1].forward(&cropped, params[depth + 1], n);
        inputs.push(cropped);
        let u = self.layers[depth + 2].forward(&h, params[depth + 2], n);
        inputs.push(h);
        *self.inputs.lock().unwrap_or_else(|e| e.into_inner()) = inputs;
        self.columns_to_rows(&u)
    }

    /// [`Self::forward`] for inference: the same arithmetic (the same values), activations in
    /// two buffers updated in place, nothing kept for a backward pass.
    fn infer(&self, x: &[f32], p: &[f32]) -> Vec<f32> {
        let (b, t, t_pad) = (self.batch, self.t, self.t_pad);
        let NetworkShape { width, depth, .. } = self.shape;
        let params = self.param_slices(p);
        let n = b * t;
        let (mut cur, mut next) = (Vec::new(), Vec::new());
        self.layers[0].infer_into(&self.to_columns(x), params[0], n, &mut next);
        if t_pad > t {
            cur.resize(width * b * t_pad, 0.0);
            for (dst, src) in cur.chunks_mut(t_pad).zip(next.chunks(t)) {
                dst[..t].copy_from_slice(src);
                dst[t..].fill(0.0);
            }
        } else {
            std::mem::swap(&mut cur, &mut next);
        }
        for l in 0..depth {
            self.layers[1 + l].infer_into(&cur, params[1 + l], b * t_pad, &mut next);
            std::mem::swap(&mut cur, &mut next);
        }
        if t_pad > t {
            next.clear();
            for row in cur.chunks(t_pad) {
                next.extend_from_slice(&row[..t]);
            }
            std::mem::swap(&mut cur, &mut next);
        }
        self.layers[depth + 1].infer_into(&cur, params[depth + 1], n, &mut next);
        self.layers[depth + 2].infer_into(&next, params[depth + 2], n, &mut cur);
        self.columns_to_rows(&cur)
    }

    fn backward(&self, x: &[f32], p: &[f32], grad: &[f32]) -> Vec<f32> {
        let (b, t) = (self.batch, self.t);
        let NetworkShape { c_out, depth, .. } = self.shape;
        let mut inputs =
            std::mem::take(&mut *self.inputs.lock().unwrap_or_else(|e| e.into_inner()));
        if inputs.len() != self.layers.len() {
            // The forward ran without a graph: run it again to rebuild the saved state.
            let _ = self.forward(x, p);
            inputs = std::mem::take(&mut *self.inputs.lock().unwrap_or_else(|e| e.into_inner()));
        }
        let params = self.param_slices(p);
        let n = b * t;
        let mut dparams: Vec<Vec<f32>> = vec![Vec::new(); self.layers.len()];
        let mut g = vec![0.0f32; grad.len()];
        for (k, row) in grad.chunks(c_out).enumerate() {
            for (c, &v) in row.iter().enumerate() {
                g[c * n + k] = v;
            }
        }
        let last = self.layers.len() - 1;
        let (dh, dp) = self.layers[last].backward(&inputs[last], params[last], &mut g, n);
        dparams[last] = dp;
        let mut dh = dh;
        let (dc, dp) =
            self.layers[depth + 1].backward(&inputs[depth + 1], params[depth + 1], &mut dh, n);
        dparams[depth + 1] = dp;
        let mut dv = self.pad(&dc, self.shape.width);
        let n_pad = b * self.t_pad;
        for l in (0..depth).rev() {
            let (d, dp) =
                self.layers[1 + l].backward(&inputs[1 + l], params[1 + l], &mut dv, n_pad);
            dparams[1 + l] = dp;
            dv = d;
        }
        let mut d_lift = self.crop(&dv);
        let (_, dp) = self.layers[0].backward(&inputs[0], params[0], &mut d_lift, n);
        dparams[0] = dp;
        dparams.concat()
    }
}

/// One forward (and backward) of the network for one batch.
///
/// The batch is cut into (at most) two halves that run side by side on rayon's pool, each a
/// whole forward and backward on its own samples; the parameter gradients of the halves are
/// added in a fixed order. The cut does not depend on the thread count, so neither do the
/// results (one thread runs the halves one after the other). Two halves rather than one part
/// per sample: the parameter gradients of every part must be summed, which costs a pass over
/// all parameters per part.
pub struct FusedNetwork {
    shape: NetworkShape,
    batch: usize,
    t: usize,
    parts: Vec<(usize, NetworkPart)>,
}

impl FusedNetwork {
    /// The network for `batch` samples of `t` points, Fourier layers on the plan `dft`
    /// (length `T_p >= t`).
    pub fn new(shape: NetworkShape, dft: &Arc<RealDft>, batch: usize, t: usize) -> Self {
        let first = batch.div_ceil(2);
        let parts = [(0, first), (first, batch - first)]
            .into_iter()
            .filter(|&(_, len)| len > 0)
            .map(|(start, len)| (start, NetworkPart::new(shape, dft, len, t)))
            .collect();
        Self {
            shape,
            batch,
            t,
            parts,
        }
    }

    /// Length of the flat parameter vector.
    pub fn param_len(&self) -> usize {
        self.parts.first().map_or(0, |(_, p)| p.param_len())
    }

    fn forward(&self, x: &[f32], p: &[f32]) -> Vec<f32> {
        let per_in = self.t * self.shape.c_in;
        let per_out = self.t * self.shape.c_out;
        let outs: Vec<Vec<f32>> = self
            .parts
            .par_iter()
            .map(|(start, part)| part.forward(&x[start * per_in..(start + part.batch) * per_in], p))
            .collect();
        let mut u = Vec::with_capacity(self.batch * per_out);
        for o in outs {
            u.extend(o);
        }
        u
    }

    /// The output `[B, T, C_out]` of the network `shape` (Fourier layers on the plan `dft`)
    /// for host input `x [B, T, C_in]` of `t` points and flat parameters `p`, for inference:
    /// the op's forward pass to round-off, nothing kept for a backward pass. Samples run one
    /// by one, side by side (each sample's activations stay in the core's cache, and its
    /// output does not depend on the other samples).
    pub fn infer(
        shape: NetworkShape,
        dft: &Arc<RealDft>,
        t: usize,
        x: &[f32],
        p: &[f32],
    ) -> Vec<f32> {
        let per_in = t * shape.c_in;
        let sample = NetworkPart::new(shape, dft, 1, t);
        let outs: Vec<Vec<f32>> = x.par_chunks(per_in).map(|x| sample.infer(x, p)).collect();
        outs.concat()
    }

    fn backward(&self, x: &[f32], p: &[f32], grad: &[f32]) -> Vec<f32> {
        let per_in = self.t * self.shape.c_in;
        let per_out = self.t * self.shape.c_out;
        let grads: Vec<Vec<f32>> = self
            .parts
            .par_iter()
            .map(|(start, part)| {
                let n = part.batch;
                part.backward(
                    &x[start * per_in..(start + n) * per_in],
                    p,
                    &grad[start * per_out..(start + n) * per_out],
                )
            })
            .collect();
        let mut grads = grads.into_iter();
        let mut total = grads.next().unwrap_or_default();
        for g in grads {
            for (t, v) in total.iter_mut().zip(g) {
                *t += v;
            }
        }
        total
    }
}

impl CustomOp2 for FusedNetwork {
    fn name(&self) -> &'static str {
        "fused-fno"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let expected = [self.batch, self.t, self.shape.c_in];
        if l1.shape().dims() != expected || l2.shape().dims() != [self.param_len()] {
            return Err(candle_core::Error::Msg(format!(
                "fused network: input {:?} and parameters {:?}, expected {expected:?} and [{}]",
                l1.shape(),
                l2.shape(),
                self.param_len()
            )));
        }
        let op = "fused network";
        let u = self.forward(
            super::cpu_f32(s1, l1, op, "input")?,
            super::cpu_f32(s2, l2, op, "parameters")?,
        );
        Ok((
            CpuStorage::F32(u),
            Shape::from((self.batch, self.t, self.shape.c_out)),
        ))
    }

    fn bwd(
        &self,
        x: &Tensor,
        p: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>)> {
        let dp = super::with_host(x, |xh| {
            super::with_host(p, |ph| {
                super::with_host(grad, |gh| self.backward(xh, ph, gh))
            })
        })???;
        // The input is data (z-scored parameters and irregularity): no gradient flows to it.
        Ok((None, Some(Tensor::from_vec(dp, p.shape(), p.device())?)))
    }
}
