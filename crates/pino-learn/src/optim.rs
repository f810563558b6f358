//! Adam (Kingma & Ba) with an externally set learning rate (the caller decays it; training
//! takes it from its configuration's schedule). Moments are plain tensors so that a checkpoint can
//! store and restore them exactly:
//! ```text
//! m <- b1 m + (1 - b1) g        v <- b2 v + (1 - b2) g^2
//! p <- p - lr (m / (1 - b1^s)) / (sqrt(v / (1 - b2^s)) + eps)      s = step count (1-based)
//! ```
//! with b1 = 0.9, b2 = 0.999, eps = 1e-8 (the usual defaults). [`Average`]: the variables'
//! exponential moving average over the steps.

use crate::Result;
use candle_core::backprop::GradStore;
use candle_core::{Tensor, Var};

/// Adam's state for a fixed list of variables.
#[derive(Debug, Clone)]
pub struct Adam {
    /// First moments, one per variable.
    pub m: Vec<Tensor>,
    /// Second moments.
    pub v: Vec<Tensor>,
    /// Steps taken.
    pub step: u64,
    /// Decay of the first moment.
    pub beta1: f64,
    /// Decay of the second moment.
    pub beta2: f64,
    /// Denominator guard.
    pub eps: f64,
}

impl Adam {
    /// Zero moments for `vars`.
    pub fn new(vars: &[(String, Var)]) -> Result<Self> {
        let zeros = |v: &Var| v.as_tensor().zeros_like();
        Ok(Self {
            m: vars
                .iter()
                .map(|(_, v)| zeros(v))
                .collect::<candle_core::Result<_>>()?,
            v: vars
                .iter()
                .map(|(_, v)| zeros(v))
                .collect::<candle_core::Result<_>>()?,
            step: 0,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        })
    }

    /// One update with learning rate `lr`; a variable without gradient is left alone.
    pub fn step(&mut self, vars: &[(String, Var)], grads: &GradStore, lr: f64) -> Result<()> {
        self.step += 1;
        let c1 = 1.0 - self.beta1.powi(self.step as i32);
        let c2 = 1.0 - self.beta2.powi(self.step as i32);
        for (i, (_, var)) in vars.iter().enumerate() {
            // Gradients (and everything computed from them) carry the backward graph, which
            // references this step's forward graph: detach, or the moments chain every step's
            // graph together and memory grows without bound.
            let Some(g) = grads.get(var.as_tensor()).map(Tensor::detach) else {
                continue;
            };
            if var.device().is_cpu() && var.dtype() == candle_core::DType::F32 {
                let (m, v) = self.fused_update(var, &g, i, lr, c1, c2)?;
                self.m[i] = m;
                self.v[i] = v;
                continue;
            }
            let g = &g;
            let m = ((&self.m[i] * self.beta1)? + (g * (1.0 - self.beta1))?)?;
            let v = ((&self.v[i] * self.beta2)? + (g.sqr()? * (1.0 - self.beta2))?)?;
            let denom = ((&v * (1.0 / c2))?.sqrt()? + self.eps)?;
            let update = ((&m * (lr / c1))? / denom)?;
            var.set(&(var.as_tensor().detach() - update)?)?;
            self.m[i] = m.detach();
            self.v[i] = v.detach();
        }
        Ok(())
    }

    /// The same update as the candle composition in one pass over host memory (CPU, f32):
    /// returns the new moments and sets the variable.
    fn fused_update(
        &self,
        var: &Var,
        g: &Tensor,
        i: usize,
        lr: f64,
        c1: f64,
        c2: f64,
    ) -> Result<(Tensor, Tensor)> {
        let host = |t: &Tensor| t.flatten_all()?.to_vec1::<f32>();
        let (mut p, g) = (host(var.as_tensor())?, host(g)?);
        let (mut m, mut v) = (host(&self.m[i])?, host(&self.v[i])?);
        let (b1, b2) = (self.beta1 as f32, self.beta2 as f32);
        let (one_b1, one_b2) = ((1.0 - self.beta1) as f32, (1.0 - self.beta2) as f32);
        let (inv_c2, step, eps) = ((1.0 / c2) as f32, (lr / c1) as f32, self.eps as f32);
        for k in 0..p.len() {
            m[k] = m[k] * b1 + g[k] * one_b1;
            v[k] = v[k] * b2 + g[k] * g[k] * one_b2;
            p[k] -= m[k] * step / ((v[k] * inv_c2).sqrt() + eps);
        }
        let shape = var.shape().clone();
        let dev = var.device().clone();
        var.set(&Tensor::from_vec(p, shape.clone(), &dev)?)?;
        Ok((
            Tensor::from_vec(m, shape.clone(), &dev)?,
            Tensor::from_vec(v, shape, &dev)?,
        ))
    }
}

/// An exponential moving average of the variables over the optimiser's steps (Polyak
/// averaging): after each step `a <- d a + (1 - d) p`, started from the initial values. The
/// average of the last `~1 / (1 - d)` steps is a model of its own, usually smoother than the
/// last iterate where the steps at a fixed learning rate wander around a minimum.
#[derive(Debug, Clone)]
pub struct Average {
    /// The averages, one per variable.
    pub values: Vec<Tensor>,
    /// The decay `d` per step, in `[0, 1)`.
    pub decay: f64,
}

