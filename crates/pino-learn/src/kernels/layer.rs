//! One network layer, fused: `y = act(W^T x + b [+ K x])`, forward and backward on host
//! memory (the building block of the fused network).
//!
//! Channel-major `x [C, B, T]` (or `[C, N]`), pointwise weight `W [C, C']` (stored `[in,
//! out]`), bias `b [C']`, optionally the spectral convolution `K` of [`super::spectral_op`]
//! with `wr, wi [M, C, C']`, and `act` GELU or identity. The layer's parameters are one flat
//! slice `[W | b | wr | wi]`. Forward and backward:
//! ```text
//! z = W^T x + b [+ K x]      y = act(z)                     (z kept for backward)
//! gz = g act'(z)    db = sum_n gz    dW = x gz^T    dx = W gz [+ K^T gz]    dwr, dwi from K
//! ```
//! Products run in the `gemm` crate (the one candle's CPU backend uses), the rest in
//! [`super::simd`] and rustfft.

use super::simd;
use super::spectral_op::{SpectralConvOp, C32};
use super::RealDft;
use rayon::prelude::*;
use std::sync::{Arc, Mutex};

/// `dst = (accumulate ? dst : 0) + A B`, row-major `dst [m, n]`; `A [m, k]` given by its
/// row/column strides, as is `B [k, n]`.
#[allow(clippy::too_many_arguments)]
fn gemm(
    m: usize,
    n: usize,
    k: usize,
    dst: &mut [f32],
    accumulate: bool,
    a: &[f32],
    (a_rs, a_cs): (usize, usize),
    b: &[f32],
    (b_rs, b_cs): (usize, usize),
) {
    assert!(dst.len() >= m * n);
    assert!(m == 0 || k == 0 || a.len() > (m - 1) * a_rs + (k - 1) * a_cs);
    assert!(n == 0 || k == 0 || b.len() > (k - 1) * b_rs + (n - 1) * b_cs);
    let threads = rayon::current_num_threads();
    let parallelism = if threads > 1 && m * n * k > 1 << 16 {
        gemm::Parallelism::Rayon(threads)
    } else {
        gemm::Parallelism::None
    };
    // SAFETY: the asserts above keep every index the strides reach inside the slices, and
    // `dst` does not alias `a` or `b` (it is borrowed mutably).
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            n as isize,
            accumulate,
            a.as_ptr(),
            a_cs as isize,
            a_rs as isize,
            b.as_ptr(),
            b_cs as isize,
            b_rs as isize,
            1.0,
            1.0,
            false,
            false,
            false,
            parallelism,
        )
    }
}

/// What the forward pass keeps for the backward pass.
struct Saved {
    pre_activation: Vec<f32>,
    spectrum: Option<Vec<C32>>,
}

/// One fused layer for one call.
pub struct FusedLayer {
    c_in: usize,
    c_out: usize,
    gelu: bool,
    spectral: Option<SpectralConvOp>,
    saved: Mutex<Option<Saved>>,
}

impl FusedLayer {
    /// A pointwise layer `act(W^T x + b)`.
    pub fn pointwise(c_in: usize, c_out: usize, gelu: bool) -> Self {
        Self {
            c_in,
            c_out,
            gelu,
            spectral: None,
            saved: Mutex::new(None),
        }
    }

    /// A Fourier layer `act(W^T x + b + K x)` on the plan `dft` for `batch` samples.
    pub fn fourier(c: usize, gelu: bool, dft: &Arc<RealDft>, batch: usize) -> Self {
        Self {
            c_in: c,
            c_out: c,
            gelu,
            spectral: Some(SpectralConvOp::new(Arc::clone(dft), batch)),
            saved: Mutex::new(None),
        }
    }

    /// Length of the flat parameter vector `[W | b | wr | wi]`.
    pub fn param_len(&self) -> usize {
        let spectral = self
            .spectral
            .as_ref()
            .map_or(0, |s| 2 * s.modes() * self.c_in * self.c_out);
        self.c_in * self.c_out + self.c_out + spectral
    }

