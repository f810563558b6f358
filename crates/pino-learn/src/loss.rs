//! Losses of the five algorithms (`learning.md`, Losses):
//! ```text
//! relL2(p, y)  = mean_k ||p_k - y_k|| / ||y_k||          (per sample over channels and time)
//! L_data       = relL2(u, u*)                            (18 outputs: 14 displacements and
//!                                                         4 contact forces, z-scored)
//! L_deriv      = relL2(v, v*) + relL2(a, a*)             (10 vehicle DOFs, z-scored with the
//!                                                         `_v`/`_a` statistics, interior points)
//! L_ode_global = mean_{i,t} |R_i| / F_ref                (F_ref = mean static wheel load W)
//! L_ode_phi    = mean_{i,t} rho |R_i| / phi_ki
//! total        = L_data [+ lambda_ode L_ode_* | + lambda_d L_deriv]   (Table 3)
//! ```

use crate::config::{Algorithm, TrainConfig, DOFS};
use crate::data::Batch;
use crate::norm::Normalisation;
use crate::physics::{derivatives, residuals};
use crate::Result;
use candle_core::{DType, Tensor};

/// Per-sample relative L2 `||p - y|| / ||y||` over all but the first axis: `[B]`.
pub fn rel_l2_per_sample(pred: &Tensor, truth: &Tensor) -> Result<Tensor> {
    let b = pred.dim(0)?;
    let diff = (pred - truth)?.reshape((b, ()))?;
    let num = diff.sqr()?.sum(1)?;
    let den = truth.reshape((b, ()))?.sqr()?.sum(1)?;
    Ok((num / den)?.sqrt()?)
}

/// Batch mean of [`rel_l2_per_sample`].
pub fn rel_l2(pred: &Tensor, truth: &Tensor) -> Result<Tensor> {
    Ok(rel_l2_per_sample(pred, truth)?.mean_all()?)
}

/// Everything the losses need besides the batch.
#[derive(Debug, Clone)]
pub struct LossContext {
    /// Algorithm and weights.
    pub config: TrainConfig,
    /// The model's normalisation.
    pub norm: Normalisation,
    /// Time step of the window (s).
    pub dt: f64,
    /// Force scale of the global ODE loss (N).
    pub f_ref: f64,
}

impl LossContext {
    /// Hertz constant of the configured wheel radius.
    pub fn hertz_g(&self) -> f64 {
        vtcd::contact::hertz_constant(self.config.wheel_radius)
    }

    /// z-scored predicted derivatives at interior points, f64 `[B, T-2, 10]` each.
    pub fn predicted_derivatives(&self, u_n: &Tensor) -> Result<(Tensor, Tensor)> {
        let vehicle = u_n.narrow(2, 0, DOFS)?;
        let (_, v, a) = derivatives(&vehicle, &self.norm.outputs, self.dt)?;
        let zs = |x: &Tensor, s: &crate::norm::ChannelStats| -> Result<Tensor> {
            let mean = Tensor::from_slice(&s.mean, (1, 1, DOFS), x.device())?;
            let std = Tensor::from_slice(&s.std, (1, 1, DOFS), x.device())?;
            Ok(x.broadcast_sub(&mean)?.broadcast_div(&std)?)
        };
        Ok((
            zs(&v, &self.norm.velocities)?,
            zs(&a, &self.norm.accelerations)?,
        ))
    }

    /// ODE residuals `[B, T-2, 10]` (N, N m) of a z-scored prediction.
    pub fn residuals(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let (z, v, a) = derivatives(&u_n.narrow(2, 0, DOFS)?, &self.norm.outputs, self.dt)?;
        let rail_stats = crate::norm::ChannelStats {
            names: self.norm.outputs.names[DOFS..].to_vec(),
            mean: self.norm.outputs.mean[DOFS..].to_vec(),
            std: self.norm.outputs.std[DOFS..].to_vec(),
        };
        let (z_r, _, _) = derivatives(&u_n.narrow(2, DOFS, 4)?, &rail_stats, self.dt)?;
        residuals(
            (&z, &v, &a),
            &z_r,
            &batch.eta,
            &batch.params,
            self.config.gravity,
            self.hertz_g(),
        )
    }

