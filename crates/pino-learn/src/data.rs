//! Datasets: Parquet artifacts -> per-sample arrays (physical units) -> z-scored batches.
//!
//! Inputs are the artifacts of the physics stages: `params.parquet` (`sample_id`, `split`, 14
//! parameters), `simulation.parquet` shards (rows sorted by `sample_id` then `t`) and, for
//! algorithm 3, `weights.parquet` (`sample_id`, `phi_1..phi_10`). Each record must have the
//! same uniform time grid; the window drops the first `startup_fraction` of it and keeps every
//! `time_stride`-th point, leaving `T` points with spacing `dt`.
//!
//! Per sample (row-major, time first): `u [T, 14]`, `v [T, 10]`, `a [T, 10]`, `eta [T, 4]`.
//! A [`Batch`] holds f32 z-scored tensors `x [B, T, 19]`, `u [B, T, 14]`, interior derivative
//! targets `v, a [B, T-2, 10]`, and f64 physical `params [B, 14]`, `eta [B, T-2, 4]`,
//! `phi [B, 10]` for the ODE residual.

use crate::config::{WindowConfig, DOFS, IN_CHANNELS, OUT_CHANNELS};
use crate::norm::{ChannelStats, Normalisation};
use crate::{Error, Result};
use candle_core::{DType, Device, Tensor};
use pino_data::{read_parquet, read_parquet_files, schema};
use std::path::{Path, PathBuf};

/// Which split a sample belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Split {
    /// Training.
    Train,
    /// Validation.
    Validation,
    /// Test (held out from every choice of settings).
    Test,
}

/// One sample in physical units over the window.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// `sample_id`.
    pub id: i64,
    /// Its split.
    pub split: Split,
    /// The 14 parameters (spec order).
    pub params: [f64; 14],
    /// Solutions `[T, 14]` (m, rad).
    pub u: Vec<f64>,
    /// Vehicle velocities `[T, 10]`.
    pub v: Vec<f64>,
    /// Vehicle accelerations `[T, 10]`.
    pub a: Vec<f64>,
    /// Irregularity under each wheel `[T, 4]` (m).
    pub eta: Vec<f64>,
    /// ODE magnitude weights (N, N m), when a weights file was given.
    pub phi: Option<[f64; DOFS]>,
}

/// A windowed dataset.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// Samples sorted by id.
    pub samples: Vec<Sample>,
    /// Times of the window (s), `T` values.
    pub t: Vec<f64>,
    /// Spacing of the window (s).
    pub dt: f64,
    /// Points of each full record before windowing.
    pub record_points: usize,
}

fn dataset_err(path: &Path, message: String) -> Error {
    Error::Dataset {
        path: path.to_owned(),
        message,
    }
}

/// The simulation columns this crate reads.
pub fn needed_simulation_columns() -> Vec<String> {
    let mut c = vec![schema::SAMPLE_ID.to_owned(), schema::TIME.to_owned()];
    c.extend(schema::solution_channels().iter().map(|s| s.to_string()));
    c.extend(schema::VEHICLE_DOFS.iter().map(|s| schema::velocity(s)));
    c.extend(schema::VEHICLE_DOFS.iter().map(|s| schema::acceleration(s)));
    c.extend(schema::ETA_UNDER_WHEEL.iter().map(|s| s.to_string()));
    c
}

/// Reads `params.parquet`: `(sample_id, split, params)` rows.
pub fn read_params(path: &Path) -> Result<Vec<(i64, Split, [f64; 14])>> {
    let mut cols = vec![schema::SAMPLE_ID, schema::SPLIT];
    cols.extend(schema::PARAMETERS);
    let t = read_parquet(path, Some(&cols))?;
    let ids = t.i64(schema::SAMPLE_ID)?;
    let splits = t.str(schema::SPLIT)?;
    let values: Vec<&[f64]> = schema::PARAMETERS
        .iter()
        .map(|p| t.f64(p))
        .collect::<pino_data::Result<_>>()?;
    let mut out = Vec::with_capacity(ids.len());
    for (r, (&id, split)) in ids.iter().zip(splits).enumerate() {
        let split = match split.as_str() {
            schema::SPLIT_TRAIN => Split::Train,
            schema::SPLIT_VALIDATION => Split::Validation,
            schema::SPLIT_TEST => Split::Test,
            other => {
                return Err(dataset_err(
                    path,
                    format!(
                        "sample {id}: split `{other}`, allowed `train`, `validation` or `test`"
                    ),
                ))
            }
        };
        out.push((id, split, std::array::from_fn(|k| values[k][r])));
    }
    Ok(out)
}