    /// `(W, b, wr, wi)` views of the flat parameters.
    fn split<'a>(&self, p: &'a [f32]) -> (&'a [f32], &'a [f32], &'a [f32], &'a [f32]) {
        let (w, rest) = p.split_at(self.c_in * self.c_out);
        let (b, rest) = rest.split_at(self.c_out);
        let (wr, wi) = rest.split_at(rest.len() / 2);
        (w, b, wr, wi)
    }

    /// Host forward over `n` columns; keeps what the backward pass needs.
    pub(crate) fn forward(&self, x: &[f32], p: &[f32], n: usize) -> Vec<f32> {
        let (w, b, wr, wi) = self.split(p);
        let mut z = match &self.spectral {
            Some(s) => {
                let (kx, spectrum) = s.forward_host(x, wr, wi, self.c_in, self.c_out);
                *self.saved.lock().unwrap_or_else(|e| e.into_inner()) = Some(Saved {
                    pre_activation: Vec::new(),
                    spectrum: Some(spectrum),
                });
                kx
            }
            None => vec![0.0f32; self.c_out * n],
        };
        let accumulate = self.spectral.is_some();
        // z [C', N] (+)= W^T [C', C] x [C, N]
        gemm(
            self.c_out,
            n,
            self.c_in,
            &mut z,
            accumulate,
            w,
            (1, self.c_out),
            x,
            (n, 1),
        );
        let mut y = vec![0.0f32; z.len()];
        y.par_chunks_mut(n)
            .zip(z.par_chunks_mut(n))
            .enumerate()
            .for_each(|(o, (yo, zo))| {
                for v in zo.iter_mut() {
                    *v += b[o];
                }
                simd::bias_act_forward(zo, &[], 0.0, self.gelu, yo);
            });
        let mut saved = self.saved.lock().unwrap_or_else(|e| e.into_inner());
        match saved.as_mut() {
            Some(s) => s.pre_activation = z,
            None => {
                *saved = Some(Saved {
                    pre_activation: z,
                    spectrum: None,
                })
            }
        }
        y
    }

    /// Host forward for inference over `n` columns into `out` (its old contents are
    /// overwritten; it is resized to `[C', n]`): the arithmetic of [`Self::forward`], so the
    /// same values, with the bias and activation applied in place and nothing kept.
    pub(crate) fn infer_into(&self, x: &[f32], p: &[f32], n: usize, out: &mut Vec<f32>) {
        let (w, b, wr, wi) = self.split(p);
        out.resize(self.c_out * n, 0.0);
        let accumulate = match &self.spectral {
            Some(s) => {
                s.infer_into(x, wr, wi, self.c_in, self.c_out, out);
                true
            }
            None => false,
        };
        // out [C', N] (+)= W^T [C', C] x [C, N]
        gemm(
            self.c_out,
            n,
            self.c_in,
            out,
            accumulate,
            w,
            (1, self.c_out),
            x,
            (n, 1),
        );
        out.par_chunks_mut(n)
            .enumerate()
            .for_each(|(o, zo)| simd::bias_act_in_place(zo, b[o], self.gelu));
    }

    /// Host backward: (`dx`, `dparams`); `grad` is overwritten with the pre-activation
    /// gradient.
    pub(crate) fn backward(
        &self,
        x: &[f32],
        p: &[f32],
        grad: &mut [f32],
        n: usize,
    ) -> (Vec<f32>, Vec<f32>) {
        let saved = self.saved.lock().unwrap_or_else(|e| e.into_inner()).take();
        let (pre, spectrum) = match saved {
            Some(s) if !s.pre_activation.is_empty() => (s.pre_activation, s.spectrum),
            _ => {
                // Not kept (the forward ran without a graph): recompute.
                let _ = self.forward(x, p, n);
                let s = self
                    .saved
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .take()
                    .expect("forward saves its state");
                (s.pre_activation, s.spectrum)
            }
        };
        let (w, _, wr, wi) = self.split(p);
        let db: Vec<f32> = grad
            .par_chunks_mut(n)
            .zip(pre.par_chunks(n))
            .map(|(g, z)| {
                if self.gelu {
                    simd::gelu_backward(z, &[], 0.0, g)
                } else {
                    g.iter().map(|&v| v as f64).sum::<f64>() as f32
                }
            })
            .collect();
        let mut dparams = vec![0.0f32; self.param_len()];
        let (dw, rest) = dparams.split_at_mut(self.c_in * self.c_out);
        let (dbias, dspectral) = rest.split_at_mut(self.c_out);
        dbias.copy_from_slice(&db);
        // dW [C, C'] = x [C, N] gz^T [N, C']
        gemm(self.c_in, self.c_out, n, dw, false, x, (n, 1), grad, (1, n));
        let mut dx = match (&self.spectral, spectrum) {
            (Some(s), Some(spectrum)) => {
                let (dx, dwr, dwi) =
                    s.backward_host(&spectrum, wr, wi, grad, self.c_in, self.c_out);
                let (dr, di) = dspectral.split_at_mut(dwr.len());
                dr.copy_from_slice(&dwr);
                di.copy_from_slice(&dwi);
                dx
            }
            _ => vec![0.0f32; self.c_in * n],
        };
        // dx [C, N] (+)= W [C, C'] gz [C', N]
        let accumulate = self.spectral.is_some();
        gemm(
            self.c_in,
            n,
            self.c_out,
            &mut dx,
            accumulate,
            w,
            (self.c_out, 1),
            grad,
            (n, 1),
        );
        (dx, dparams)
    }
}