    /// `L_deriv` of a prediction.
    pub fn deriv_loss(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let (v, a) = self.predicted_derivatives(u_n)?;
        Ok((rel_l2(&v, &batch.v.to_dtype(DType::F64)?)?
            + rel_l2(&a, &batch.a.to_dtype(DType::F64)?)?)?)
    }

    /// `L_ode_global`.
    pub fn ode_global_loss(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        Ok((self.residuals(u_n, batch)?.abs()?.mean_all()? / self.f_ref)?)
    }

    /// `L_ode_phi`.
    pub fn ode_phi_loss(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let r = self.residuals(u_n, batch)?.abs()?;
        let b = r.dim(0)?;
        let phi = batch.phi.reshape((b, 1, DOFS))?;
        Ok((r.broadcast_div(&phi)?.mean_all()? * self.config.rho)?)
    }

    /// The algorithm's total loss (f32 scalar, differentiable) and its parts as numbers.
    pub fn loss(&self, u_n: &Tensor, batch: &Batch) -> Result<(Tensor, LossValues)> {
        let data = rel_l2(u_n, &batch.u)?;
        let mut values = LossValues {
            data: data.to_scalar::<f32>()? as f64,
            ..LossValues::default()
        };
        let extra = match self.config.algorithm {
            Algorithm::Fno => None,
            Algorithm::Pino => {
                let l = self.ode_global_loss(u_n, batch)?;
                values.ode = l.to_scalar::<f64>()?;
                Some((l * self.config.lambda_ode)?)
            }
            Algorithm::PinoMbdWeights => {
                let l = self.ode_phi_loss(u_n, batch)?;
                values.ode = l.to_scalar::<f64>()?;
                Some((l * self.config.lambda_ode)?)
            }
            Algorithm::PinoMbdDerivatives | Algorithm::PinoMbdDerivativesDeep => {
                let l = self.deriv_loss(u_n, batch)?;
                values.deriv = l.to_scalar::<f64>()?;
                Some((l * self.config.lambda_d)?)
            }
        };
        let total = match extra {
            Some(e) => (data + e.to_dtype(DType::F32)?)?,
            None => data,
        };
        values.total = total.to_scalar::<f32>()? as f64;
        Ok((total, values))
    }

    /// Table 4 metrics of a prediction, per sample: relative L2 of solutions (the 14
    /// displacement channels, as in the paper; not the contact forces), first and second
    /// derivatives (fractions, not percent).
    pub fn metrics_per_sample(&self, u_n: &Tensor, batch: &Batch) -> Result<[Vec<f64>; 3]> {
        let (v, a) = self.predicted_derivatives(u_n)?;
        let disp = |u: &Tensor| -> Result<Tensor> {
            Ok(u.narrow(2, 0, crate::config::SOLUTION_CHANNELS)?
                .to_dtype(DType::F64)?)
        };
        let sol = rel_l2_per_sample(&disp(u_n)?, &disp(&batch.u)?)?;
        let first = rel_l2_per_sample(&v, &batch.v.to_dtype(DType::F64)?)?;
        let second = rel_l2_per_sample(&a, &batch.a.to_dtype(DType::F64)?)?;
        Ok([sol.to_vec1()?, first.to_vec1()?, second.to_vec1()?])
    }
}

/// Loss parts of one step (0 where the algorithm does not use a part).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LossValues {
    /// The optimised total.
    pub total: f64,
    /// `L_data`.
    pub data: f64,
    /// `L_deriv`.
    pub deriv: f64,
    /// `L_ode_global` or `L_ode_phi`.
    pub ode: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    #[test]
    fn relative_l2_is_per_sample_then_averaged() {
        let dev = Device::Cpu;
        // Sample 0: truth (3, 4), pred (3, 4) + (0, 5) -> 5/5 = 1; sample 1: exact -> 0.
        let truth = Tensor::from_vec(vec![3.0f64, 4.0, 1.0, 0.0], (2, 1, 2), &dev).unwrap();
        let pred = Tensor::from_vec(vec![3.0f64, 9.0, 1.0, 0.0], (2, 1, 2), &dev).unwrap();
        let per = rel_l2_per_sample(&pred, &truth)
            .unwrap()
            .to_vec1::<f64>()
            .unwrap();
        assert_eq!(per, vec![1.0, 0.0]);
        assert_eq!(
            rel_l2(&pred, &truth).unwrap().to_scalar::<f64>().unwrap(),
            0.5
        );
    }
}
