//! The end of every pointwise layer as one fused CPU op: `y = act(a [+ b] + bias)`.
//!
//! Tensors are channel-major, `a, b [C, N]` (`N` = samples x time points) and `bias [C]`;
//! `act` is GELU (tanh form) or the identity. A Fourier layer passes its spectral and pointwise
//! branches as `a` and `b`, so the sum, the bias and the activation are one pass over memory
//! forward and one backward (`da = db = g act'(z)`, `dbias_c = sum_n da[c, n]`), where the
//! composition of candle ops would make five.

use super::simd;
use candle_core::{CpuStorage, CustomOp2, CustomOp3, Layout, Shape, Tensor};
use rayon::prelude::*;

/// `act(a + bias)` (two inputs) or `act(a + b + bias)` (three inputs).
#[derive(Debug, Clone, Copy)]
pub struct BiasActivation {
    /// GELU when true, identity when false.
    pub gelu: bool,
}

fn slice<'a>(s: &'a CpuStorage, l: &Layout) -> candle_core::Result<&'a [f32]> {
    let CpuStorage::F32(v) = s else {
        return Err(candle_core::Error::Msg(
            "fused bias-activation: inputs must be f32".into(),
        ));
    };
    let (a, b) = l.contiguous_offsets().ok_or_else(|| {
        candle_core::Error::Msg("fused bias-activation: inputs must be contiguous".into())
    })?;
    Ok(&v[a..b])
}

fn channels(shape: &Shape, bias: &Shape) -> candle_core::Result<(usize, usize)> {
    let dims = shape.dims();
    let c = *dims.first().unwrap_or(&0);
    if bias.dims() != [c] || c == 0 {
        return Err(candle_core::Error::Msg(format!(
            "fused bias-activation: input {shape:?} with bias {bias:?} (need [C, ...] and [C])"
        )));
    }
    Ok((c, shape.elem_count() / c))
}

impl BiasActivation {
    fn forward(&self, a: &[f32], b: &[f32], bias: &[f32], n: usize) -> Vec<f32> {
        let mut out = vec![0.0f32; a.len()];
        out.par_chunks_mut(n).enumerate().for_each(|(c, o)| {
            let bc = if b.is_empty() {
                &[][..]
            } else {
                &b[c * n..(c + 1) * n]
            };
            simd::bias_act_forward(&a[c * n..(c + 1) * n], bc, bias[c], self.gelu, o);
        });
        out
    }

    /// `(d(a or b), dbias)` from the upstream gradient.
    fn backward(
        &self,
        a: &Tensor,
        b: Option<&Tensor>,
        bias: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<(Tensor, Tensor)> {
        let (c, n) = channels(a.shape(), bias.shape())?;
        let mut g = grad.flatten_all()?.to_vec1::<f32>()?;
        let dbias: Vec<f32> = if self.gelu {
            let a_h = a.flatten_all()?.to_vec1::<f32>()?;
            let b_h = match b {
                Some(b) => b.flatten_all()?.to_vec1::<f32>()?,
                None => Vec::new(),
            };
            let bias_h = bias.to_vec1::<f32>()?;
            g.par_chunks_mut(n)
                .enumerate()
                .map(|(ci, gc)| {
                    let bc = if b_h.is_empty() {
                        &[][..]
                    } else {
                        &b_h[ci * n..(ci + 1) * n]
                    };
                    simd::gelu_backward(&a_h[ci * n..(ci + 1) * n], bc, bias_h[ci], gc)
                })
                .collect()
        } else {
            g.par_chunks(n)
                .map(|gc| gc.iter().map(|&v| v as f64).sum::<f64>() as f32)
                .collect()
        };
        Ok((
            Tensor::from_vec(g, a.shape(), a.device())?,
            Tensor::from_vec(dbias, c, a.device())?,
        ))
    }
}

impl CustomOp2 for BiasActivation {
    fn name(&self) -> &'static str {
        "fused-bias-activation"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (_, n) = channels(l1.shape(), l2.shape())?;
        let out = self.forward(slice(s1, l1)?, &[], slice(s2, l2)?, n);
        Ok((CpuStorage::F32(out), l1.shape().clone()))
    }

    fn bwd(
        &self,
        a: &Tensor,
        bias: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>)> {
        let (da, dbias) = self.backward(a, None, bias, grad)?;
        Ok((Some(da), Some(dbias)))
    }
}

impl CustomOp3 for BiasActivation {
    fn name(&self) -> &'static str {
        "fused-sum-bias-activation"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        if l1.shape() != l2.shape() {
            return Err(candle_core::Error::Msg(format!(
                "fused bias-activation: summands {:?} and {:?} differ",
                l1.shape(),
                l2.shape()
            )));
        }
        let (_, n) = channels(l1.shape(), l3.shape())?;
        let out = self.forward(slice(s1, l1)?, slice(s2, l2)?, slice(s3, l3)?, n);
        Ok((CpuStorage::F32(out), l1.shape().clone()))
    }

    fn bwd(
        &self,
        a: &Tensor,
        b: &Tensor,
        bias: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let (d, dbias) = self.backward(a, Some(b), bias, grad)?;
        Ok((Some(d.clone()), Some(d), Some(dbias)))
    }
}