impl Average {
    /// The average of `vars` started from their current values.
    pub fn new(vars: &[(String, Var)], decay: f64) -> Result<Self> {
        Ok(Self {
            values: vars
                .iter()
                .map(|(_, v)| v.as_tensor().copy())
                .collect::<candle_core::Result<_>>()?,
            decay,
        })
    }

    /// One step: `a <- d a + (1 - d) p` for every variable.
    pub fn update(&mut self, vars: &[(String, Var)]) -> Result<()> {
        let d = self.decay;
        for (a, (_, var)) in self.values.iter_mut().zip(vars) {
            *a = ((&*a * d)? + (var.as_tensor().detach() * (1.0 - d))?)?.detach();
        }
        Ok(())
    }

    /// Runs `f` with the variables set to the averages, then restores them.
    pub fn with_average<T>(
        &self,
        vars: &[(String, Var)],
        f: impl FnOnce() -> Result<T>,
    ) -> Result<T> {
        let raw: Vec<Tensor> = vars
            .iter()
            .map(|(_, v)| v.as_tensor().copy())
            .collect::<candle_core::Result<_>>()?;
        self.install(vars)?;
        let out = f();
        for ((_, var), r) in vars.iter().zip(&raw) {
            var.set(r)?;
        }
        out
    }

    /// Sets the variables to the averages.
    pub fn install(&self, vars: &[(String, Var)]) -> Result<()> {
        for ((_, var), a) in vars.iter().zip(&self.values) {
            var.set(a)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    /// The average is the closed-form weighted sum of the iterates; decay 0 is the last one,
    /// and `with_average` leaves the variables as they were.
    #[test]
    fn the_average_weights_the_iterates_geometrically() {
        let dev = Device::Cpu;
        let var = Var::from_tensor(&Tensor::new(&[0.0f32], &dev).unwrap()).unwrap();
        let vars = vec![("p".to_owned(), var)];
        let mut avg = Average::new(&vars, 0.5).unwrap();
        let mut last = Average::new(&vars, 0.0).unwrap();
        for x in [4.0f32, 8.0] {
            vars[0].1.set(&Tensor::new(&[x], &dev).unwrap()).unwrap();
            avg.update(&vars).unwrap();
            last.update(&vars).unwrap();
        }
        // a = 0.5 (0.5 * 0 + 0.5 * 4) + 0.5 * 8 = 5.
        let a: Vec<f32> = avg.values[0].to_vec1().unwrap();
        assert_eq!(a, [5.0]);
        assert_eq!(last.values[0].to_vec1::<f32>().unwrap(), [8.0]);
        let seen = avg
            .with_average(&vars, || Ok(vars[0].1.as_tensor().to_vec1::<f32>()?))
            .unwrap();
        assert_eq!(seen, [5.0]);
        assert_eq!(vars[0].1.as_tensor().to_vec1::<f32>().unwrap(), [8.0]);
    }

    #[test]
    fn first_adam_step_moves_each_parameter_by_lr() {
        // After one step m_hat = g and v_hat = g^2, so the update is lr * g / (|g| + eps).
        let dev = Device::Cpu;
        let p = Var::from_vec(vec![1.0f32, -2.0], 2, &dev).unwrap();
        let vars = vec![("p".to_owned(), p.clone())];
        let loss = (p.as_tensor().sqr().unwrap() * 3.0)
            .unwrap()
            .sum_all()
            .unwrap();
        let grads = loss.backward().unwrap();
        let mut adam = Adam::new(&vars).unwrap();
        adam.step(&vars, &grads, 0.1).unwrap();
        let after = p.as_tensor().to_vec1::<f32>().unwrap();
        assert!(
            (after[0] - 0.9).abs() < 1e-6 && (after[1] + 1.9).abs() < 1e-6,
            "{after:?}"
        );
        assert_eq!(adam.step, 1);
    }

    /// The fused host update (f32 on the CPU) follows the candle composition (taken by f64
    /// variables) over several steps with changing gradients.
    #[test]
    fn fused_update_matches_the_composition() {
        let dev = Device::Cpu;
        let start = vec![0.5f64, -1.5, 2.0, 0.0];
        let run = |dtype: candle_core::DType| -> Vec<f64> {
            let p = Var::from_tensor(
                &Tensor::from_vec(start.clone(), 4, &dev)
                    .unwrap()
                    .to_dtype(dtype)
                    .unwrap(),
            )
            .unwrap();
            let vars = vec![("p".to_owned(), p.clone())];
            let mut adam = Adam::new(&vars).unwrap();
            for k in 0..5 {
                let w = Tensor::from_vec(vec![1.0f64, -2.0, 0.5, 3.0], 4, &dev)
                    .unwrap()
                    .to_dtype(dtype)
                    .unwrap();
                let loss = ((p.as_tensor().sqr().unwrap() * &w).unwrap() * (1.0 + k as f64))
                    .unwrap()
                    .sum_all()
                    .unwrap();
                adam.step(&vars, &loss.backward().unwrap(), 0.05).unwrap();
            }
            p.as_tensor()
                .to_dtype(candle_core::DType::F64)
                .unwrap()
                .to_vec1()
                .unwrap()
        };
        let fused = run(candle_core::DType::F32);
        let composed = run(candle_core::DType::F64);
        for (a, b) in fused.iter().zip(&composed) {
            assert!((a - b).abs() < 1e-5, "fused {a} vs composition {b}");
        }
        assert!(fused.iter().zip(&start).any(|(a, b)| (a - b).abs() > 0.1));
    }
}
