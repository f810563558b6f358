//! Losses of the five algorithms (`docs/learning.md`, Losses):
//! ```text
//! relL2(p, y)  = mean_k ||p_k - y_k|| / ||y_k||          (per sample over channels and time)
//! L_data       = relL2(u, u*)                            (every output: solutions and forces,
//!                                                         z-scored)
//!                [+ rate_weight relL2(r, r*)]             (the rate outputs, their own term,
//!                                                         when a training asks for them)
//! L_deriv      = relL2(v, v*) + relL2(a, a*)             (the rigid DOFs, z-scored with the
//!                                                         `_v`/`_a` statistics, interior points)
//! L_ode_global = mean_{i,t} |R_i| / F_ref                (F_ref = mean static contact force)
//! L_ode_phi    = mean_{i,t} rho |R_i| / phi_ki
//! total        = L_data [+ lambda_ode L_ode_* | + lambda_d L_deriv]   (Table 3)
//!                [+ beam_weight relL2(w, w*)]            (optional balance of the beam
//!                                                         deflection channels)
//!                [+ force_weight relL2(f, f*)]           (optional balance of the force
//!                                                         outputs)
//! ```

use crate::checkpoint::ModelMeta;
use crate::config::{Algorithm, TrainConfig};
use crate::data::Batch;
use crate::layout::Layout;
use crate::norm::Normalisation;
use crate::residual::{
    composed_residuals, derivatives, ChannelMap, OdeLoss, OdeWeights, SampleEquations,
};
use crate::{Error, Result};
use candle_core::{DType, Tensor};
use mbd_system::System;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

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
///
/// Built by [`LossContext::new`], which also builds the residual's channel map once; each
/// sample's equations and their Jacobian ([`SampleEquations`]) are built the first time a batch
/// holds the sample and kept (keyed by the exact bits of its parameters: a sample of another
/// split with the same parameters shares them), so an epoch after the first builds none. The
/// layout and the system are read-only for that reason. Clones share the kept equations.
#[derive(Debug, Clone)]
pub struct LossContext {
    /// Algorithm and weights.
    pub config: TrainConfig,
    /// The model's normalisation.
    pub norm: Normalisation,
    /// Time step of the window (s).
    pub dt: f64,
    /// Force scale of the global ODE loss (N), when the description has one.
    pub f_ref: Option<f64>,
    layout: Layout,
    system: Arc<System>,
    map: Arc<ChannelMap>,
    equations: EquationCache,
}

/// Each sample's equations by its `sample_id`, with the design they were built from (a
/// sample id met again with another design gets its equations built again), shared by clones.
type EquationCache = Arc<Mutex<KeptEquations>>;

/// The kept equations: `sample_id` -> (design, equations).
type KeptEquations = HashMap<i64, (Vec<f64>, Arc<SampleEquations>)>;

impl LossContext {
    /// The losses of `config` over `layout` of `system`, on windows of step `dt` (s)
    /// normalised by `norm`; `f_ref` (N) scales the global ODE loss where there is one.
    pub fn new(
        config: TrainConfig,
        norm: Normalisation,
        dt: f64,
        f_ref: Option<f64>,
        layout: Layout,
        system: Arc<System>,
    ) -> Self {
        let map = Arc::new(ChannelMap::new(&system, &layout));
        Self {
            config,
            norm,
            dt,
            f_ref,
            layout,
            system,
            map,
            equations: EquationCache::default(),
        }
    }

    /// The losses a model was trained with ([`ModelMeta`]: its algorithm and weights,
    /// normalisation, time step, force scale and layout), over its compiled `system`.
    pub fn of_model(meta: &ModelMeta, system: Arc<System>) -> Self {
        Self::new(
            meta.train,
            meta.norm.clone(),
            meta.grid.dt,
            meta.f_ref,
            meta.layout.clone(),
            system,
        )
    }

    /// The channel layout.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The system description (the residual's element code).
    pub fn system(&self) -> &Arc<System> {
        &self.system
    }

    fn dofs(&self) -> usize {
        self.layout.n_dofs()
    }

