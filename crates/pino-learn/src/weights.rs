//! ODE magnitude weights of PINO-MBD (`docs/learning.md`, phi), for any described system.
//!
//! For one sample `k` and equation `i` (a DOF with an equation, [`crate::layout::Layout`]):
//! ```text
//! phi_ki = max_t |R_i(t)|                  (N, or N m for a pitch)
//! R      = M a~ - F(z~, v~, w~, eta)       (the engine's element code, crate::residual)
//! s~     = s + r std(s) xi,  xi ~ N(0, 1)  for every signal s below, every time point
//! ```
//! `std(s)` is the population standard deviation of the signal over the evaluated window of
//! this sample; the window drops the first `window_start_fraction` of the record, as training
//! does. The noised signals are the solution columns (the DOFs' displacements, then the
//! deflections under moving points and at sensors), the DOFs' `_v`, then their `_a`; the
//! excitations are inputs and are not noised. Where a damper needs the rate of a deflection or
//! of a profile, it is the central difference of the (noised) signal, one-sided at the ends,
//! except a profile's rate stored beside it (`eta_<element>_v`, an excitation: exact).
//!
//! **Noise order** (fixed; it makes `phi` reproducible from the seed): the normals of
//! `SampleStream::new(seed, Purpose::WeightNoise, sample_id)` are consumed signal by signal in
//! the order above (the column order of the simulation file) and within a signal in time
//! order over the window. Every signal consumes its normals even when its std is 0.

use crate::layout::Layout;
use crate::residual::ChannelMap;
use crate::{Error, Result};
use mbd_dataset::{Purpose, SampleStream};
use mbd_engine::residual::{EquationState, Equations};
use mbd_system::System;
use serde::{Deserialize, Serialize};

/// The weights configuration (the `weights` stage's parameters, all required).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeightConfig {
    /// Seed of the noise streams.
    pub seed: u64,
    /// Noise ratio `r`, in (0, 1].
    pub noise_ratio: f64,
    /// Fraction of each record dropped before evaluating, in [0, 1).
    pub window_start_fraction: f64,
}

impl WeightConfig {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<()> {
        if !(self.noise_ratio > 0.0 && self.noise_ratio <= 1.0) {
            return Err(Error::OutOfRange {
                field: "noise_ratio".into(),
                value: self.noise_ratio.to_string(),
                allowed: "in (0, 1]".into(),
            });
        }
        if !(0.0..1.0).contains(&self.window_start_fraction) {
            return Err(Error::OutOfRange {
                field: "window_start_fraction".into(),
                value: self.window_start_fraction.to_string(),
                allowed: "in [0, 1)".into(),
            });
        }
        Ok(())
    }

    /// First evaluated index of a record of `len` points: `floor(fraction len)`.
    pub fn window_start(&self, len: usize) -> usize {
        (self.window_start_fraction * len as f64).floor() as usize
    }
}

/// The simulation columns the weights read ([`Layout::weights_record`]): the noised ones
/// (solutions, `_v`, `_a`), then the excitations.
pub fn columns(layout: &Layout) -> Vec<String> {
    layout.record_columns(&layout.outputs[..layout.solutions])
}

/// Central difference of `x` at `t` (one-sided at the ends), per unit `dt`.
fn rate(x: &[f64], t: usize, dt: f64) -> f64 {
    let n = x.len();
    if n < 2 {
        return 0.0;
    }
    let (a, b) = if t == 0 {
        (0, 1)
    } else if t + 1 == n {
        (n - 2, n - 1)
    } else {
        (t - 1, t + 1)
    };
    (x[b] - x[a]) / ((b - a) as f64 * dt)
}

/// `phi` of one sample: its columns as [`columns`] lists them (full records), its parameters,
/// the output spacing `dt` (s).
pub fn magnitude_weights(
    cfg: &WeightConfig,
    system: &System,
    layout: &Layout,
    params: &mbd_system::Sampled,
    sample_id: u64,
    record: &[Vec<f64>],
    dt: f64,
) -> Result<Vec<f64>> {
    let n = record.first().map_or(0, Vec::len);
    let start = cfg.window_start(n);
    if start >= n {
        return Err(Error::OutOfRange {
            field: "window_start_fraction".into(),
            value: cfg.window_start_fraction.to_string(),
            allowed: format!(
                "a window of at least one point of the {n}-point record of sample {sample_id}"
            ),
        });
    }
    let ranges = layout.weights_record();
    let d = layout.n_dofs();
    let mut stream = SampleStream::new(cfg.seed, Purpose::WeightNoise, sample_id);
    let noised: Vec<Vec<f64>> = record[..ranges.excitations.start]
        .iter()
        .map(|sig| {
            let w = &sig[start..];
            let m = w.len() as f64;
            let mean = w.iter().sum::<f64>() / m;
            let std = (w.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / m).sqrt();
            let sd = cfg.noise_ratio * std;
            w.iter().map(|x| x + sd * stream.normal()).collect()
        })
        .collect();
    let eta_cols: Vec<&[f64]> = record[ranges.excitations.clone()]
        .iter()
        .map(|c| &c[start..])
        .collect();
    let model = system.instantiate(params).map_err(|e| Error::OutOfRange {
        field: e.path,
        value: e.value.to_string(),
        allowed: e.allowed,
    })?;
    let map = ChannelMap::new(system, layout);
    let eq = Equations::new(model, map.equations.clone());
    let mut scratch = eq.scratch();
    let (n_p, n_el) = (map.point.len(), map.eta.len());
    let (mut w, mut wr) = (vec![0.0; n_p], vec![0.0; n_p]);
    let (mut et, mut etr) = (vec![0.0; n_el], vec![0.0; n_el]);
    let (mut z, mut v, mut a) = (vec![0.0; d], vec![0.0; d], vec![0.0; d]);
    let mut r = vec![0.0; map.equations.len()];
    let mut max = vec![0.0f64; map.equations.len()];
    for t in 0..n - start {
        for i in 0..d {
            z[i] = noised[i][t];
            v[i] = noised[ranges.velocities.start + i][t];
            a[i] = noised[ranges.accelerations.start + i][t];
        }
        for (p, ch) in map.point.iter().enumerate() {
            if let Some(ch) = *ch {
                w[p] = noised[ch][t];
                wr[p] = rate(&noised[ch], t, dt);
            }
        }
        for (el, ch) in map.eta.iter().enumerate() {
            if let Some(j) = *ch {
                et[el] = eta_cols[j][t];
                etr[el] = match map.eta_rate[el] {
                    Some(r) => eta_cols[r][t],
                    None => rate(eta_cols[j], t, dt),
                };
            }
        }
        let state = EquationState {
            z: &z,
            v: &v,
            a: &a,
            point_w: &w,
            point_rate: &wr,
            eta: &et,
            eta_rate: &etr,
        };
        eq.residuals(&state, &mut scratch, &mut r);
        for (m, ri) in max.iter_mut().zip(&r) {
            // f64::max drops NaN: keep a NaN once seen so that bad data cannot hide.
            *m = if m.is_nan() || ri.is_nan() {
                f64::NAN
            } else {
                m.max(ri.abs())
            };
        }
    }
    let names = layout.phi_columns();
    if let Some(i) = max.iter().position(|x| !x.is_finite()) {
        return Err(Error::OutOfRange {
            field: format!("{} of sample {sample_id}", names[i]),
            value: max[i].to_string(),
            allowed: "finite (the record holds non-finite values)".into(),
        });
    }
    Ok(max)
}