/// Reads `weights.parquet` into `(sample_id, phi)` rows; every phi must be finite and > 0.
pub fn read_weights(path: &Path) -> Result<Vec<(i64, [f64; DOFS])>> {
    let names = schema::phi_columns();
    let mut cols = vec![schema::SAMPLE_ID];
    cols.extend(names.iter().map(String::as_str));
    let t = read_parquet(path, Some(&cols))?;
    let ids = t.i64(schema::SAMPLE_ID)?;
    let phis: Vec<&[f64]> = names
        .iter()
        .map(|n| t.f64(n))
        .collect::<pino_data::Result<_>>()?;
    let mut out = Vec::with_capacity(ids.len());
    for (r, &id) in ids.iter().enumerate() {
        let phi: [f64; DOFS] = std::array::from_fn(|i| phis[i][r]);
        if let Some(i) = phi.iter().position(|p| !(p.is_finite() && *p > 0.0)) {
            return Err(dataset_err(
                path,
                format!(
                    "sample {id}: phi_{} = {} must be finite and > 0",
                    i + 1,
                    phi[i]
                ),
            ));
        }
        out.push((id, phi));
    }
    Ok(out)
}

/// Loads and windows a dataset. Samples present in `params` but absent from the simulation
/// (failed simulations) are skipped; a simulated sample without parameters is an error.
pub fn load_dataset(
    params_file: &Path,
    simulation_files: &[PathBuf],
    weights_file: Option<&Path>,
    window: &WindowConfig,
) -> Result<Dataset> {
    window.validate()?;
    let params = read_params(params_file)?;
    let weights = weights_file.map(read_weights).transpose()?;
    let first_file = simulation_files.first().ok_or_else(|| {
        dataset_err(
            params_file,
            "no simulation.parquet given for these parameters".into(),
        )
    })?;
    let cols = needed_simulation_columns();
    let col_refs: Vec<&str> = cols.iter().map(String::as_str).collect();
    let table = read_parquet_files(simulation_files, Some(&col_refs))?;
    let ids = table.i64(schema::SAMPLE_ID)?;
    let times = table.f64(schema::TIME)?;
    let get = |names: &[String]| -> Result<Vec<&[f64]>> {
        Ok(names
            .iter()
            .map(|n| table.f64(n))
            .collect::<pino_data::Result<_>>()?)
    };
    let sol_names: Vec<String> = schema::solution_channels()
        .iter()
        .map(|s| s.to_string())
        .collect();
    let vel_names: Vec<String> = schema::VEHICLE_DOFS
        .iter()
        .map(|s| schema::velocity(s))
        .collect();
    let acc_names: Vec<String> = schema::VEHICLE_DOFS
        .iter()
        .map(|s| schema::acceleration(s))
        .collect();
    let eta_names: Vec<String> = schema::ETA_UNDER_WHEEL
        .iter()
        .map(|s| s.to_string())
        .collect();
    let (sol, vel, acc, eta) = (
        get(&sol_names)?,
        get(&vel_names)?,
        get(&acc_names)?,
        get(&eta_names)?,
    );

    // Contiguous runs of one sample id.
    let mut runs: Vec<(i64, usize, usize)> = Vec::new();
    let mut start = 0;
    for r in 1..=ids.len() {
        if r == ids.len() || ids[r] != ids[start] {
            runs.push((ids[start], start, r));
            start = r;
        }
    }
    let mut seen = std::collections::BTreeSet::new();
    let mut grid: Option<(usize, f64, f64, i64)> = None; // (n, dt, t0, first id)
    let mut samples = Vec::with_capacity(runs.len());
    let mut t_window = Vec::new();
    for &(id, lo, hi) in &runs {
        if !seen.insert(id) {
            return Err(dataset_err(
                first_file,
                format!("rows of sample {id} are not contiguous (rows must be sorted by sample_id then t)"),
            ));
        }
        let n = hi - lo;
        let ts = &times[lo..hi];
        if n < 3 {
            return Err(dataset_err(
                first_file,
                format!("sample {id} has {n} time points, need >= 3"),
            ));
        }
        let dt = (ts[n - 1] - ts[0]) / (n - 1) as f64;
        if let Some(k) =
            (1..n).find(|&k| ((ts[k] - ts[k - 1]) - dt).abs() > 1e-6 * dt.abs().max(1e-12))
        {
            return Err(dataset_err(
                first_file,
                format!("sample {id}: time step {} at row {k} differs from the mean step {dt} (need a uniform, increasing grid)", ts[k] - ts[k - 1]),
            ));
        }
        if dt.is_nan() || dt <= 0.0 {
            return Err(dataset_err(
                first_file,
                format!("sample {id}: time is not increasing (dt = {dt})"),
            ));
        }
        match grid {
            None => grid = Some((n, dt, ts[0], id)),
            Some((n0, dt0, t00, id0)) => {
                if n != n0 {
                    return Err(dataset_err(
                        first_file,
                        format!("sample {id} has {n} time points but sample {id0} has {n0}: all records must have the same length"),
                    ));
                }
                if (dt - dt0).abs() > 1e-9 * dt0
                    || (ts[0] - t00).abs() > 1e-9 * dt0.max(1e-12) * 1e3
                {
                    return Err(dataset_err(
                        first_file,
                        format!("sample {id} has time grid (t0 {}, dt {dt}) but sample {id0} has (t0 {t00}, dt {dt0})", ts[0]),
                    ));
                }
            }
        }
        let keep: Vec<usize> = (window.first_index(n)..n)
            .step_by(window.time_stride)
            .map(|k| lo + k)
            .collect();
        if t_window.is_empty() {
            t_window = keep.iter().map(|&r| times[r]).collect();
        }
        let block = |chans: &[&[f64]]| -> Vec<f64> {
            let mut out = Vec::with_capacity(keep.len() * chans.len());
            for &r in &keep {
                out.extend(chans.iter().map(|c| c[r]));
            }
            out
        };
        let Some(&(_, split, p)) = params.iter().find(|(pid, _, _)| *pid == id) else {
            return Err(dataset_err(
                params_file,
                format!("sample {id} is in the simulation but not in the parameters file"),
            ));
        };
        // The weights stage covers the training split only; `train` checks that every
        // training sample has its phi when the algorithm needs it.
        let phi = weights
            .as_ref()
            .and_then(|w| w.iter().find(|(wid, _)| *wid == id).map(|(_, p)| *p));
        samples.push(Sample {
            id,
            split,
            params: p,
            u: block(&sol),
            v: block(&vel),
            a: block(&acc),
            eta: block(&eta),
            phi,
        });
    }
    let Some((record_points, dt, _, _)) = grid else {
        return Err(dataset_err(first_file, "the simulation has no rows".into()));
    };
    if t_window.len() < 3 {
        return Err(dataset_err(
            first_file,
            format!("the window keeps {} points, need >= 3", t_window.len()),
        ));
    }
    samples.sort_by_key(|s| s.id);
    Ok(Dataset {
        samples,
        t: t_window,
        dt: dt * window.time_stride as f64,
        record_points,
    })
}

