//! The 1-D spectral convolution `K v = F^-1( R . F v )` on the lowest `M` Fourier modes of
//! channel-major activations `v [C, B, T]`, in two interchangeable implementations:
//!
//! - [`Transform::Fused`] (CPU): one custom op per call with rustfft, complex mode mixing and a
//!   hand-written backward pass ([`crate::kernels`]); cost `O(T log T)` per row.
//! - [`Transform::Matmul`] (any device, the CUDA path and the reference): precomputed bases,
//!   with `theta_mt = 2 pi m t / T`,
//!   ```text
//!   forward  [T, 2M]:  Re X_m =  sum_t x_t cos(theta_mt),   Im X_m = -sum_t x_t sin(theta_mt)
//!   inverse  [2M, T]:  y_t = sum_m c_m (Re Y_m cos(theta_mt) - Im Y_m sin(theta_mt)),
//!                      c_0 = 1/T, c_m = 2/T (m >= 1)
//!   ```
//!   two matrix products that candle differentiates; cost `4 M T` per row.
//!
//! Mode mixing is complex and per mode: `Y_m[o] = sum_c X_m[c] R_m[c, o]`, written for the
//! composition as one real batched product `[Re X, Im X] [[Re R, Im R], [-Im R, Re R]]` of
//! shape `[M, B, 2C] x [M, 2C, 2C'] -> [M, B, 2C']`. The measurement that picked the fused
//! kernels is in BENCHMARKS.md (Training engine).

use crate::kernels::{self, RealDft};
use crate::Result;
use candle_core::{DType, Device, Tensor};
use std::f64::consts::PI;
use std::sync::Arc;

/// How the spectral convolution is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transform {
    /// Dense cosine/sine bases, candle ops only (any device).
    Matmul,
    /// Fused rustfft custom ops with hand-written backward passes (CPU, f32).
    Fused,
}

impl Transform {
    /// The fast implementation for a device: fused kernels on the CPU, the composition
    /// elsewhere.
    pub fn for_device(device: &Device) -> Self {
        if device.is_cpu() {
            Transform::Fused
        } else {
            Transform::Matmul
        }
    }
}

/// The truncated real DFT of length `T` on `M` modes, in one of the two implementations.
#[derive(Debug, Clone)]
pub struct Dft {
    /// Time points.
    pub t_points: usize,
    /// Kept modes.
    pub modes: usize,
    transform: Transform,
    bases: Option<(Tensor, Tensor)>,
    plan: Option<Arc<RealDft>>,
}

impl Dft {
    /// Bases or plan for `t_points` and `modes` (`2 modes <= t_points`) in `dtype` on
    /// `device`.
    pub fn new(
        t_points: usize,
        modes: usize,
        transform: Transform,
        dtype: DType,
        device: &Device,
    ) -> Result<Self> {
        let (t, m) = (t_points, modes);
        let (bases, plan) = match transform {
            Transform::Fused => (None, Some(Arc::new(RealDft::new(t, m)))),
            Transform::Matmul => {
                let mut fwd = vec![0.0f64; t * 2 * m];
                let mut inv = vec![0.0f64; 2 * m * t];
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
                        fwd[n * 2 * m + k] = co;
                        fwd[n * 2 * m + m + k] = -s;
                        inv[k * t + n] = c * co;
                        inv[(m + k) * t + n] = -c * s;
                    }
                }
                (
                    Some((
                        Tensor::from_vec(fwd, (t, 2 * m), device)?.to_dtype(dtype)?,
                        Tensor::from_vec(inv, (2 * m, t), device)?.to_dtype(dtype)?,
                    )),
                    None,
                )
            }
        };
        Ok(Self {
            t_points,
            modes,
            transform,
            bases,
            plan,
        })
    }

    /// The implementation in use.
    pub fn transform(&self) -> Transform {
        self.transform
    }

    /// The rustfft plan of the fused implementation.
    pub fn plan(&self) -> Option<&Arc<RealDft>> {
        self.plan.as_ref()
    }

    /// `K x` of `x [C, B, T]` with `wr, wi [M, C, C']`: `[C', B, T]`.
    pub fn conv(&self, x: &Tensor, wr: &Tensor, wi: &Tensor) -> Result<Tensor> {
        match (&self.plan, &self.bases) {
            (Some(plan), _) => kernels::spectral_conv(plan, x, wr, wi),
            (None, Some((fwd, inv))) => {
                let (c, b, t) = x.dims3()?;
                let m = self.modes;
                let spec = x.reshape((c * b, t))?.matmul(fwd)?; // [C B, 2M]
                let mixed = mix_modes(&spec.reshape((c, b, 2 * m))?, wr, wi)?; // [C', B, 2M]
                let co = mixed.dim(0)?;
                Ok(mixed
                    .reshape((co * b, 2 * m))?
                    .matmul(inv)?
                    .reshape((co, b, t))?)
            }
            (None, None) => unreachable!("a Dft has bases or a plan"),
        }
    }
}

