//! The 1-D spectral convolution `K v = F^-1( R . F v )` on the lowest `M` Fourier modes,
//! with two interchangeable implementations of the truncated real DFT (candle has no FFT):
//!
//! - [`Transform::Matmul`]: precomputed bases. With `theta_mt = 2 pi m t / T`,
//!   ```text
//!   forward  [2M, T]:  Re X_m =  sum_t x_t cos(theta_mt),   Im X_m = -sum_t x_t sin(theta_mt)
//!   inverse  [T, 2M]:  y_t = sum_m c_m (Re Y_m cos(theta_mt) - Im Y_m sin(theta_mt)),
//!                      c_0 = 1/T, c_m = 2/T (m >= 1; M <= T/2 so no Nyquist term)
//!   ```
//!   so the transform is two matrix products and candle differentiates it; it runs on any
//!   device.
//! - [`Transform::Fft`]: candle custom ops on the CPU calling rustfft, with hand-written
//!   adjoints as backward passes (the adjoint of the truncated forward DFT is `Re(ifft)` of the
//!   zero-padded cotangent, and vice versa).
//!
//! Mode mixing is complex and per mode: `Y_m[o] = sum_i X_m[i] R_m[i, o]`, written as one real
//! batched product `[Re X, Im X] [[Re R, Im R], [-Im R, Re R]]` of shape
//! `[M, B, 2C] x [M, 2C, 2C'] -> [M, B, 2C']`. Activations are `[B, T, C]` (time, then
//! channels). The measurement that picked the default is in BENCHMARKS.md (Learning).

use crate::Result;
use candle_core::{CpuStorage, CustomOp1, DType, Device, Layout, Shape, Tensor};
use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use std::f64::consts::PI;
use std::sync::Arc;

/// How the truncated DFT is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transform {
    /// Dense cosine/sine bases, two matrix products (default; any device).
    Matmul,
    /// rustfft custom ops with adjoint backward passes (CPU only).
    Fft,
}

/// The truncated real DFT of length `T` on `M` modes, in one of the two implementations.
#[derive(Debug, Clone)]
pub struct Dft {
    /// Time points.
    pub t_points: usize,
    /// Kept modes.
    pub modes: usize,
    transform: Transform,
    forward: Tensor,
    inverse: Tensor,
}

impl Dft {
    /// Bases for `t_points` and `modes` in `dtype` on `device`.
    pub fn new(
        t_points: usize,
        modes: usize,
        transform: Transform,
        dtype: DType,
        device: &Device,
    ) -> Result<Self> {
        let (t, m) = (t_points, modes);
        let mut fwd = vec![0.0f64; 2 * m * t];
        let mut inv = vec![0.0f64; t * 2 * m];
        for k in 0..m {
            let c = if k == 0 {
                1.0 / t as f64
            } else {
                2.0 / t as f64
            };
            for n in 0..t {
                // Reduce k*n mod T first so the angle stays accurate for long records.
                let theta = 2.0 * PI * ((k * n) % t) as f64 / t as f64;
                let (s, co) = theta.sin_cos();
                fwd[k * t + n] = co;
                fwd[(m + k) * t + n] = -s;
                inv[n * 2 * m + k] = c * co;
                inv[n * 2 * m + m + k] = -c * s;
            }
        }
        Ok(Self {
            t_points,
            modes,
            transform,
            forward: Tensor::from_vec(fwd, (2 * m, t), device)?.to_dtype(dtype)?,
            inverse: Tensor::from_vec(inv, (t, 2 * m), device)?.to_dtype(dtype)?,
        })
    }