impl Dataset {
    /// Window length `T`.
    pub fn t_points(&self) -> usize {
        self.t.len()
    }

    /// Indices of the samples of one split.
    pub fn split_indices(&self, split: Split) -> Vec<usize> {
        (0..self.samples.len())
            .filter(|&i| self.samples[i].split == split)
            .collect()
    }

    /// Mean static wheel load W (N) over the training split: the PINO force scale F_ref.
    pub fn mean_wheel_load(&self, gravity: f64) -> f64 {
        let train: Vec<&Sample> = self
            .samples
            .iter()
            .filter(|s| s.split == Split::Train)
            .collect();
        let sum: f64 = train
            .iter()
            .map(|s| {
                vtcd::vehicle::Vehicle::new(
                    &vtcd::params::SampleParams::from_array(s.params),
                    gravity,
                )
                .w
            })
            .sum();
        sum / train.len().max(1) as f64
    }

    /// Z-score statistics over the training split.
    pub fn normalisation(&self) -> Result<Normalisation> {
        let train: Vec<&Sample> = self
            .samples
            .iter()
            .filter(|s| s.split == Split::Train)
            .collect();
        if train.is_empty() {
            return Err(Error::Dataset {
                path: PathBuf::from("params.parquet"),
                message: "no sample of split `train`: normalisation needs training data".into(),
            });
        }
        let inputs: Vec<Vec<f64>> = train.iter().map(|s| self.input_block(s)).collect();
        let mut in_names = vec![schema::TIME];
        in_names.extend(schema::ETA_UNDER_WHEEL);
        in_names.extend(schema::PARAMETERS);
        let sol = schema::solution_channels();
        let vel: Vec<String> = schema::VEHICLE_DOFS
            .iter()
            .map(|s| schema::velocity(s))
            .collect();
        let acc: Vec<String> = schema::VEHICLE_DOFS
            .iter()
            .map(|s| schema::acceleration(s))
            .collect();
        let vel: Vec<&str> = vel.iter().map(String::as_str).collect();
        let acc: Vec<&str> = acc.iter().map(String::as_str).collect();
        Ok(Normalisation {
            inputs: ChannelStats::from_blocks(&in_names, inputs.iter().map(Vec::as_slice)),
            outputs: ChannelStats::from_blocks(&sol, train.iter().map(|s| s.u.as_slice())),
            velocities: ChannelStats::from_blocks(&vel, train.iter().map(|s| s.v.as_slice())),
            accelerations: ChannelStats::from_blocks(&acc, train.iter().map(|s| s.a.as_slice())),
        })
    }