/// Complex mode mixing of spectra `x [C, B, 2M]` (columns `Re X_0..M-1, Im X_0..M-1`) with
/// `wr, wi [M, C, C']`: `[C', B, 2M]`.
pub fn mix_modes(x: &Tensor, wr: &Tensor, wi: &Tensor) -> Result<Tensor> {
    let (c, b, m2) = x.dims3()?;
    let m = m2 / 2;
    let co = wr.dim(2)?;
    let xm = x
        .reshape((c, b, 2, m))?
        .permute((3, 1, 2, 0))?
        .contiguous()?
        .reshape((m, b, 2 * c))?;
    let top = Tensor::cat(&[wr, wi], 2)?;
    let bottom = Tensor::cat(&[&wi.neg()?, wr], 2)?;
    let w = Tensor::cat(&[&top, &bottom], 1)?; // [M, 2C, 2C']
    let y = xm.matmul(&w)?; // [M, B, 2C']
    Ok(y.reshape((m, b, 2, co))?
        .permute((3, 1, 2, 0))?
        .contiguous()?
        .reshape((co, b, 2 * m))?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Var;

    fn rand_vec(n: usize, seed: u64) -> Vec<f32> {
        let mut s =
            mbd_dataset::rng::SampleStream::new(seed, mbd_dataset::rng::Purpose::Training, 99);
        (0..n).map(|_| s.normal() as f32).collect()
    }

    #[test]
    fn band_limited_signals_pass_unchanged_through_both_implementations() {
        let (t, m) = (24, 5);
        let dev = Device::Cpu;
        // Modes 0..M-1 only; identity weights (R_m = I) must reproduce the signal.
        let x: Vec<f32> = (0..t)
            .map(|n| {
                let th = 2.0 * PI * n as f64 / t as f64;
                (0.3 + (2.0 * th).cos() - 0.5 * (4.0 * th).sin()) as f32
            })
            .collect();
        let xt = Tensor::from_vec(x.clone(), (1, 1, t), &dev).unwrap();
        let wr = Tensor::ones((m, 1, 1), DType::F32, &dev).unwrap();
        let wi = Tensor::zeros((m, 1, 1), DType::F32, &dev).unwrap();
        for tr in [Transform::Matmul, Transform::Fused] {
            let dft = Dft::new(t, m, tr, DType::F32, &dev).unwrap();
            let y = dft.conv(&xt, &wr, &wi).unwrap();
            let y = y.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            for (a, b) in x.iter().zip(&y) {
                assert!((a - b).abs() < 1e-5, "{tr:?}: {a} vs {b}");
            }
        }
    }

    /// The fused op against the composition: values, and the gradients of
    /// `L = sum(K(x) * r)` with respect to x, Re R and Im R (f32, odd row count so the
    /// unpaired last row is covered, padded-looking length 45 = 3^2 5).
    #[test]
    fn fused_values_and_gradients_match_the_composition() {
        let (c, b, t, co, m) = (3, 3, 45, 4, 9);
        let dev = Device::Cpu;
        let x = Var::from_vec(rand_vec(c * b * t, 1), (c, b, t), &dev).unwrap();
        let wr = Var::from_vec(rand_vec(m * c * co, 2), (m, c, co), &dev).unwrap();
        let wi = Var::from_vec(rand_vec(m * c * co, 3), (m, c, co), &dev).unwrap();
        let r = Tensor::from_vec(rand_vec(co * b * t, 4), (co, b, t), &dev).unwrap();
        let run = |tr: Transform| {
            let dft = Dft::new(t, m, tr, DType::F32, &dev).unwrap();
            let y = dft
                .conv(x.as_tensor(), wr.as_tensor(), wi.as_tensor())
                .unwrap();
            let g = (&y * &r).unwrap().sum_all().unwrap().backward().unwrap();
            let flat = |t: &Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            let grads: Vec<Vec<f32>> = [&x, &wr, &wi]
                .iter()
                .map(|v| flat(g.get(v.as_tensor()).unwrap()))
                .collect();
            (flat(&y), grads)
        };
        let (y_ref, g_ref) = run(Transform::Matmul);
        let (y_fused, g_fused) = run(Transform::Fused);
        let close = |a: &[f32], b: &[f32], what: &str| {
            let scale = a.iter().fold(0.0f32, |s, v| s.max(v.abs()));
            for (i, (p, q)) in a.iter().zip(b).enumerate() {
                assert!(
                    (p - q).abs() <= 2e-5 * scale.max(1.0),
                    "{what}[{i}]: composition {p} vs fused {q}"
                );
            }
        };
        close(&y_ref, &y_fused, "y");
        for (k, name) in ["dx", "dwr", "dwi"].iter().enumerate() {
            close(&g_ref[k], &g_fused[k], name);
        }
    }

    /// The composition's gradients against central finite differences in f64 (the reference
    /// the fused kernels are checked against is itself checked here). L is linear in each
    /// argument, so central differences are exact up to rounding.
    #[test]
    fn composition_gradients_match_finite_differences() {
        let (c, b, t, co, m) = (2, 2, 16, 3, 4);
        let dev = Device::Cpu;
        let f64v =
            |n: usize, s: u64| -> Vec<f64> { rand_vec(n, s).into_iter().map(f64::from).collect() };
        let dft = Dft::new(t, m, Transform::Matmul, DType::F64, &dev).unwrap();
        let x = Var::from_vec(f64v(c * b * t, 1), (c, b, t), &dev).unwrap();
        let wr = Var::from_vec(f64v(m * c * co, 2), (m, c, co), &dev).unwrap();
        let wi = Var::from_vec(f64v(m * c * co, 3), (m, c, co), &dev).unwrap();
        let r = Tensor::from_vec(f64v(co * b * t, 4), (co, b, t), &dev).unwrap();
        let loss = |x: &Tensor, wr: &Tensor, wi: &Tensor| -> Tensor {
            (dft.conv(x, wr, wi).unwrap() * &r)
                .unwrap()
                .sum_all()
                .unwrap()
        };
        let grads = loss(x.as_tensor(), wr.as_tensor(), wi.as_tensor())
            .backward()
            .unwrap();
        let vars = [&x, &wr, &wi];
        for (k, var) in vars.iter().enumerate() {
            let g = grads.get(var.as_tensor()).unwrap();
            let g = g.flatten_all().unwrap().to_vec1::<f64>().unwrap();
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
                    let args: Vec<Tensor> = (0..3)
                        .map(|j| {
                            if j == k {
                                pt.clone()
                            } else {
                                vars[j].as_tensor().clone()
                            }
                        })
                        .collect();
                    loss(&args[0], &args[1], &args[2])
                        .to_scalar::<f64>()
                        .unwrap()
                };
                let fd = (eval(h) - eval(-h)) / (2.0 * h);
                assert!(
                    (fd - gi).abs() <= 1e-8 * (1.0 + fd.abs()),
                    "arg {k} index {i}: autograd {gi} vs finite difference {fd}"
                );
            }
        }
    }
}
