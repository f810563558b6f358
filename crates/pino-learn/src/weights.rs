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
use crate::residual::{ChannelMap, State};
use crate::{Error, Result};
use mbd_dataset::{Purpose, SampleStream};
use mbd_engine::residual::Equations;
use mbd_system::{Sampled, System};
use pino_data::records::{for_each_record, ParamsTable, Record};
use pino_data::{schema, Column, Table};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

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
    params: &Sampled,
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
    let noised = noised_window(cfg, &record[..ranges.excitations.start], start, sample_id);
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
    let mut state = State::new(&map);
    let mut scratch = eq.scratch();
    let mut r = vec![0.0; map.equations.len()];
    let mut max = vec![0.0f64; map.equations.len()];
    for t in 0..n - start {
        state.gather(t, &map, &ranges, &noised, &eta_cols, dt);
        eq.residuals(&state.view(), &mut scratch, &mut r);
        for (m, ri) in max.iter_mut().zip(&r) {
            // f64::max drops NaN: keep a NaN once seen so that bad data cannot hide.
            *m = if m.is_nan() || ri.is_nan() {
                f64::NAN
            } else {
                m.max(ri.abs())
            };
        }
    }
    finite_weights(max, layout, sample_id)
}

/// The noised signals over the window from `start` (module docs: `s + r std(s) xi`, the
/// normals of the sample's stream consumed signal by signal, in time order).
fn noised_window(
    cfg: &WeightConfig,
    signals: &[Vec<f64>],
    start: usize,
    sample_id: u64,
) -> Vec<Vec<f64>> {
    let mut stream = SampleStream::new(cfg.seed, Purpose::WeightNoise, sample_id);
    signals
        .iter()
        .map(|sig| {
            let w = &sig[start..];
            let m = w.len() as f64;
            let mean = w.iter().sum::<f64>() / m;
            let std = (w.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / m).sqrt();
            let sd = cfg.noise_ratio * std;
            w.iter().map(|x| x + sd * stream.normal()).collect()
        })
        .collect()
}

impl State {
    /// The state at `t`: the DOFs' displacements, velocities and accelerations, the
    /// deflections under moving points with their rates, the profiles with theirs.
    fn gather(
        &mut self,
        t: usize,
        map: &ChannelMap,
        ranges: &crate::layout::Record,
        noised: &[Vec<f64>],
        eta_cols: &[&[f64]],
        dt: f64,
    ) {
        for i in 0..self.z.len() {
            self.z[i] = noised[i][t];
            self.v[i] = noised[ranges.velocities.start + i][t];
            self.a[i] = noised[ranges.accelerations.start + i][t];
        }
        for (p, ch) in map.point.iter().enumerate() {
            if let Some(ch) = *ch {
                self.point_w[p] = noised[ch][t];
                self.point_rate[p] = rate(&noised[ch], t, dt);
            }
        }
        for (el, ch) in map.eta.iter().enumerate() {
            if let Some(j) = *ch {
                self.eta[el] = eta_cols[j][t];
                self.eta_rate[el] = match map.eta_rate[el] {
                    Some(r) => eta_cols[r][t],
                    None => rate(eta_cols[j], t, dt),
                };
            }
        }
    }
}

/// `max` as the sample's weights, or an error naming the first non-finite one.
fn finite_weights(max: Vec<f64>, layout: &Layout, sample_id: u64) -> Result<Vec<f64>> {
    if let Some(i) = max.iter().position(|x| !x.is_finite()) {
        return Err(Error::OutOfRange {
            field: format!("{} of sample {sample_id}", layout.phi_columns()[i]),
            value: max[i].to_string(),
            allowed: "finite (the record holds non-finite values)".into(),
        });
    }
    Ok(max)
}

/// Every sample of a `params.parquet`, by id: whether it is a training sample, and its
/// parameters.
pub type SampleParams = BTreeMap<i64, (bool, Sampled)>;

/// The samples of `params` ([`SampleParams`]), their values checked against `system`.
pub fn sample_params(system: &System, params: ParamsTable) -> Result<SampleParams> {
    params
        .rows()
        .map(|(id, s, v)| {
            let train = s == crate::data::Split::Train.as_str();
            Ok((id, (train, system.sampled_values(v)?)))
        })
        .collect()
}

/// `phi` ([`magnitude_weights`]) of every training sample of the simulation `files`, by sample
/// id. Records are streamed; a group of samples is weighted in parallel at a time (one group in
/// memory), each from its own noise stream, so the result does not depend on threads, grouping
/// or file layout. A record of a sample absent from `samples` (inputs of different runs) or
/// present in two files is refused. `tick` is called once per weighted sample.
pub fn weigh_training_samples(
    cfg: &WeightConfig,
    system: &System,
    layout: &Layout,
    samples: &SampleParams,
    files: &[PathBuf],
    dt: f64,
    tick: &(dyn Fn() + Sync),
) -> Result<BTreeMap<i64, Vec<f64>>> {
    let cols = columns(layout);
    let col_refs: Vec<&str> = cols.iter().map(String::as_str).collect();
    let mut phi: BTreeMap<i64, Vec<f64>> = BTreeMap::new();
    let group = 16 * rayon::current_num_threads().max(1);
    let mut pending: Vec<Record> = Vec::new();
    let weigh_group = |pending: &mut Vec<Record>, phi: &mut BTreeMap<i64, Vec<f64>>| {
        let results: Vec<(i64, Result<Vec<f64>>)> = pending
            .par_iter()
            .map(|r| {
                let params = &samples[&r.id].1;
                let out =
                    magnitude_weights(cfg, system, layout, params, r.id as u64, &r.columns, dt);
                tick();
                (r.id, out)
            })
            .collect();
        pending.clear();
        collect_group(results, phi)
    };
    for_each_record::<Error>(files, &col_refs, &mut |file, rec| {
        match samples.get(&rec.id) {
            Some((true, _)) => pending.push(rec),
            Some((false, _)) => {}
            None => {
                return Err(Error::Dataset {
                    path: file.to_owned(),
                    message: format!(
                        "sample {} is not in params.parquet (inputs from different runs?)",
                        rec.id
                    ),
                })
            }
        }
        if pending.len() >= group {
            weigh_group(&mut pending, &mut phi)?;
        }
        Ok(())
    })?;
    weigh_group(&mut pending, &mut phi)?;
    Ok(phi)
}

/// Adds the weights of one group of samples to `phi`, in sample order: the first failure
/// (named by its sample) or a sample seen before is an error.
fn collect_group(
    results: Vec<(i64, Result<Vec<f64>>)>,
    phi: &mut BTreeMap<i64, Vec<f64>>,
) -> Result<()> {
    for (id, out) in results {
        let w = out.map_err(|e| Error::Sample {
            id,
            source: Box::new(e),
        })?;
        if phi.insert(id, w).is_some() {
            return Err(Error::DuplicateSample(id));
        }
    }
    Ok(())
}

/// The `weights.parquet` table of `phi`: `sample_id`, then `phi_<dof>` in DOF order
/// ([`Layout::phi_columns`]), sorted by sample id, with the units of `system`.
pub fn weights_table(
    system: &System,
    layout: &Layout,
    phi: &BTreeMap<i64, Vec<f64>>,
) -> Result<Table> {
    let mut table = Table::default().with_units(pino_data::system::units_of(system)?);
    table.push(
        schema::SAMPLE_ID,
        Column::I64(phi.keys().copied().collect()),
    )?;
    for (i, name) in layout.phi_columns().iter().enumerate() {
        table.push(name, Column::F64(phi.values().map(|w| w[i]).collect()))?;
    }
    Ok(table)
}