    /// `x [B, T, C] -> [B, 2M, C]` (rows `Re X_0..Re X_{M-1}, Im X_0..Im X_{M-1}`).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        match self.transform {
            Transform::Matmul => Ok(self.forward.broadcast_matmul(x)?),
            Transform::Fft => {
                let (b, t, c) = x.dims3()?;
                let rows = x.transpose(1, 2)?.contiguous()?.reshape((b * c, t))?;
                let op = FftOp::new(self.t_points, self.modes, Direction::Forward);
                let spec = rows.apply_op1(op)?; // [B*C, 2M]
                Ok(spec.reshape((b, c, 2 * self.modes))?.transpose(1, 2)?)
            }
        }
    }

    /// `y [B, 2M, C] -> [B, T, C]`, the real signal whose lowest modes are `y`.
    pub fn inverse(&self, y: &Tensor) -> Result<Tensor> {
        match self.transform {
            Transform::Matmul => Ok(self.inverse.broadcast_matmul(y)?),
            Transform::Fft => {
                let (b, m2, c) = y.dims3()?;
                let rows = y.transpose(1, 2)?.contiguous()?.reshape((b * c, m2))?;
                let op = FftOp::new(self.t_points, self.modes, Direction::Inverse);
                let sig = rows.apply_op1(op)?; // [B*C, T]
                Ok(sig.reshape((b, c, self.t_points))?.transpose(1, 2)?)
            }
        }
    }
}

/// Complex mode mixing: `x [B, 2M, C]`, `wr, wi [M, C, C']` -> `[B, 2M, C']`.
pub fn mix_modes(x: &Tensor, wr: &Tensor, wi: &Tensor) -> Result<Tensor> {
    let (b, m2, c) = x.dims3()?;
    let m = m2 / 2;
    let co = wr.dim(2)?;
    let xm = x
        .reshape((b, 2, m, c))?
        .permute((2, 0, 1, 3))?
        .contiguous()?
        .reshape((m, b, 2 * c))?;
    let top = Tensor::cat(&[wr, wi], 2)?;
    let bottom = Tensor::cat(&[&wi.neg()?, wr], 2)?;
    let w = Tensor::cat(&[&top, &bottom], 1)?; // [M, 2C, 2C']
    let y = xm.matmul(&w)?; // [M, B, 2C']
    Ok(y.reshape((m, b, 2, co))?
        .permute((1, 2, 0, 3))?
        .contiguous()?
        .reshape((b, 2 * m, co))?)
}