    /// The physical input block `[T, 19]` of a sample.
    pub fn input_block(&self, s: &Sample) -> Vec<f64> {
        input_block(&self.t, &s.eta, &s.params)
    }
}

/// Physical input block `[T, 19]`: `t`, `eta_1..4`, the 14 parameters.
pub fn input_block(t: &[f64], eta: &[f64], params: &[f64; 14]) -> Vec<f64> {
    let mut out = Vec::with_capacity(t.len() * IN_CHANNELS);
    for (k, &tk) in t.iter().enumerate() {
        out.push(tk);
        out.extend_from_slice(&eta[4 * k..4 * k + 4]);
        out.extend_from_slice(params);
    }
    out
}

/// A sample prepared for batching: z-scored f32 blocks.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// `sample_id`.
    pub id: i64,
    x: Vec<f32>,
    u: Vec<f32>,
    v: Vec<f32>,
    a: Vec<f32>,
    params: [f64; 14],
    eta: Vec<f64>,
    phi: [f64; DOFS],
}

/// Z-scores every sample once.
pub fn prepare(ds: &Dataset, norm: &Normalisation) -> Vec<Prepared> {
    ds.samples
        .iter()
        .map(|s| Prepared {
            id: s.id,
            x: norm.inputs.normalise(&ds.input_block(s)),
            u: norm.outputs.normalise(&s.u),
            v: norm.velocities.normalise(&s.v),
            a: norm.accelerations.normalise(&s.a),
            params: s.params,
            eta: s.eta.clone(),
            phi: s.phi.unwrap_or([1.0; DOFS]),
        })
        .collect()
}

/// One batch of tensors (see the module doc for shapes).
#[derive(Debug, Clone)]
pub struct Batch {
    /// Inputs `[B, T, 19]` f32 z-scored.
    pub x: Tensor,
    /// Target solutions `[B, T, 14]` f32 z-scored.
    pub u: Tensor,
    /// Target velocities at interior points `[B, T-2, 10]` f32 z-scored.
    pub v: Tensor,
    /// Target accelerations at interior points `[B, T-2, 10]` f32 z-scored.
    pub a: Tensor,
    /// Parameters `[B, 14]` f64 physical.
    pub params: Tensor,
    /// Irregularity at interior points `[B, T-2, 4]` f64 physical (m).
    pub eta: Tensor,
    /// ODE magnitude weights `[B, 10]` f64 (ones when absent).
    pub phi: Tensor,
}

