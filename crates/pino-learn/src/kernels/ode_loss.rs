//! The ODE-residual losses of algorithms 2 and 3 as one fused CPU op with its backward pass.
//!
//! From a z-scored prediction `u_n [B, T, 14]` (10 vehicle DOFs, then `z_r1..z_r4`), the
//! physical states at interior points (`z = s u + m`, central differences for `v` and `a`, as in
//! [`crate::physics::derivatives`]) enter the ten vehicle equations of `vtcd::vehicle`
//! (evaluated by [`vtcd::vehicle::Vehicle::residuals`], the solver's own code), with the Hertz
//! forces `P_i = (max(0, z_wi - z_ri - eta_i) / G)^{3/2}`. The loss is
//! ```text
//! L = mean_{k,n,i} c_{k,i} |R_i(k, n)|     c = 1 / F_ref (global)  or  rho / phi_{k,i} (phi)
//! ```
//! The residual is linear in `(z, v, a, P)`; its Jacobian is taken per sample by evaluating the
//! residual on unit vectors (exact for a linear map), so the backward pass is
//! `dL/d(z, v, a, P) = J^T (c sign R) / (B (T-2) 10)`, then `dP/d delta` of Hertz, then the
//! transposed stencils.

use candle_core::{CpuStorage, CustomOp1, Layout, Shape, Tensor};
use vtcd::vehicle::Vehicle;

const DOFS: usize = 10;
const WHEELS: usize = 4;
/// Columns of the residual's Jacobian: `z`, `v`, `a` (10 each), then the 4 contact forces.
const COLS: usize = 3 * DOFS + WHEELS;

/// How residuals are weighted.
#[derive(Debug, Clone)]
pub enum OdeWeights {
    /// `1 / F_ref` for every equation (PINO).
    Global {
        /// Force scale (N).
        f_ref: f64,
    },
    /// `rho / phi_{k,i}` (PINO-MBD with ODE magnitude weights), `phi [B, 10]`.
    Phi {
        /// Residual level.
        rho: f64,
        /// Weights per sample and equation (N, N m).
        phi: Vec<f64>,
    },
}

/// Everything the residual loss of one batch needs besides the prediction.
pub struct OdeLoss {
    /// One vehicle per sample (its parameters and gravity).
    pub vehicles: Vec<Vehicle>,
    /// Irregularity under each wheel at interior points `[B, T-2, 4]` (m).
    pub eta: Vec<f64>,
    /// Output channel means (14).
    pub mean: Vec<f64>,
    /// Output channel stds (14).
    pub std: Vec<f64>,
    /// Time step (s).
    pub dt: f64,
    /// Hertz constant (m/N^(2/3)).
    pub hertz_g: f64,
    /// Residual weights.
    pub weights: OdeWeights,
}

/// Physical state of sample `k` at interior point `n`: `(z, v, a, z_r)`.
struct State {
    z: [f64; DOFS],
    v: [f64; DOFS],
    a: [f64; DOFS],
    z_r: [f64; WHEELS],
}

impl OdeLoss {
    fn state(&self, u: &[f32], base: usize, c: usize, n: usize) -> State {
        let at = |k: usize, ch: usize| u[base + k * c + ch] as f64;
        let mut s = State {
            z: [0.0; DOFS],
            v: [0.0; DOFS],
            a: [0.0; DOFS],
            z_r: [0.0; WHEELS],
        };
        for i in 0..DOFS {
            let (prev, mid, next) = (at(n - 1, i), at(n, i), at(n + 1, i));
            s.z[i] = mid * self.std[i] + self.mean[i];
            s.v[i] = (next - prev) / (2.0 * self.dt) * self.std[i];
            s.a[i] = (next - 2.0 * mid + prev) / (self.dt * self.dt) * self.std[i];
        }
        for w in 0..WHEELS {
            s.z_r[w] = at(n, DOFS + w) * self.std[DOFS + w] + self.mean[DOFS + w];
        }
        s
    }

    fn delta(&self, s: &State, k: usize, t2: usize, n: usize, w: usize) -> f64 {
        s.z[6 + w] - s.z_r[w] - self.eta[(k * t2 + n - 1) * WHEELS + w]
    }

    fn contact(&self, s: &State, k: usize, t2: usize, n: usize) -> [f64; WHEELS] {
        std::array::from_fn(|w| {
            vtcd::contact::contact_force(self.delta(s, k, t2, n, w), self.hertz_g)
        })
    }

    fn weight(&self, k: usize, i: usize) -> f64 {
        match &self.weights {
            OdeWeights::Global { f_ref } => 1.0 / f_ref,
            OdeWeights::Phi { rho, phi } => rho / phi[k * DOFS + i],
        }
    }

