//! The direct-derivative loss `L_deriv` as one fused CPU op with its backward pass.
//!
//! For a z-scored prediction `u_n [B, T, C]` whose first `D` channels are the vehicle DOFs
//! (channel std `s_c`), targets `v*, a* [B, T-2, D]` z-scored with `(mv_c, sv_c)` and
//! `(ma_c, sa_c)`, at interior points `n = 1..T-2`:
//! ```text
//! p_v[n,c] = (s_c (u[n+1,c] - u[n-1,c]) / (2 dt) - mv_c) / sv_c
//! p_a[n,c] = (s_c (u[n+1,c] - 2 u[n,c] + u[n-1,c]) / dt^2 - ma_c) / sa_c
//! L = mean_k ( ||p_v,k - v*_k|| / ||v*_k|| + ||p_a,k - a*_k|| / ||a*_k|| )
//! ```
//! the same function as the candle composition in [`crate::loss`] (which the tests compare it
//! with). Sums are accumulated in f64. The backward pass applies the transposed stencils to
//! `dL/dp = (p - y) / (B ||p - y|| ||y||)`.

use candle_core::{CpuStorage, CustomOp1, Layout, Shape, Tensor};

/// Statistics and targets of one batch's derivative loss.
pub struct DerivativeLoss {
    /// Vehicle channels `D` (the first `D` of the prediction).
    pub dofs: usize,
    /// Time step (s).
    pub dt: f64,
    /// Std of each predicted channel (first `D` used).
    pub out_std: Vec<f64>,
    /// Velocity statistics `(mean, std)` per DOF.
    pub velocity: (Vec<f64>, Vec<f64>),
    /// Acceleration statistics `(mean, std)` per DOF.
    pub acceleration: (Vec<f64>, Vec<f64>),
    /// z-scored target velocities `[B, T-2, D]`.
    pub v_target: Vec<f32>,
    /// z-scored target accelerations `[B, T-2, D]`.
    pub a_target: Vec<f32>,
}

impl DerivativeLoss {
    /// Predicted z-scored derivatives of sample `k` at interior point `n`, channel `c`.
    #[inline]
    fn predicted(&self, u: &[f32], base: usize, c_total: usize, n: usize, c: usize) -> (f64, f64) {
        let prev = u[base + (n - 1) * c_total + c] as f64;
        let mid = u[base + n * c_total + c] as f64;
        let next = u[base + (n + 1) * c_total + c] as f64;
        let s = self.out_std[c];
        let v = (s * (next - prev) / (2.0 * self.dt) - self.velocity.0[c]) / self.velocity.1[c];
        let a = (s * (next - 2.0 * mid + prev) / (self.dt * self.dt) - self.acceleration.0[c])
            / self.acceleration.1[c];
        (v, a)
    }

    /// Per sample `(||p_v - v*||^2, ||v*||^2, ||p_a - a*||^2, ||a*||^2)`.
    fn sums(&self, u: &[f32], b: usize, t: usize, c_total: usize) -> Vec<[f64; 4]> {
        let d = self.dofs;
        (0..b)
            .map(|k| {
                let mut acc = [0.0f64; 4];
                for n in 1..t - 1 {
                    for c in 0..d {
                        let (pv, pa) = self.predicted(u, k * t * c_total, c_total, n, c);
                        let i = (k * (t - 2) + n - 1) * d + c;
                        let (yv, ya) = (self.v_target[i] as f64, self.a_target[i] as f64);
                        acc[0] += (pv - yv) * (pv - yv);
                        acc[1] += yv * yv;
                        acc[2] += (pa - ya) * (pa - ya);
                        acc[3] += ya * ya;
                    }
                }
                acc
            })
            .collect()
    }
}

fn dims(shape: &Shape, dofs: usize) -> candle_core::Result<(usize, usize, usize)> {
    let (b, t, c) = shape.dims3()?;
    if t < 3 || c < dofs {
        return Err(candle_core::Error::Msg(format!(
            "fused derivative loss: prediction {shape:?} needs >= 3 points and >= {dofs} channels"
        )));
    }
    Ok((b, t, c))
}

impl CustomOp1 for DerivativeLoss {
    fn name(&self) -> &'static str {
        "fused-derivative-loss"
    }

    fn cpu_fwd(
        &self,
        storage: &CpuStorage,
        layout: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (b, t, c) = dims(layout.shape(), self.dofs)?;
        let u = super::cpu_f32(storage, layout, "fused derivative loss", "prediction")?;
        let loss: f64 = self
            .sums(u, b, t, c)
            .iter()
            .map(|s| (s[0] / s[1]).sqrt() + (s[2] / s[3]).sqrt())
            .sum::<f64>()
            / b as f64;
        Ok((CpuStorage::F32(vec![loss as f32]), Shape::from(())))
    }

    fn bwd(
        &self,
        arg: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        let (b, t, c_total) = dims(arg.shape(), self.dofs)?;
        let upstream = grad_res
            .to_dtype(candle_core::DType::F64)?
            .to_scalar::<f64>()?;
        let d = self.dofs;
        let grad = super::with_host(arg, |u| {
            let sums = self.sums(u, b, t, c_total);
            let mut g = vec![0.0f64; u.len()];
            for (k, s) in sums.iter().enumerate() {
                let base = k * t * c_total;
                // dL/dp = (p - y) / (B ||p - y|| ||y||), zero where the residual vanishes.
                let scale = |num: f64, den: f64| {
                    let r = (num * den).sqrt();
                    if r > 0.0 {
                        upstream / (b as f64 * r)
                    } else {
                        0.0
                    }
                };
                let (kv, ka) = (scale(s[0], s[1]), scale(s[2], s[3]));
                for n in 1..t - 1 {
                    for c in 0..d {
                        let (pv, pa) = self.predicted(u, base, c_total, n, c);
                        let i = (k * (t - 2) + n - 1) * d + c;
                        let gv = kv * (pv - self.v_target[i] as f64) * self.out_std[c]
                            / (2.0 * self.dt * self.velocity.1[c]);
                        let ga = ka * (pa - self.a_target[i] as f64) * self.out_std[c]
                            / (self.dt * self.dt * self.acceleration.1[c]);
                        g[base + (n + 1) * c_total + c] += gv + ga;
                        g[base + (n - 1) * c_total + c] += -gv + ga;
                        g[base + n * c_total + c] += -2.0 * ga;
                    }
                }
            }
            g.into_iter().map(|x| x as f32).collect::<Vec<f32>>()
        })?;
        Ok(Some(Tensor::from_vec(grad, arg.shape(), arg.device())?))
    }
}