    /// z-scored predicted derivatives at interior points, f64 `[B, T-2, D]` each.
    pub fn predicted_derivatives(&self, u_n: &Tensor) -> Result<(Tensor, Tensor)> {
        let d = self.dofs();
        let dofs = u_n.narrow(2, 0, d)?;
        let (_, v, a) = derivatives(&dofs, &self.norm.outputs, self.dt)?;
        let zs = |x: &Tensor, s: &crate::norm::ChannelStats| -> Result<Tensor> {
            let mean = Tensor::from_slice(&s.mean, (1, 1, d), x.device())?;
            let std = Tensor::from_slice(&s.std, (1, 1, d), x.device())?;
            Ok(x.broadcast_sub(&mean)?.broadcast_div(&std)?)
        };
        Ok((
            zs(&v, &self.norm.velocities)?,
            zs(&a, &self.norm.accelerations)?,
        ))
    }

    /// The channel map of the residual.
    pub fn channel_map(&self) -> &Arc<ChannelMap> {
        &self.map
    }

    /// The equations of the batch's samples, found by sample id: built on a sample's first
    /// batch (from its design, [`Batch::designs`]) and kept.
    pub fn sample_equations(&self, batch: &Batch) -> Result<Vec<Arc<SampleEquations>>> {
        if self.map.equations.is_empty() {
            return Err(Error::OutOfRange {
                field: "algorithm".into(),
                value: self.config.algorithm.id().to_string(),
                allowed: format!(
                    "1, 4 or 5: the ODE losses need DOFs with equations, and no DOF of `{}` has one with these outputs (every element acting on a DOF must have both ends among the outputs or the excitations)",
                    self.system.name
                ),
            });
        }
        let same = |a: &[f64], b: &[f64]| {
            a.iter()
                .map(|x| x.to_bits())
                .eq(b.iter().map(|x| x.to_bits()))
        };
        batch
            .ids
            .iter()
            .zip(&batch.designs)
            .map(|(&id, p)| {
                if let Some((design, kept)) = self.kept_equations().get(&id) {
                    if same(design, p) {
                        return Ok(kept.clone());
                    }
                }
                // Built outside the lock: another thread may build the same sample meanwhile
                // (the same value; the first one kept wins).
                let design = self.system.sampled_values(p.as_slice())?;
                let built = Arc::new(SampleEquations::new(&self.system, &self.map, &design)?);
                let mut kept = self.kept_equations();
                let slot = kept.entry(id).or_insert_with(|| (p.clone(), built.clone()));
                if !same(&slot.0, p) {
                    *slot = (p.clone(), built);
                }
                Ok(slot.1.clone())
            })
            .collect()
    }

    fn kept_equations(&self) -> std::sync::MutexGuard<'_, KeptEquations> {
        // A panic while holding the lock cannot leave a half-inserted entry: keep going.
        self.equations
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// ODE residuals `[B, T-2, Q]` (N, N m) of a z-scored prediction, as candle ops.
    pub fn residuals(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let samples = self.sample_equations(batch)?;
        composed_residuals(
            &self.map,
            &samples,
            u_n,
            &batch.eta,
            &self.norm.outputs,
            self.dt,
        )
    }

    fn f_ref(&self) -> Result<f64> {
        self.f_ref.ok_or_else(|| Error::OutOfRange {
            field: "algorithm".into(),
            value: "2".into(),
            allowed: format!(
                "not 2 for `{}`: the global ODE loss scales by the mean static force of the contact elements (those resting on moving points), and it has none, or its rigid part is not statically determinate and an element other than a contact carries vertical load to the ground",
                self.system.name
            ),
        })
    }

    /// `L_deriv` of a prediction (a fused op for f32 on the CPU, the composition elsewhere).
    pub fn deriv_loss(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        if u_n.device().is_cpu() && u_n.dtype() == DType::F32 {
            let host = |t: &Tensor| t.flatten_all()?.to_vec1::<f32>();
            let op = crate::kernels::deriv_loss::DerivativeLoss {
                dofs: self.dofs(),
                dt: self.dt,
                out_std: self.norm.outputs.std.clone(),
                velocity: (
                    self.norm.velocities.mean.clone(),
                    self.norm.velocities.std.clone(),
                ),
                acceleration: (
                    self.norm.accelerations.mean.clone(),
                    self.norm.accelerations.std.clone(),
                ),
                v_target: host(&batch.v)?,
                a_target: host(&batch.a)?,
            };
            return Ok(u_n.contiguous()?.apply_op1(op)?.to_dtype(DType::F64)?);
        }
        self.deriv_loss_composed(u_n, batch)
    }

    /// `L_deriv` as candle ops (any device; the reference of the fused op).
    pub fn deriv_loss_composed(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let (v, a) = self.predicted_derivatives(u_n)?;
        Ok((rel_l2(&v, &batch.v.to_dtype(DType::F64)?)?
            + rel_l2(&a, &batch.a.to_dtype(DType::F64)?)?)?)
    }