    /// Jacobian `[10, COLS]` of vehicle `k`'s residual in `(z, v, a, P)`.
    fn jacobian(&self, k: usize) -> [[f64; COLS]; DOFS] {
        let veh = &self.vehicles[k];
        let zero = [0.0; DOFS];
        let base = veh.residuals(&zero, &zero, &zero, &[0.0; WHEELS]);
        let mut jac = [[0.0; COLS]; DOFS];
        for col in 0..COLS {
            let mut x = [[0.0; DOFS]; 3];
            let mut p = [0.0; WHEELS];
            if col < 3 * DOFS {
                x[col / DOFS][col % DOFS] = 1.0;
            } else {
                p[col - 3 * DOFS] = 1.0;
            }
            let r = veh.residuals(&x[0], &x[1], &x[2], &p);
            for i in 0..DOFS {
                jac[i][col] = r[i] - base[i];
            }
        }
        jac
    }
}

fn dims(shape: &Shape) -> candle_core::Result<(usize, usize, usize)> {
    let (b, t, c) = shape.dims3()?;
    if t < 3 || c < DOFS + WHEELS {
        return Err(candle_core::Error::Msg(format!(
            "fused ODE loss: prediction {shape:?} needs >= 3 points and >= 14 channels"
        )));
    }
    Ok((b, t, c))
}

impl CustomOp1 for OdeLoss {
    fn name(&self) -> &'static str {
        "fused-ode-loss"
    }

    fn cpu_fwd(
        &self,
        storage: &CpuStorage,
        layout: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (b, t, c) = dims(layout.shape())?;
        let u = super::cpu_f32(storage, layout, "fused ODE loss", "prediction")?;
        let mut total = 0.0f64;
        for k in 0..b {
            let w: [f64; DOFS] = std::array::from_fn(|i| self.weight(k, i));
            for n in 1..t - 1 {
                let s = self.state(u, k * t * c, c, n);
                let p = self.contact(&s, k, t - 2, n);
                let r = self.vehicles[k].residuals(&s.z, &s.v, &s.a, &p);
                total += r.iter().zip(&w).map(|(r, w)| r.abs() * w).sum::<f64>();
            }
        }
        let mean = total / (b * (t - 2) * DOFS) as f64;
        Ok((CpuStorage::F32(vec![mean as f32]), Shape::from(())))
    }

    fn bwd(
        &self,
        arg: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        let (b, t, c) = dims(arg.shape())?;
        let upstream = grad_res
            .to_dtype(candle_core::DType::F64)?
            .to_scalar::<f64>()?;
        let scale = upstream / (b * (t - 2) * DOFS) as f64;
        let grad = super::with_host(arg, |u| {
            let mut g = vec![0.0f64; u.len()];
            for k in 0..b {
                let jac = self.jacobian(k);
                let base = k * t * c;
                for n in 1..t - 1 {
                    let s = self.state(u, base, c, n);
                    let p = self.contact(&s, k, t - 2, n);
                    let r = self.vehicles[k].residuals(&s.z, &s.v, &s.a, &p);
                    // dL/dR, then dL/d(z, v, a, P) = J^T dL/dR.
                    let dr: [f64; DOFS] =
                        std::array::from_fn(|i| scale * self.weight(k, i) * r[i].signum());
                    let mut dx = [0.0f64; COLS];
                    for (i, row) in jac.iter().enumerate() {
                        if dr[i] != 0.0 {
                            for (d, j) in dx.iter_mut().zip(row) {
                                *d += dr[i] * j;
                            }
                        }
                    }
                    // Hertz: dP/d delta = 3/2 sqrt(delta / G) / G for delta > 0.
                    let mut d_delta = [0.0f64; WHEELS];
                    for (w, dd) in d_delta.iter_mut().enumerate() {
                        let delta = self.delta(&s, k, t - 2, n, w);
                        if delta > 0.0 {
                            *dd = dx[3 * DOFS + w] * 1.5 * (delta / self.hertz_g).sqrt()
                                / self.hertz_g;
                        }
                    }
                    let mut dz = [0.0f64; DOFS];
                    dz.copy_from_slice(&dx[..DOFS]);
                    for w in 0..WHEELS {
                        dz[6 + w] += d_delta[w];
                        // z_r enters delta with a minus sign; it is a plain value (no stencil).
                        g[base + n * c + DOFS + w] -= d_delta[w] * self.std[DOFS + w];
                    }
                    for i in 0..DOFS {
                        let sd = self.std[i];
                        let gv = dx[DOFS + i] * sd / (2.0 * self.dt);
                        let ga = dx[2 * DOFS + i] * sd / (self.dt * self.dt);
                        g[base + (n + 1) * c + i] += gv + ga;
                        g[base + (n - 1) * c + i] += -gv + ga;
                        g[base + n * c + i] += dz[i] * sd - 2.0 * ga;
                    }
                }
            }
            g.into_iter().map(|x| x as f32).collect::<Vec<f32>>()
        })?;
        Ok(Some(Tensor::from_vec(grad, arg.shape(), arg.device())?))
    }
}