/// Builds the batch of `items[idx]` on `device`.
pub fn make_batch(
    items: &[Prepared],
    idx: &[usize],
    t_points: usize,
    device: &Device,
) -> Result<Batch> {
    let b = idx.len();
    let t = t_points;
    let interior = |blk: &[f32], c: usize| -> Vec<f32> { blk[c..(t - 1) * c].to_vec() };
    let cat32 = |f: &dyn Fn(&Prepared) -> Vec<f32>| -> Vec<f32> {
        idx.iter().flat_map(|&i| f(&items[i])).collect()
    };
    let x = Tensor::from_vec(cat32(&|p| p.x.clone()), (b, t, IN_CHANNELS), device)?;
    let u = Tensor::from_vec(cat32(&|p| p.u.clone()), (b, t, OUT_CHANNELS), device)?;
    let v = Tensor::from_vec(cat32(&|p| interior(&p.v, DOFS)), (b, t - 2, DOFS), device)?;
    let a = Tensor::from_vec(cat32(&|p| interior(&p.a, DOFS)), (b, t - 2, DOFS), device)?;
    let params: Vec<f64> = idx.iter().flat_map(|&i| items[i].params).collect();
    let eta: Vec<f64> = idx
        .iter()
        .flat_map(|&i| items[i].eta[4..(t - 1) * 4].to_vec())
        .collect();
    let phi: Vec<f64> = idx.iter().flat_map(|&i| items[i].phi).collect();
    Ok(Batch {
        x,
        u,
        v,
        a,
        params: Tensor::from_vec(params, (b, 14), device)?,
        eta: Tensor::from_vec(eta, (b, t - 2, 4), device)?,
        phi: Tensor::from_vec(phi, (b, DOFS), device)?.to_dtype(DType::F64)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{write_dataset, SyntheticSpec};
    use pino_data::{read_parquet, write_parquet, Column, Table};

    /// Rewrites `file` keeping the rows where `keep(row)` and the columns where `col(name)`.
    fn rewrite(file: &Path, keep: &dyn Fn(usize) -> bool, col: &dyn Fn(&str) -> bool) {
        let t = read_parquet(file, None).unwrap();
        let rows: Vec<usize> = (0..t.num_rows()).filter(|&r| keep(r)).collect();
        let mut out = Table::default();
        for (name, c) in t.columns() {
            if !col(name) {
                continue;
            }
            let c = match c {
                Column::F64(v) => Column::F64(rows.iter().map(|&r| v[r]).collect()),
                Column::I64(v) => Column::I64(rows.iter().map(|&r| v[r]).collect()),
                Column::Str(v) => Column::Str(rows.iter().map(|&r| v[r].clone()).collect()),
            };
            out.push(name, c).unwrap();
        }
        write_parquet(file, &out).unwrap();
    }

    #[test]
    fn window_statistics_and_bad_files() {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 2,
            n_validation: 1,
            duration: 0.1,
            ..Default::default()
        };
        let f = write_dataset(&spec, dir.path()).unwrap();
        let ds = load_dataset(
            &f.params,
            std::slice::from_ref(&f.simulation),
            Some(&f.weights),
            &WindowConfig::default(),
        )
        .unwrap();
        // 100 points, the first 10 dropped.
        assert_eq!((ds.t_points(), ds.record_points), (90, 100));
        assert!((ds.t[0] - 0.01).abs() < 1e-12 && (ds.dt - 1e-3).abs() < 1e-15);
        assert_eq!(ds.split_indices(Split::Validation), vec![2]);
        let norm = ds.normalisation().unwrap();
        // Stats come from the training split only: sample 2's parameters do not move them.
        let m_c_mean = (ds.samples[0].params[0] + ds.samples[1].params[0]) / 2.0;
        assert!((norm.inputs.mean[5] - m_c_mean).abs() < 1e-9 * m_c_mean);

        // Mismatched record lengths: sample 1 loses its last row.
        rewrite(&f.simulation, &|r| r != 199, &|_| true);
        let err = load_dataset(
            &f.params,
            std::slice::from_ref(&f.simulation),
            None,
            &WindowConfig::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("sample 1 has 99 time points but sample 0 has 100"),
            "{err}"
        );

        // A missing column is named with its file.
        rewrite(&f.simulation, &|_| true, &|c| c != "beta_t2_v");
        let err = load_dataset(
            &f.params,
            std::slice::from_ref(&f.simulation),
            None,
            &WindowConfig::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("simulation.parquet") && err.contains("missing column `beta_t2_v`"),
            "{err}"
        );

        // A non-positive phi is refused with its sample and column.
        let w = read_parquet(&f.weights, None).unwrap();
        let mut bad = Table::default();
        for (name, c) in w.columns() {
            let c = match (name.as_str(), c) {
                ("phi_4", Column::F64(v)) => Column::F64(v.iter().map(|_| 0.0).collect()),
                _ => c.clone(),
            };
            bad.push(name, c).unwrap();
        }
        write_parquet(&f.weights, &bad).unwrap();
        let err = read_weights(&f.weights).unwrap_err().to_string();
        assert!(err.contains("sample 0: phi_4 = 0"), "{err}");
    }
}
