//! The difficulty of a prediction known without the solver: its own physics residual.
//!
//! A neural operator's output need not satisfy the equations it approximates; how far it is
//! from them is a measure of how hard the design was for it. Per equation `q` (a DOF with an
//! equation, `pino-calibration` and `docs/uncertainty.md`), over every
//! [`RESIDUAL_STRIDE`]-th interior point `n = 1, 1 + s, ... <= T-2` of the window:
//! ```text
//! R_q(n) = m_q a_q(n) - F_q(z(n), v(n), w(n), w'(n), eta(n), eta'(n))     (N, or N m)
//! rms_q  = sqrt(mean_n R_q(n)^2)
//! g      = sqrt(mean_q (rms_q / ref_q)^2)                                 (dimensionless)
//! ```
//! with the state read as the residual losses read it (`pino_learn::residual`): the predicted
//! displacements, their central-difference velocities and accelerations (the same rates the
//! indices read), the deflections under moving points from their predicted outputs with
//! central-difference rates, the exact profiles with central-difference rates. `ref_q` is the
//! median of `rms_q` over the samples a calibration is fitted on (the validation split): it
//! puts equations of different units on one scale and is fixed before any calibration score is
//! computed. The residual is the engine's own element code
//! (`mbd_engine::residual::Equations`), nonlinear contacts included.

use crate::Result;
use mbd_engine::residual::EquationState;
use mbd_system::System;
use pino_learn::layout::Layout;
use pino_learn::residual::{sample_equations, ChannelMap};
use pino_outputs::physical::Physical;

/// The residual is evaluated at every `RESIDUAL_STRIDE`-th interior point: its RMS over a
/// window is an average (500 points of a 2000-point window), as good a ranking of designs as
/// every point's, at a quarter of the cost per answer (BENCHMARKS.md, "Calibrated intervals").
/// The same probe scores the calibration and answers, so the stride is part of the normaliser.
pub const RESIDUAL_STRIDE: usize = 4;

/// How one system's predictions are turned into residuals (built once per model).
#[derive(Debug, Clone)]
pub struct ResidualProbe {
    map: ChannelMap,
    outputs: usize,
    excitations: usize,
}

impl ResidualProbe {
    /// The probe of a model of `layout` on `system`; `None` when no DOF has an equation with
    /// these outputs (then no residual exists to normalise by).
    pub fn new(system: &System, layout: &Layout) -> Option<Self> {
        let map = ChannelMap::new(system, layout);
        (!map.equations.is_empty()).then_some(Self {
            map,
            outputs: layout.n_outputs(),
            excitations: layout.n_excitations(),
        })
    }

    /// Number of equations `Q`.
    pub fn equations(&self) -> usize {
        self.map.equations.len()
    }

    /// `rms_q` of every equation (N, N m) for a prediction `side` of a design with sampled
    /// parameters `params` under excitations `eta [T, E]`, at spacing `dt` (s).
    pub fn rms(
        &self,
        system: &System,
        params: &[f64],
        side: &Physical,
        eta: &[f64],
        dt: f64,
    ) -> Result<Vec<f64>> {
        let design = system.sampled_values(params)?;
        let eq = sample_equations(system, &design, self.map.equations.clone())?;
        let (o, e, d) = (self.outputs, self.excitations, self.map.dofs);
        let t = side.u.len() / o;
        let mut scratch = eq.scratch();
        let (n_p, n_el) = (self.map.point.len(), self.map.eta.len());
        let (mut w, mut wr) = (vec![0.0; n_p], vec![0.0; n_p]);
        let (mut et, mut etr) = (vec![0.0; n_el], vec![0.0; n_el]);
        let mut z = vec![0.0; d];
        let mut r = vec![0.0; self.equations()];
        let mut sum = vec![0.0; self.equations()];
        let centred = |x: &dyn Fn(usize) -> f64, n: usize| (x(n + 1) - x(n - 1)) / (2.0 * dt);
        let mut points = 0usize;
        for n in (1..t.saturating_sub(1)).step_by(RESIDUAL_STRIDE) {
            points += 1;
            z.copy_from_slice(&side.u[n * o..n * o + d]);
            for (p, ch) in self.map.point.iter().enumerate() {
                if let Some(c) = *ch {
                    w[p] = side.u[n * o + c];
                    wr[p] = centred(&|k| side.u[k * o + c], n);
                }
            }
            for (el, ch) in self.map.eta.iter().enumerate() {
                if let Some(j) = *ch {
                    et[el] = eta[n * e + j];
                    etr[el] = centred(&|k| eta[k * e + j], n);
                }
            }
            let state = EquationState {
                z: &z,
                v: &side.v[(n - 1) * d..n * d],
                a: &side.a[(n - 1) * d..n * d],
                point_w: &w,
                point_rate: &wr,
                eta: &et,
                eta_rate: &etr,
            };
            eq.residuals(&state, &mut scratch, &mut r);
            for (s, x) in sum.iter_mut().zip(&r) {
                *s += x * x;
            }
        }
        let points = points.max(1) as f64;
        Ok(sum.into_iter().map(|s| (s / points).sqrt()).collect())
    }
}

/// `g = sqrt(mean_q (rms_q / ref_q)^2)`: the residual relative to its reference level.
pub fn relative_residual(rms: &[f64], reference: &[f64]) -> f64 {
    let q = rms.len().max(1) as f64;
    (rms.iter()
        .zip(reference)
        .map(|(r, s)| (r / s).powi(2))
        .sum::<f64>()
        / q)
        .sqrt()
}

/// The median of each equation's `rms_q` over samples (`ref_q`), floored at a positive value
/// so that an equation the predictions satisfy exactly cannot divide by zero.
pub fn reference_levels(rms: &[Vec<f64>]) -> Vec<f64> {
    let q = rms.first().map_or(0, Vec::len);
    (0..q)
        .map(|j| {
            let mut col: Vec<f64> = rms.iter().map(|r| r[j]).collect();
            col.sort_by(f64::total_cmp);
            let m = col[col.len() / 2];
            if m > 0.0 && m.is_finite() {
                m
            } else {
                f64::MIN_POSITIVE
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_relative_residual_is_the_rms_of_the_ratios() {
        assert_eq!(relative_residual(&[2.0, 4.0], &[1.0, 2.0]), 2.0);
        assert_eq!(relative_residual(&[3.0, 0.0], &[1.0, 1.0]), (4.5f64).sqrt());
        let refs = reference_levels(&[vec![1.0, 0.0], vec![3.0, 0.0], vec![2.0, 0.0]]);
        assert_eq!(refs[0], 2.0);
        assert!(refs[1] > 0.0);
    }
}