    /// The fused residual loss (f32 on the CPU), `None` elsewhere.
    fn fused_ode_loss(
        &self,
        u_n: &Tensor,
        batch: &Batch,
        weights: OdeWeights,
    ) -> Result<Option<Tensor>> {
        if !(u_n.device().is_cpu() && u_n.dtype() == DType::F32) {
            return Ok(None);
        }
        let op = OdeLoss {
            map: self.map.clone(),
            samples: self.sample_equations(batch)?,
            eta: batch.eta.to_dtype(DType::F64)?.flatten_all()?.to_vec1()?,
            n_eta: self.layout.n_excitations(),
            mean: self.norm.outputs.mean.clone(),
            std: self.norm.outputs.std.clone(),
            dt: self.dt,
            weights,
            forward: Default::default(),
        };
        Ok(Some(u_n.contiguous()?.apply_op1(op)?.to_dtype(DType::F64)?))
    }

    /// `L_ode_global`.
    pub fn ode_global_loss(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let weights = OdeWeights::Global {
            f_ref: self.f_ref()?,
        };
        if let Some(l) = self.fused_ode_loss(u_n, batch, weights)? {
            return Ok(l);
        }
        self.ode_global_loss_composed(u_n, batch)
    }

    /// `L_ode_global` as candle ops (any device; the reference of the fused op).
    pub fn ode_global_loss_composed(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        Ok((self.residuals(u_n, batch)?.abs()?.mean_all()? / self.f_ref()?)?)
    }

    /// `L_ode_phi`.
    pub fn ode_phi_loss(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let weights = OdeWeights::Phi {
            rho: self.config.rho,
            phi: batch.phi.to_dtype(DType::F64)?.flatten_all()?.to_vec1()?,
        };
        if let Some(l) = self.fused_ode_loss(u_n, batch, weights)? {
            return Ok(l);
        }
        self.ode_phi_loss_composed(u_n, batch)
    }

    /// `L_ode_phi` as candle ops (any device; the reference of the fused op).
    pub fn ode_phi_loss_composed(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let r = self.residuals(u_n, batch)?.abs()?;
        let (b, _, q) = r.dims3()?;
        let phi = batch.phi.reshape((b, 1, q))?;
        Ok((r.broadcast_div(&phi)?.mean_all()? * self.config.rho)?)
    }

    /// `L_data`: the relative L2 of the displacements and forces, plus that of the rate
    /// outputs as a term of its own (so the rates, harder to fit, neither dilute nor dominate
    /// the displacements' term).
    fn data_loss(&self, u_n: &Tensor, batch: &Batch) -> Result<Tensor> {
        let rates = self.layout.rates;
        if rates == 0 {
            return rel_l2(u_n, &batch.u);
        }
        let base = self.layout.n_outputs() - rates;
        let part = |u: &Tensor, from: usize, n: usize| u.narrow(2, from, n);
        let outputs = rel_l2(&part(u_n, 0, base)?, &part(&batch.u, 0, base)?)?;
        let direct = rel_l2(&part(u_n, base, rates)?, &part(&batch.u, base, rates)?)?;
        Ok((outputs + (direct * self.config.rate_weight())?)?)
    }

    /// The algorithm's total loss (f32 scalar, differentiable) and its parts as numbers.
    pub fn loss(&self, u_n: &Tensor, batch: &Batch) -> Result<(Tensor, LossValues)> {
        let data = self.data_loss(u_n, batch)?;
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
        let mut total = match extra {
            Some(e) => (data + e.to_dtype(DType::F32)?)?,
            None => data,
        };
        if self.config.beam_weight > 0.0 {
            let (d, n) = (self.dofs(), self.layout.solutions - self.dofs());
            let rail = rel_l2(&u_n.narrow(2, d, n)?, &batch.u.narrow(2, d, n)?)?;
            values.beam = rail.to_scalar::<f32>()? as f64;
            total = (total + (rail * self.config.beam_weight)?)?;
        }
        let force_weight = self.config.force_weight();
        if force_weight > 0.0 {
            let (from, n) = (
                self.layout.solutions,
                self.layout.n_outputs() - self.layout.solutions - self.layout.rates,
            );
            let forces = rel_l2(&u_n.narrow(2, from, n)?, &batch.u.narrow(2, from, n)?)?;
            values.force = forces.to_scalar::<f32>()? as f64;
            total = (total + (forces * force_weight)?)?;
        }
        values.total = total.to_scalar::<f32>()? as f64;
        Ok((total, values))
    }