/// The spectral convolution `K x = F^-1(R . F x)` of `x [B, T, C]`.
pub fn spectral_conv(dft: &Dft, x: &Tensor, wr: &Tensor, wi: &Tensor) -> Result<Tensor> {
    let spec = dft.forward(x)?;
    let mixed = mix_modes(&spec, wr, wi)?;
    dft.inverse(&mixed)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Direction {
    /// `[N, T] -> [N, 2M]`.
    Forward,
    /// `[N, 2M] -> [N, T]`.
    Inverse,
}

/// Truncated real DFT (or its inverse) of each row, with rustfft; f32 or f64, CPU.
struct FftOp {
    t: usize,
    m: usize,
    dir: Direction,
    fft: Arc<dyn rustfft::Fft<f64>>,
    ifft: Arc<dyn rustfft::Fft<f64>>,
}

impl FftOp {
    fn new(t: usize, m: usize, dir: Direction) -> Self {
        let mut planner = FftPlanner::new();
        Self {
            t,
            m,
            dir,
            fft: planner.plan_fft_forward(t),
            ifft: planner.plan_fft_inverse(t),
        }
    }

    fn scale(&self, k: usize) -> f64 {
        if k == 0 {
            1.0 / self.t as f64
        } else {
            2.0 / self.t as f64
        }
    }

    /// Forward: row of T reals -> [Re X_0..M-1, Im X_0..M-1].
    fn rfft_row(&self, x: &[f64], out: &mut [f64], buf: &mut [Complex<f64>]) {
        for (b, &v) in buf.iter_mut().zip(x) {
            *b = Complex::new(v, 0.0);
        }
        self.fft.process(buf);
        for k in 0..self.m {
            out[k] = buf[k].re;
            out[self.m + k] = buf[k].im;
        }
    }

    /// Inverse: [Re Y, Im Y] -> T reals `y_t = Re sum_m c_m Y_m e^{i theta}`.
    fn irfft_row(&self, y: &[f64], out: &mut [f64], buf: &mut [Complex<f64>]) {
        buf.fill(Complex::new(0.0, 0.0));
        for k in 0..self.m {
            buf[k] = Complex::new(y[k], y[self.m + k]) * self.scale(k);
        }
        self.ifft.process(buf);
        for (o, b) in out.iter_mut().zip(buf.iter()) {
            *o = b.re;
        }
    }

    fn run_rows(&self, input: &[f64], n: usize, forward: bool) -> Vec<f64> {
        use rayon::prelude::*;
        let (len_in, len_out) = if forward {
            (self.t, 2 * self.m)
        } else {
            (2 * self.m, self.t)
        };
        let mut out = vec![0.0; n * len_out];
        out.par_chunks_mut(len_out)
            .zip(input.par_chunks(len_in))
            .for_each_init(
                || vec![Complex::new(0.0, 0.0); self.t],
                |buf, (o, i)| {
                    if forward {
                        self.rfft_row(i, o, buf)
                    } else {
                        self.irfft_row(i, o, buf)
                    }
                },
            );
        out
    }
}

impl CustomOp1 for FftOp {
    fn name(&self) -> &'static str {
        match self.dir {
            Direction::Forward => "truncated-rfft",
            Direction::Inverse => "truncated-irfft",
        }
    }

    fn cpu_fwd(
        &self,
        storage: &CpuStorage,
        layout: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (n, len) = layout.shape().dims2()?;
        let (o1, o2) = layout
            .contiguous_offsets()
            .ok_or_else(|| candle_core::Error::Msg("fft op needs a contiguous input".into()))?;
        let as_f64: Vec<f64> = match storage {
            CpuStorage::F64(v) => v[o1..o2].to_vec(),
            CpuStorage::F32(v) => v[o1..o2].iter().map(|&x| x as f64).collect(),
            _ => {
                return Err(candle_core::Error::Msg(
                    "fft op supports f32 and f64".into(),
                ))
            }
        };
        let forward = self.dir == Direction::Forward;
        let expect = if forward { self.t } else { 2 * self.m };
        if len != expect {
            return Err(candle_core::Error::Msg(format!(
                "fft op: row length {len}, expected {expect}"
            )));
        }
        let out = self.run_rows(&as_f64, n, forward);
        let len_out = out.len() / n.max(1);
        let storage = match storage {
            CpuStorage::F32(_) => CpuStorage::F32(out.iter().map(|&x| x as f32).collect()),
            _ => CpuStorage::F64(out),
        };
        Ok((storage, Shape::from((n, len_out))))
    }

    fn bwd(
        &self,
        _arg: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        // The adjoint of the truncated forward DFT maps a cotangent (gr, gi) to
        // g_t = sum_m gr_m cos - gi_m sin = Re sum_m (gr + i gi) e^{i theta}: an inverse
        // transform with weights 1 instead of c_m. The adjoint of the inverse maps g_t to
        // (c_m Re G_m, c_m Im G_m) with G = FFT(g). Both reuse the row kernels with rescaling.
        let adjoint = AdjointOp {
            inner: FftOp::new(self.t, self.m, self.dir),
        };
        Ok(Some(grad_res.contiguous()?.apply_op1_no_bwd(&adjoint)?))
    }
}

/// Backward pass of [`FftOp`] (no second derivative).
struct AdjointOp {
    inner: FftOp,
}