    /// Table 4 metrics of a prediction, per sample: relative L2 of solutions (the
    /// displacement channels, as in the paper; not the forces), first and second derivatives
    /// (fractions, not percent).
    pub fn metrics_per_sample(&self, u_n: &Tensor, batch: &Batch) -> Result<[Vec<f64>; 3]> {
        let (v, a) = self.predicted_derivatives(u_n)?;
        let disp = |u: &Tensor| -> Result<Tensor> {
            Ok(u.narrow(2, 0, self.layout.solutions)?
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
    /// Relative L2 of the beam deflections, when `beam_weight > 0`.
    pub beam: f64,
    /// Relative L2 of the force outputs, when `force_weight > 0`.
    pub force: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;
    use mbd_test_models::vehicle_track::{self, NUM_DOFS};

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

    /// A synthetic batch of three samples, its loss context for `algorithm`, and a prediction
    /// near the truth (residuals of both signs, loaded contacts).
    fn tiny_case(algorithm: i64) -> (LossContext, Batch, Tensor) {
        use crate::config::{TrainParams, WindowConfig};
        use crate::data::{make_batch, prepare};
        use crate::synthetic::{write_dataset, SyntheticSpec};
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 3,
            n_validation: 1,
            duration: 0.08,
            ..Default::default()
        };
        let f = write_dataset(&spec, dir.path()).unwrap();
        let window = WindowConfig {
            startup_fraction: 0.1,
            time_stride: 1,
        };
        let ds = f.load(&window, true).unwrap();
        let norm = ds.normalisation().unwrap();
        let items = prepare(&ds, &norm).unwrap();
        let dev = Device::Cpu;
        let batch = make_batch(&items, &[0, 1, 2], ds.t_points(), &dev).unwrap();
        let (_, config, _) = TrainParams::small(algorithm).configs(&ds.layout).unwrap();
        let ctx = LossContext::new(
            config,
            norm,
            ds.dt,
            ds.force_scale(),
            ds.layout.clone(),
            ds.system().clone(),
        );
        let mut s = mbd_dataset::rng::SampleStream::new(9, mbd_dataset::rng::Purpose::Training, 1);
        let noise: Vec<f32> = (0..batch.u.elem_count())
            .map(|_| 0.05 * s.normal() as f32)
            .collect();
        let u0 = (&batch.u + Tensor::from_vec(noise, batch.u.shape(), &dev).unwrap()).unwrap();
        (ctx, batch, u0)
    }

    /// A sample's equations are built on its first batch and kept by its id: a later batch
    /// (or a clone of the context) gets the same ones, and the loss is bit for bit the one of a
    /// fresh context that builds them again.
    #[test]
    fn sample_equations_are_built_once_and_kept() {
        let (ctx, batch, u) = tiny_case(3);
        let first = ctx.sample_equations(&batch).unwrap();
        let again = ctx.clone().sample_equations(&batch).unwrap();
        assert_eq!(first.len(), 3);
        assert!(first.iter().zip(&again).all(|(a, b)| Arc::ptr_eq(a, b)));
        assert!(!Arc::ptr_eq(&first[0], &first[1]));
        // A sample id met again with another design gets equations built for that design.
        let mut other = batch.clone();
        other.designs[0] = batch.designs[1].clone();
        let rebuilt = ctx.sample_equations(&other).unwrap();
        assert!(!Arc::ptr_eq(&rebuilt[0], &first[0]));
        assert!(Arc::ptr_eq(&rebuilt[1], &first[1]));
        let kept = ctx.loss(&u, &batch).unwrap().0.to_scalar::<f32>().unwrap();
        let (fresh, _, _) = tiny_case(3);
        let built = fresh
            .loss(&u, &batch)
            .unwrap()
            .0
            .to_scalar::<f32>()
            .unwrap();
        assert_eq!(kept.to_bits(), built.to_bits());
    }

    /// Each algorithm's total loss against its combination computed by hand with plain loops
    /// (relative L2 per sample, central differences, the solver's residuals).
    #[test]
    fn each_algorithm_loss_is_its_hand_computed_combination() {
        for algorithm in 1..=5 {
            let (ctx, batch, u) = tiny_case(algorithm);
            let (b, t, c) = u.dims3().unwrap();
            let host = |x: &Tensor| -> Vec<f64> {
                x.to_dtype(DType::F64)
                    .unwrap()
                    .flatten_all()
                    .unwrap()
                    .to_vec1()
                    .unwrap()
            };
            let (pred, truth, v_t, a_t) =
                (host(&u), host(&batch.u), host(&batch.v), host(&batch.a));
            let (params, eta, phi) = (host(&batch.params), host(&batch.eta), host(&batch.phi));
            let rel = |num: f64, den: f64| (num / den).sqrt();
            let mut data = 0.0;
            let mut deriv = 0.0;
            let (mut ode_global, mut ode_phi) = (0.0, 0.0);
            let (out, vel, acc) = (
                &ctx.norm.outputs,
                &ctx.norm.velocities,
                &ctx.norm.accelerations,
            );
            // The residuals of the hand-written vehicle-track model
            // (`mbd_test_models::vehicle_track`), independent of the description.
            let layout = ctx.layout();
            let col = |name: &str| layout.outputs.iter().position(|o| o == name).unwrap();
            // The vehicle's DOFs are the first outputs, in its equation order.
            assert_eq!(layout.outputs[..NUM_DOFS], vehicle_track::DOFS);
            let (np, ne, nq) = (
                layout.params.len(),
                layout.n_excitations(),
                layout.equations.len(),
            );
            let wheel_radius = 0.43;
            let g = vehicle_track::hertz_constant(wheel_radius);
            let f_ref = ctx.f_ref.unwrap();
            for k in 0..b {
                let sample = |x: &[f64], n: usize, ch: usize| x[(k * t + n) * c + ch];
                let (mut nu, mut du) = (0.0, 0.0);
                for i in 0..t * c {
                    let (p, y) = (pred[k * t * c + i], truth[k * t * c + i]);
                    nu += (p - y) * (p - y);
                    du += y * y;
                }
                data += rel(nu, du) / b as f64;
                let veh = vehicle_track::HalfVehicle::new(
                    |name| params[k * np + layout.params.iter().position(|n| n == name).unwrap()],
                    9.81,
                );
                let mut sums = [0.0f64; 4];
                for n in 1..t - 1 {
                    let (mut z, mut v, mut a) = ([0.0; NUM_DOFS], [0.0; NUM_DOFS], [0.0; NUM_DOFS]);
                    for i in 0..NUM_DOFS {
                        let phys = |m: usize| sample(&pred, m, i) * out.std[i] + out.mean[i];
                        z[i] = phys(n);
                        v[i] = (phys(n + 1) - phys(n - 1)) / (2.0 * ctx.dt);
                        a[i] = (phys(n + 1) - 2.0 * phys(n) + phys(n - 1)) / (ctx.dt * ctx.dt);
                        let j = (k * (t - 2) + n - 1) * NUM_DOFS + i;
                        let zv = (v[i] - vel.mean[i]) / vel.std[i];
                        let za = (a[i] - acc.mean[i]) / acc.std[i];
                        sums[0] += (zv - v_t[j]).powi(2);
                        sums[1] += v_t[j].powi(2);
                        sums[2] += (za - a_t[j]).powi(2);
                        sums[3] += a_t[j].powi(2);
                    }
                    let contact: [f64; 4] = std::array::from_fn(|w| {
                        let r = col(&format!("z_r{}", w + 1));
                        let z_r = sample(&pred, n, r) * out.std[r] + out.mean[r];
                        let e = eta[(k * t + n) * ne + w];
                        vehicle_track::contact_force(z[col(&format!("z_w{}", w + 1))] - z_r - e, g)
                    });
                    let r = veh.residuals(&z, &v, &a, &contact);
                    let count = (b * (t - 2) * nq) as f64;
                    for i in 0..NUM_DOFS {
                        ode_global += r[i].abs() / f_ref / count;
                        ode_phi += ctx.config.rho * r[i].abs() / phi[k * nq + i] / count;
                    }
                }
                deriv += (rel(sums[0], sums[1]) + rel(sums[2], sums[3])) / b as f64;
            }
            let cfg = &ctx.config;
            let want = match algorithm {
                1 => data,
                2 => data + cfg.lambda_ode * ode_global,
                3 => data + cfg.lambda_ode * ode_phi,
                _ => data + cfg.lambda_d * deriv,
            };
            let (total, values) = ctx.loss(&u, &batch).unwrap();
            let got = total
                .to_dtype(DType::F64)
                .unwrap()
                .to_scalar::<f64>()
                .unwrap();
            assert!(
                (got - want).abs() <= 2e-5 * want,
                "algorithm {algorithm}: loss {got} vs hand-computed {want}"
            );
            assert!((values.data - data).abs() <= 2e-5 * data);
        }
    }

    /// The fused derivative and ODE losses (f32, CPU) against their candle compositions on a
    /// synthetic batch: values and gradients with respect to the prediction.
    /// `force_weight` adds its multiple of the force outputs' relative L2 to the total and
    /// nothing else: the extra gradient is zero on every other channel.
    #[test]
    fn the_force_term_adds_the_forces_relative_l2_alone() {
        let (plain, batch, u0) = tiny_case(1);
        let mut weighted = plain.clone();
        weighted.config.force_weight = Some(2.0);
        let layout = &plain.layout;
        let (from, n) = (
            layout.solutions,
            layout.n_outputs() - layout.solutions - layout.rates,
        );
        assert!(n > 0, "the synthetic model has force outputs");
        let forces = rel_l2(
            &u0.narrow(2, from, n).unwrap(),
            &batch.u.narrow(2, from, n).unwrap(),
        )
        .unwrap()
        .to_dtype(DType::F64)
        .unwrap()
        .to_scalar::<f64>()
        .unwrap();
        let run = |ctx: &LossContext| {
            let u = candle_core::Var::from_tensor(&u0).unwrap();
            let (l, _) = ctx.loss(u.as_tensor(), &batch).unwrap();
            let g = l.backward().unwrap();
            let grad = g.get(u.as_tensor()).unwrap().flatten_all().unwrap();
            (
                l.to_dtype(DType::F64).unwrap().to_scalar::<f64>().unwrap(),
                grad.to_dtype(DType::F64).unwrap().to_vec1::<f64>().unwrap(),
            )
        };
        let ((l0, g0), (l1, g1)) = (run(&plain), run(&weighted));
        assert!(forces > 0.0);
        assert!(
            (l1 - l0 - 2.0 * forces).abs() <= 1e-5 * l1,
            "{l1} - {l0} != 2 x {forces}"
        );
        let channels = layout.n_outputs();
        let mut changed = 0;
        for (i, (a, b)) in g0.iter().zip(&g1).enumerate() {
            if (from..from + n).contains(&(i % channels)) {
                changed += usize::from(a != b);
            } else {
                assert_eq!(a, b, "gradient[{i}] of a non-force channel");
            }
        }
        assert!(changed > 0, "the force channels' gradient changed");
    }

    #[test]
    fn fused_losses_match_the_compositions() {
        let (ctx, batch, u0) = tiny_case(4);
        type LossFn<'a> = &'a dyn Fn(&Tensor) -> Tensor;
        let cases: [(&str, LossFn, LossFn); 3] = [
            ("deriv", &|u| ctx.deriv_loss(u, &batch).unwrap(), &|u| {
                ctx.deriv_loss_composed(u, &batch).unwrap()
            }),
            (
                "ode global",
                &|u| ctx.ode_global_loss(u, &batch).unwrap(),
                &|u| ctx.ode_global_loss_composed(u, &batch).unwrap(),
            ),
            ("ode phi", &|u| ctx.ode_phi_loss(u, &batch).unwrap(), &|u| {
                ctx.ode_phi_loss_composed(u, &batch).unwrap()
            }),
        ];
        for (name, fused, composed) in cases {
            let run = |f: LossFn| {
                let u = candle_core::Var::from_tensor(&u0).unwrap();
                let l = f(u.as_tensor());
                let g = l.backward().unwrap();
                let grad = g.get(u.as_tensor()).unwrap().flatten_all().unwrap();
                (
                    l.to_dtype(DType::F64).unwrap().to_scalar::<f64>().unwrap(),
                    grad.to_dtype(DType::F64).unwrap().to_vec1::<f64>().unwrap(),
                )
            };
            let (lf, gf) = run(fused);
            let (lc, gc) = run(composed);
            assert!(
                lc > 0.0 && (lf - lc).abs() <= 1e-5 * lc,
                "{name}: {lf} vs {lc}"
            );
            let scale = gc.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(scale > 0.0, "{name}: zero gradient");
            for (i, (a, b)) in gf.iter().zip(&gc).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-4 * scale,
                    "{name}: gradient[{i}] fused {a} vs composition {b}"
                );
            }
        }
    }
}