impl CustomOp1 for AdjointOp {
    fn name(&self) -> &'static str {
        "truncated-dft-adjoint"
    }

    fn cpu_fwd(
        &self,
        storage: &CpuStorage,
        layout: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let op = &self.inner;
        let (n, _) = layout.shape().dims2()?;
        let (o1, o2) = layout.contiguous_offsets().ok_or_else(|| {
            candle_core::Error::Msg("fft adjoint needs a contiguous input".into())
        })?;
        let g: Vec<f64> = match storage {
            CpuStorage::F64(v) => v[o1..o2].to_vec(),
            CpuStorage::F32(v) => v[o1..o2].iter().map(|&x| x as f64).collect(),
            _ => {
                return Err(candle_core::Error::Msg(
                    "fft op supports f32 and f64".into(),
                ))
            }
        };
        let out = match op.dir {
            Direction::Forward => {
                // Cotangent [N, 2M] -> [N, T]: undo the c_m weights of irfft_row.
                let mut scaled = g;
                for row in scaled.chunks_mut(2 * op.m) {
                    for k in 0..op.m {
                        let s = 1.0 / op.scale(k);
                        row[k] *= s;
                        row[op.m + k] *= s;
                    }
                }
                op.run_rows(&scaled, n, false)
            }
            Direction::Inverse => {
                // Cotangent [N, T] -> [N, 2M]: (c_m Re G_m, c_m Im G_m).
                let mut spec = op.run_rows(&g, n, true);
                for row in spec.chunks_mut(2 * op.m) {
                    for k in 0..op.m {
                        let s = op.scale(k);
                        row[k] *= s;
                        row[op.m + k] *= s;
                    }
                }
                spec
            }
        };
        let len_out = out.len() / n.max(1);
        let storage = match storage {
            CpuStorage::F32(_) => CpuStorage::F32(out.iter().map(|&x| x as f32).collect()),
            _ => CpuStorage::F64(out),
        };
        Ok((storage, Shape::from((n, len_out))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Var;

    fn rand_vec(n: usize, seed: u64) -> Vec<f64> {
        let mut s = vtcd::rng::SampleStream::new(seed, vtcd::rng::Purpose::Training, 99);
        (0..n).map(|_| s.normal()).collect()
    }

    #[test]
    fn truncated_dft_matches_a_direct_sum_and_inverts_band_limited_signals() {
        let (t, m) = (24, 5);
        let dev = Device::Cpu;
        // A signal made of modes 0..M-1 is reproduced exactly by inverse(forward(x)).
        let x: Vec<f64> = (0..t)
            .map(|n| {
                let th = 2.0 * PI * n as f64 / t as f64;
                0.3 + (2.0 * th).cos() - 0.5 * (4.0 * th).sin()
            })
            .collect();
        for tr in [Transform::Matmul, Transform::Fft] {
            let dft = Dft::new(t, m, tr, DType::F64, &dev).unwrap();
            let xt = Tensor::from_vec(x.clone(), (1, t, 1), &dev).unwrap();
            let spec = dft
                .forward(&xt)
                .unwrap()
                .flatten_all()
                .unwrap()
                .to_vec1::<f64>()
                .unwrap();
            // Direct sums: Re X_2 = T/2, Im X_4 = +T/4 (x = -0.5 sin -> -sum x sin = 0.5 T/2).
            assert!((spec[0] - 0.3 * t as f64).abs() < 1e-12);
            assert!((spec[2] - t as f64 / 2.0).abs() < 1e-12, "{tr:?} {spec:?}");
            assert!(
                (spec[m + 4] - t as f64 / 4.0).abs() < 1e-12,
                "{tr:?} {spec:?}"
            );
            let back = dft.inverse(&dft.forward(&xt).unwrap()).unwrap();
            let back = back.flatten_all().unwrap().to_vec1::<f64>().unwrap();
            for (a, b) in x.iter().zip(&back) {
                assert!((a - b).abs() < 1e-12, "{tr:?}: {a} vs {b}");
            }
        }
    }

    /// Gradients of `L = sum(K(x) * r)` with respect to x, Re R and Im R against central
    /// finite differences. L is linear in each argument, so central differences are exact up
    /// to rounding: with h = 1e-3 in f64 and |L| ~ 10, rounding error ~ 1e-16 * 10 / 1e-3 =
    /// 1e-12; we allow 1e-8 relative.
    #[test]
    fn spectral_conv_gradients_match_finite_differences() {
        let (b, t, c, co, m) = (2, 16, 3, 2, 4);
        let dev = Device::Cpu;
        for tr in [Transform::Matmul, Transform::Fft] {
            let dft = Dft::new(t, m, tr, DType::F64, &dev).unwrap();
            let x = Var::from_vec(rand_vec(b * t * c, 1), (b, t, c), &dev).unwrap();
            let wr = Var::from_vec(rand_vec(m * c * co, 2), (m, c, co), &dev).unwrap();
            let wi = Var::from_vec(rand_vec(m * c * co, 3), (m, c, co), &dev).unwrap();
            let r = Tensor::from_vec(rand_vec(b * t * co, 4), (b, t, co), &dev).unwrap();
            let loss = |x: &Tensor, wr: &Tensor, wi: &Tensor| -> Tensor {
                (spectral_conv(&dft, x, wr, wi).unwrap() * &r)
                    .unwrap()
                    .sum_all()
                    .unwrap()
            };
            let l = loss(x.as_tensor(), wr.as_tensor(), wi.as_tensor());
            let grads = l.backward().unwrap();
            for (k, var) in [&x, &wr, &wi].into_iter().enumerate() {
                let g = grads
                    .get(var.as_tensor())
                    .unwrap()
                    .flatten_all()
                    .unwrap()
                    .to_vec1::<f64>()
                    .unwrap();
                let base = var
                    .as_tensor()
                    .flatten_all()
                    .unwrap()
                    .to_vec1::<f64>()
                    .unwrap();
                let h = 1e-3;
                for (i, gi) in g.iter().enumerate() {
                    let eval = |d: f64| -> f64 {
                        let mut p = base.clone();
                        p[i] += d;
                        let pt = Tensor::from_vec(p, var.as_tensor().shape(), &dev).unwrap();
                        let args: [Tensor; 3] = std::array::from_fn(|j| {
                            if j == k {
                                pt.clone()
                            } else {
                                [&x, &wr, &wi][j].as_tensor().clone()
                            }
                        });
                        loss(&args[0], &args[1], &args[2])
                            .to_scalar::<f64>()
                            .unwrap()
                    };
                    let fd = (eval(h) - eval(-h)) / (2.0 * h);
                    assert!(
                        (fd - gi).abs() <= 1e-8 * (1.0 + fd.abs()),
                        "{tr:?} arg {k} index {i}: autograd {gi} vs finite difference {fd}"
                    );
                }
            }
        }
    }

    #[test]
    fn both_transforms_agree_in_f32() {
        let (b, t, c, m) = (2, 50, 4, 8);
        let dev = Device::Cpu;
        let x = Tensor::from_vec(rand_vec(b * t * c, 5), (b, t, c), &dev)
            .unwrap()
            .to_dtype(DType::F32)
            .unwrap();
        let wr = Tensor::from_vec(rand_vec(m * c * c, 6), (m, c, c), &dev)
            .unwrap()
            .to_dtype(DType::F32)
            .unwrap();
        let wi = Tensor::from_vec(rand_vec(m * c * c, 7), (m, c, c), &dev)
            .unwrap()
            .to_dtype(DType::F32)
            .unwrap();
        let ys: Vec<Vec<f32>> = [Transform::Matmul, Transform::Fft]
            .into_iter()
            .map(|tr| {
                let dft = Dft::new(t, m, tr, DType::F32, &dev).unwrap();
                spectral_conv(&dft, &x, &wr, &wi)
                    .unwrap()
                    .flatten_all()
                    .unwrap()
                    .to_vec1()
                    .unwrap()
            })
            .collect();
        // f32 sums of ~50 terms of size ~1: 1e-5 absolute.
        for (a, b) in ys[0].iter().zip(&ys[1]) {
            assert!((a - b).abs() < 1e-4, "{a} vs {b}");
        }
    }
}
