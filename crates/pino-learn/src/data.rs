//! Datasets: Parquet artifacts -> a sample index and streamed windows -> z-scored f32
//! storage -> batches.
//!
//! Inputs are the artifacts of the physics stages: `params.parquet` (`sample_id`, `split`, 14
//! parameters), `simulation.parquet` shards (rows sorted by `sample_id` then `t`) and, for
//! algorithm 3, `weights.parquet` (`sample_id`, `phi_1..phi_10`). Each record must have the
//! same uniform time grid; the window drops the first `startup_fraction` of it and keeps every
//! `time_stride`-th point, leaving `T` points with spacing `dt`.
//!
//! Memory is bounded by streaming: the simulation files are read batch by batch with column
//! projection (`pino_data::for_each_batch`), one record at a time is assembled in f64, and
//! only its window is kept, z-scored, in f32. [`load_dataset`] makes one such pass that
//! checks every record and accumulates the training split's normalisation statistics in f64
//! (no time series kept); [`prepare`] makes a second pass storing each sample once:
//! outputs `u [T, 18]`, derivative targets `v, a [T, 10]` (f32, z-scored), the irregularity
//! `eta [T, 4]` (f64, physical, for the ODE residual), in a [`SeriesStore`] (memory, or a
//! spill file past the memory budget), and the 14 parameters once per sample.
//! The `[T, 19]` input block (`t`, `eta_1..4`, parameters) is built only at batch time, with
//! the same arithmetic as before, so batches are bitwise those of an all-in-memory f64 load.
//! [`load_split`] reads one split in a single pass (the `evaluate` stage).
//!
//! A [`Batch`] holds f32 z-scored tensors `x [B, T, 19]`, `u [B, T, 18]`, interior derivative
//! targets `v, a [B, T-2, 10]`, and f64 physical `params [B, 14]`, `eta [B, T-2, 4]`,
//! `phi [B, 10]` for the ODE residual.

use crate::config::{WindowConfig, DOFS, IN_CHANNELS, OUT_CHANNELS};
use crate::norm::{Normalisation, StatsAccumulator};
use crate::store::{SampleSeries, SeriesStore};
use crate::{Error, Result};
use candle_core::{DType, Device, Tensor};
use pino_data::{for_each_batch, read_parquet, schema, Table};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Which split a sample belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Split {
    /// Training.
    Train,
    /// Validation (model selection, per-epoch reports).
    Validation,
    /// Test (held out from every choice; Table 4).
    Test,
}

impl Split {
    /// The label in `params.parquet`.
    pub fn label(self) -> &'static str {
        match self {
            Split::Train => schema::SPLIT_TRAIN,
            Split::Validation => schema::SPLIT_VALIDATION,
            Split::Test => schema::SPLIT_TEST,
        }
    }
}

/// One sample's identity: everything but its time series.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// `sample_id`.
    pub id: i64,
    /// Its split.
    pub split: Split,
    /// The 14 parameters (spec order).
    pub params: [f64; 14],
    /// ODE magnitude weights (N, N m), when a weights file was given.
    pub phi: Option<[f64; DOFS]>,
}

/// A windowed dataset: the index of the simulated samples, the window's grid, the training
/// split's normalisation statistics, and where to stream the time series from.
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
    simulation_files: Vec<PathBuf>,
    params_file: PathBuf,
    window: WindowConfig,
    train_stats: Option<Normalisation>,
}

fn dataset_err(path: &Path, message: String) -> Error {
    Error::Dataset {
        path: path.to_owned(),
        message,
    }
}

/// Channel groups of a streamed window, column-major: `[OUT_CHANNELS]` outputs (14
/// displacements, 4 forces), `[DOFS]` velocities, `[DOFS]` accelerations, 4 irregularities.
const U0: usize = 0;
const V0: usize = OUT_CHANNELS;
const A0: usize = V0 + DOFS;
const E0: usize = A0 + DOFS;
const SERIES: usize = E0 + 4;

fn velocity_names() -> Vec<String> {
    schema::VEHICLE_DOFS
        .iter()
        .map(|s| schema::velocity(s))
        .collect()
}

fn acceleration_names() -> Vec<String> {
    schema::VEHICLE_DOFS
        .iter()
        .map(|s| schema::acceleration(s))
        .collect()
}

/// The simulation columns this crate reads: `sample_id`, `t`, then the window's series in
/// channel order (outputs, `_v`, `_a`, `eta_1..4`).
pub fn needed_simulation_columns() -> Vec<String> {
    let mut c = vec![schema::SAMPLE_ID.to_owned(), schema::TIME.to_owned()];
    c.extend(schema::output_channels().iter().map(|s| s.to_string()));
    c.extend(velocity_names());
    c.extend(acceleration_names());
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

/// The splits present in `params.parquet`, without reading any simulation.
pub fn splits_present(params_file: &Path) -> Result<BTreeSet<Split>> {
    Ok(read_params(params_file)?
        .into_iter()
        .map(|(_, s, _)| s)
        .collect())
}

/// The first record's grid `(points, dt, t0, sample id)`, which every record must share.
type Grid = (usize, f64, f64, i64);

/// Checks one record's time column against the grid of the first record.
fn check_grid(file: &Path, id: i64, ts: &[f64], grid: &mut Option<Grid>) -> Result<()> {
    let n = ts.len();
    if n < 3 {
        return Err(dataset_err(
            file,
            format!("sample {id} has {n} time points, need >= 3"),
        ));
    }
    let dt = (ts[n - 1] - ts[0]) / (n - 1) as f64;
    if let Some(k) = (1..n).find(|&k| ((ts[k] - ts[k - 1]) - dt).abs() > 1e-6 * dt.abs().max(1e-12))
    {
        return Err(dataset_err(
            file,
            format!("sample {id}: time step {} at row {k} differs from the mean step {dt} (need a uniform, increasing grid)", ts[k] - ts[k - 1]),
        ));
    }
    if dt.is_nan() || dt <= 0.0 {
        return Err(dataset_err(
            file,
            format!("sample {id}: time is not increasing (dt = {dt})"),
        ));
    }
    match *grid {
        None => *grid = Some((n, dt, ts[0], id)),
        Some((n0, dt0, t00, id0)) => {
            if n != n0 {
                return Err(dataset_err(
                    file,
                    format!("sample {id} has {n} time points but sample {id0} has {n0}: all records must have the same length"),
                ));
            }
            if (dt - dt0).abs() > 1e-9 * dt0 || (ts[0] - t00).abs() > 1e-9 * dt0.max(1e-12) * 1e3 {
                return Err(dataset_err(
                    file,
                    format!("sample {id} has time grid (t0 {}, dt {dt}) but sample {id0} has (t0 {t00}, dt {dt0})", ts[0]),
                ));
            }
        }
    }
    Ok(())
}

/// One record being assembled from streamed batches: `t` then the [`SERIES`] columns.
struct Record {
    id: i64,
    cols: Vec<Vec<f64>>,
}

/// Receives one whole record: its file, `sample_id` and columns (`t`, then the series).
type RecordSink<'a> = dyn FnMut(&Path, i64, &[Vec<f64>]) -> Result<()> + 'a;
/// Receives one windowed sample: the sample, the window's times and its series.
type WindowSink<'a> = dyn FnMut(&Sample, &[f64], &[Vec<f64>]) -> Result<()> + 'a;

/// Streams every record of `files` in file order, one at a time, to `f(file, id, columns)`
/// (`t` then the series, full record length, physical f64). Checks contiguity of ids.
fn for_each_record(files: &[PathBuf], f: &mut RecordSink<'_>) -> Result<()> {
    let names = needed_simulation_columns();
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut seen = BTreeSet::new();
    for file in files {
        let mut failure: Option<Error> = None;
        let mut current: Option<Record> = None;
        let mut finish = |rec: Record, failure: &mut Option<Error>| -> bool {
            let r = if !seen.insert(rec.id) {
                Err(dataset_err(
                    file,
                    format!("rows of sample {} are not contiguous (rows must be sorted by sample_id then t)", rec.id),
                ))
            } else {
                f(file, rec.id, &rec.cols)
            };
            match r {
                Ok(()) => true,
                Err(e) => {
                    *failure = Some(e);
                    false
                }
            }
        };
        let stop = || pino_data::Error::Parquet {
            path: file.clone(),
            message: "stopped".into(),
        };
        let streamed = for_each_batch(file, Some(&name_refs), |table: Table| {
            let ids = table.i64(schema::SAMPLE_ID)?;
            let cols: Vec<&[f64]> = names[1..]
                .iter()
                .map(|n| table.f64(n))
                .collect::<pino_data::Result<_>>()?;
            let mut lo = 0;
            while lo < ids.len() {
                let id = ids[lo];
                let hi = (lo..ids.len()).find(|&r| ids[r] != id).unwrap_or(ids.len());
                if current.as_ref().is_some_and(|c| c.id != id) {
                    let done = current.take().expect("checked");
                    if !finish(done, &mut failure) {
                        return Err(stop());
                    }
                }
                let rec = current.get_or_insert_with(|| Record {
                    id,
                    cols: vec![Vec::new(); cols.len()],
                });
                for (dst, src) in rec.cols.iter_mut().zip(&cols) {
                    dst.extend_from_slice(&src[lo..hi]);
                }
                lo = hi;
            }
            Ok(())
        });
        if let Some(e) = failure {
            return Err(e);
        }
        streamed?;
        if let Some(rec) = current.take() {
            if !finish(rec, &mut failure) {
                return Err(failure.expect("set on failure"));
            }
        }
    }
    Ok(())
}

/// The index pass: streams every record, checks ids and grids, and calls `on_window` with
/// the window's times and series (column-major, [`SERIES`] columns of `T` values) of each sample
/// whose split `want` accepts. Returns the dataset of those samples (no statistics).
fn scan(
    params_file: &Path,
    simulation_files: &[PathBuf],
    weights_file: Option<&Path>,
    window: &WindowConfig,
    want: &dyn Fn(Split) -> bool,
    on_window: &mut WindowSink<'_>,
) -> Result<Dataset> {
    window.validate()?;
    let params: BTreeMap<i64, (Split, [f64; 14])> = read_params(params_file)?
        .into_iter()
        .map(|(id, s, p)| (id, (s, p)))
        .collect();
    // The weights stage covers the training split only; `train` checks that every training
    // sample has its phi when the algorithm needs it.
    let weights: BTreeMap<i64, [f64; DOFS]> = match weights_file {
        Some(w) => read_weights(w)?.into_iter().collect(),
        None => BTreeMap::new(),
    };
    let first_file = simulation_files.first().ok_or_else(|| {
        dataset_err(
            params_file,
            "no simulation.parquet given for these parameters".into(),
        )
    })?;
    let mut grid: Option<Grid> = None;
    let mut samples = Vec::new();
    let mut t_window: Vec<f64> = Vec::new();
    let mut windowed: Vec<Vec<f64>> = vec![Vec::new(); SERIES];
    for_each_record(simulation_files, &mut |file, id, cols| {
        check_grid(file, id, &cols[0], &mut grid)?;
        let Some(&(split, p)) = params.get(&id) else {
            return Err(dataset_err(
                params_file,
                format!("sample {id} is in the simulation but not in the parameters file"),
            ));
        };
        let n = cols[0].len();
        let keep = (window.first_index(n)..n).step_by(window.time_stride);
        if t_window.is_empty() {
            t_window = keep.clone().map(|k| cols[0][k]).collect();
        }
        if !want(split) {
            return Ok(());
        }
        let sample = Sample {
            id,
            split,
            params: p,
            phi: weights.get(&id).copied(),
        };
        for (dst, src) in windowed.iter_mut().zip(&cols[1..]) {
            dst.clear();
            dst.extend(keep.clone().map(|k| src[k]));
        }
        on_window(&sample, &t_window, &windowed)?;
        samples.push(sample);
        Ok(())
    })?;
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
        simulation_files: simulation_files.to_vec(),
        params_file: params_file.to_owned(),
        window: *window,
        train_stats: None,
    })
}

/// Streaming accumulators of the four statistic groups.
struct NormAccumulator {
    t: StatsAccumulator,
    eta: StatsAccumulator,
    params: StatsAccumulator,
    outputs: StatsAccumulator,
    velocities: StatsAccumulator,
    accelerations: StatsAccumulator,
}

impl NormAccumulator {
    fn new() -> Self {
        let vel = velocity_names();
        let acc = acceleration_names();
        let vel: Vec<&str> = vel.iter().map(String::as_str).collect();
        let acc: Vec<&str> = acc.iter().map(String::as_str).collect();
        Self {
            t: StatsAccumulator::new(&[schema::TIME]),
            eta: StatsAccumulator::new(&schema::ETA_UNDER_WHEEL),
            params: StatsAccumulator::new(&schema::PARAMETERS),
            outputs: StatsAccumulator::new(&schema::output_channels()),
            velocities: StatsAccumulator::new(&vel),
            accelerations: StatsAccumulator::new(&acc),
        }
    }

    fn add(&mut self, t: &[f64], s: &Sample, w: &[Vec<f64>]) {
        let refs =
            |r: std::ops::Range<usize>| -> Vec<&[f64]> { w[r].iter().map(Vec::as_slice).collect() };
        self.t.add_columns(&[t]);
        self.eta.add_columns(&refs(E0..SERIES));
        self.params.add_constant(&s.params, t.len());
        self.outputs.add_columns(&refs(U0..V0));
        self.velocities.add_columns(&refs(V0..A0));
        self.accelerations.add_columns(&refs(A0..E0));
    }

    fn finish(self) -> Normalisation {
        let inputs = self.t.join(self.eta).join(self.params);
        Normalisation {
            inputs: inputs.finish(),
            outputs: self.outputs.finish(),
            velocities: self.velocities.finish(),
            accelerations: self.accelerations.finish(),
        }
    }
}

/// Indexes and checks a dataset in one streaming pass and computes the training split's
/// normalisation statistics (f64 accumulators); no time series is kept ([`prepare`] loads
/// them). The dataset holds the training and validation splits: the test split is left out,
/// so nothing in training can see it ([`load_split`] reads it for `evaluate`). Samples present in `params` but absent from the simulation (failed simulations) are
/// skipped; a simulated sample without parameters is an error.
pub fn load_dataset(
    params_file: &Path,
    simulation_files: &[PathBuf],
    weights_file: Option<&Path>,
    window: &WindowConfig,
) -> Result<Dataset> {
    let mut acc = NormAccumulator::new();
    let mut any_train = false;
    let mut ds = scan(
        params_file,
        simulation_files,
        weights_file,
        window,
        &|s| s != Split::Test,
        &mut |s, t, w| {
            if s.split == Split::Train {
                any_train = true;
                acc.add(t, s, w);
            }
            Ok(())
        },
    )?;
    if any_train {
        ds.train_stats = Some(acc.finish());
    }
    Ok(ds)
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
            .map(|s| static_wheel_load(&s.params, gravity))
            .sum();
        sum / train.len().max(1) as f64
    }

    /// Z-score statistics over the training split (accumulated by [`load_dataset`]).
    pub fn normalisation(&self) -> Result<Normalisation> {
        self.train_stats.clone().ok_or_else(|| Error::Dataset {
            path: self.params_file.clone(),
            message: "no sample of split `train`: normalisation needs training data".into(),
        })
    }

    /// The `params.parquet` it was indexed from.
    pub fn params_file(&self) -> &Path {
        &self.params_file
    }

    /// The simulation files it streams from.
    pub fn simulation_files(&self) -> &[PathBuf] {
        &self.simulation_files
    }
}

/// Static wheel load W (N) of a parameter set.
pub fn static_wheel_load(params: &[f64; 14], gravity: f64) -> f64 {
    vtcd::vehicle::Vehicle::new(&vtcd::params::SampleParams::from_array(*params), gravity).w
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

/// Samples prepared for batching, each stored once: z-scored f32 outputs `[T, 18]` and
/// derivative targets `[T, 10]`, physical f64 irregularity `[T, 4]` (in a [`SeriesStore`],
/// in memory or spilled to disk), the parameters once per sample (physical f64 and z-scored
/// f32). Index `i` is the `i`-th sample of the dataset (or of the split) it was prepared
/// from.
#[derive(Debug)]
pub struct Prepared {
    t_points: usize,
    /// z-scored window times `[T]`, shared by every sample.
    t_n: Vec<f32>,
    eta_mean: [f64; 4],
    eta_std: [f64; 4],
    ids: Vec<i64>,
    params: Vec<[f64; 14]>,
    params_n: Vec<[f32; 14]>,
    phi: Vec<[f64; DOFS]>,
    /// Record of each sample in the store.
    slots: Vec<usize>,
    store: SeriesStore,
}

/// Z-scores a window's column-major group into a row-major f32 block.
fn zscore(cols: &[Vec<f64>], st: &crate::norm::ChannelStats) -> Vec<f32> {
    let c = cols.len();
    let rows = cols.first().map_or(0, Vec::len);
    let mut out = vec![0.0f32; rows * c];
    for (k, row) in out.chunks_exact_mut(c).enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = ((cols[j][k] - st.mean[j]) / st.std[j]) as f32;
        }
    }
    out
}

/// Builds a [`Prepared`] from streamed windows (any order), then orders it like a dataset.
struct Builder<'a> {
    norm: &'a Normalisation,
    store: SeriesStore,
    by_id: BTreeMap<i64, usize>,
}

impl<'a> Builder<'a> {
    fn new(norm: &'a Normalisation, t_points: usize, expected: usize) -> Result<Self> {
        Ok(Self {
            norm,
            store: SeriesStore::new(t_points, expected)?,
            by_id: BTreeMap::new(),
        })
    }

    fn add(&mut self, s: &Sample, w: &[Vec<f64>]) -> Result<()> {
        let n = self.norm;
        let rows = w[0].len();
        let mut eta = vec![0.0; rows * 4];
        for (k, row) in eta.chunks_exact_mut(4).enumerate() {
            for (i, x) in row.iter_mut().enumerate() {
                *x = w[E0 + i][k];
            }
        }
        let slot = self.store.push(&SampleSeries {
            u: zscore(&w[U0..V0], &n.outputs),
            v: zscore(&w[V0..A0], &n.velocities),
            a: zscore(&w[A0..E0], &n.accelerations),
            eta,
        })?;
        self.by_id.insert(s.id, slot);
        Ok(())
    }

    /// The samples of `ds` in its order (its phi replaces the streamed one).
    fn finish(self, ds: &Dataset) -> Prepared {
        let Builder {
            norm,
            store,
            mut by_id,
        } = self;
        let ins = &norm.inputs;
        let mut p = Prepared {
            t_points: ds.t.len(),
            t_n: ds
                .t
                .iter()
                .map(|&x| ((x - ins.mean[0]) / ins.std[0]) as f32)
                .collect(),
            eta_mean: std::array::from_fn(|i| ins.mean[1 + i]),
            eta_std: std::array::from_fn(|i| ins.std[1 + i]),
            ids: Vec::with_capacity(ds.samples.len()),
            params: Vec::with_capacity(ds.samples.len()),
            params_n: Vec::with_capacity(ds.samples.len()),
            phi: Vec::with_capacity(ds.samples.len()),
            slots: Vec::with_capacity(ds.samples.len()),
            store,
        };
        for s in &ds.samples {
            let slot = by_id.remove(&s.id).expect("every indexed sample streamed");
            p.ids.push(s.id);
            p.params.push(s.params);
            p.params_n.push(std::array::from_fn(|k| {
                ((s.params[k] - ins.mean[5 + k]) / ins.std[5 + k]) as f32
            }));
            p.phi.push(s.phi.unwrap_or([1.0; DOFS]));
            p.slots.push(slot);
        }
        p
    }
}

impl Prepared {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// `sample_id` of sample `i`.
    pub fn id(&self, i: usize) -> i64 {
        self.ids[i]
    }

    /// Window length `T`.
    pub fn t_points(&self) -> usize {
        self.t_points
    }

    /// The series of sample `i`: z-scored `u [T, 18]`, `v, a [T, 10]`, physical `eta [T, 4]`.
    pub fn series(&self, i: usize) -> Result<SampleSeries> {
        self.store.get(self.slots[i])
    }

    /// Parameters of sample `i`.
    pub fn params(&self, i: usize) -> &[f64; 14] {
        &self.params[i]
    }

    /// Whether the series were spilled to disk (over the memory budget).
    pub fn spilled(&self) -> bool {
        self.store.spilled()
    }

    /// z-scored input block `[T, 19]` of a sample with irregularity `eta` and index `i`,
    /// appended to `out`: the same values as `norm.inputs.normalise(&input_block(..))`.
    fn push_inputs(&self, i: usize, eta: &[f64], out: &mut Vec<f32>) {
        let pn = &self.params_n[i];
        for (k, &tn) in self.t_n.iter().enumerate() {
            out.push(tn);
            for j in 0..4 {
                out.push(((eta[4 * k + j] - self.eta_mean[j]) / self.eta_std[j]) as f32);
            }
            out.extend_from_slice(pn);
        }
    }

    /// Bytes held in memory by the samples (series in memory plus per-sample values).
    pub fn heap_bytes(&self) -> usize {
        self.store.memory_bytes()
            + 4 * self.t_n.len()
            + self.ids.len() * (8 + 14 * 8 + 14 * 4 + DOFS * 8 + 8)
    }
}

/// Loads and z-scores every sample of `ds` (a second streaming pass over its files).
pub fn prepare(ds: &Dataset, norm: &Normalisation) -> Result<Prepared> {
    let mut b = Builder::new(norm, ds.t.len(), ds.samples.len())?;
    let wanted: BTreeSet<i64> = ds.samples.iter().map(|s| s.id).collect();
    scan(
        &ds.params_file,
        &ds.simulation_files,
        None,
        &ds.window,
        &|s| s != Split::Test,
        &mut |s, _, w| {
            if wanted.contains(&s.id) {
                b.add(s, w)?;
            }
            Ok(())
        },
    )?;
    Ok(b.finish(ds))
}

/// Reads and z-scores (with `norm`, a model's statistics) only the samples of `split`, in one
/// streaming pass: the dataset of that split and its prepared samples, index for index.
pub fn load_split(
    params_file: &Path,
    simulation_files: &[PathBuf],
    window: &WindowConfig,
    split: Split,
    norm: &Normalisation,
) -> Result<(Dataset, Prepared)> {
    let expected = read_params(params_file)?
        .iter()
        .filter(|(_, s, _)| *s == split)
        .count();
    let mut builder: Option<Builder> = None;
    let ds = scan(
        params_file,
        simulation_files,
        None,
        window,
        &|s| s == split,
        &mut |s, t, w| {
            if builder.is_none() {
                builder = Some(Builder::new(norm, t.len(), expected)?);
            }
            builder.as_mut().expect("created").add(s, w)
        },
    )?;
    let b = match builder {
        Some(b) => b,
        None => Builder::new(norm, ds.t.len(), 0)?,
    };
    let items = b.finish(&ds);
    Ok((ds, items))
}

/// One batch of tensors (see the module doc for shapes).
#[derive(Debug, Clone)]
pub struct Batch {
    /// Inputs `[B, T, 19]` f32 z-scored.
    pub x: Tensor,
    /// Target outputs `[B, T, 18]` f32 z-scored (14 displacements, 4 contact forces).
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

/// Builds the batch of `items[idx]` on `device`; the input blocks are assembled here.
pub fn make_batch(
    items: &Prepared,
    idx: &[usize],
    t_points: usize,
    device: &Device,
) -> Result<Batch> {
    let b = idx.len();
    let t = t_points;
    debug_assert_eq!(t, items.t_points);
    let mut x = Vec::with_capacity(b * t * IN_CHANNELS);
    let mut u = Vec::with_capacity(b * t * OUT_CHANNELS);
    let mut v = Vec::with_capacity(b * (t - 2) * DOFS);
    let mut a = Vec::with_capacity(b * (t - 2) * DOFS);
    let mut eta = Vec::with_capacity(b * (t - 2) * 4);
    for &i in idx {
        let s = items.series(i)?;
        items.push_inputs(i, &s.eta, &mut x);
        u.extend_from_slice(&s.u);
        v.extend_from_slice(&s.v[DOFS..(t - 1) * DOFS]);
        a.extend_from_slice(&s.a[DOFS..(t - 1) * DOFS]);
        eta.extend_from_slice(&s.eta[4..(t - 1) * 4]);
    }
    let params: Vec<f64> = idx.iter().flat_map(|&i| items.params[i]).collect();
    let phi: Vec<f64> = idx.iter().flat_map(|&i| items.phi[i]).collect();
    Ok(Batch {
        x: Tensor::from_vec(x, (b, t, IN_CHANNELS), device)?,
        u: Tensor::from_vec(u, (b, t, OUT_CHANNELS), device)?,
        v: Tensor::from_vec(v, (b, t - 2, DOFS), device)?,
        a: Tensor::from_vec(a, (b, t - 2, DOFS), device)?,
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

        // A missing contact-force column (an output channel, read before the derivatives) is
        // named with its file.
        rewrite(&f.simulation, &|_| true, &|c| c != "p_3");
        let err = load_dataset(
            &f.params,
            std::slice::from_ref(&f.simulation),
            None,
            &WindowConfig::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("simulation.parquet") && err.contains("missing column `p_3`"),
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

        // An unknown split label is refused with the allowed ones.
        rewrite(&f.params, &|_| true, &|_| true);
        let p = read_parquet(&f.params, None).unwrap();
        let mut bad = Table::default();
        for (name, c) in p.columns() {
            let c = match (name.as_str(), c) {
                ("split", Column::Str(v)) => {
                    Column::Str(v.iter().map(|_| "holdout".to_owned()).collect())
                }
                _ => c.clone(),
            };
            bad.push(name, c).unwrap();
        }
        write_parquet(&f.params, &bad).unwrap();
        let err = read_params(&f.params).unwrap_err().to_string();
        assert!(
            err.contains("params.parquet")
                && err.contains("split `holdout`, allowed `train`, `validation` or `test`"),
            "{err}"
        );
    }

    /// Names of the 19 input channels.
    fn input_names() -> Vec<&'static str> {
        let mut n = vec![schema::TIME];
        n.extend(schema::ETA_UNDER_WHEEL);
        n.extend(schema::PARAMETERS);
        n
    }

    /// The previous all-in-memory path, kept here as the reference: the whole table in f64,
    /// windows in f64 (`[inputs, outputs, _v, _a, eta]` blocks per sample), two-pass
    /// statistics over the training split.
    struct Reference {
        ids: Vec<i64>,
        phys: Vec<[Vec<f64>; 5]>,
        norm: Normalisation,
    }

    fn reference(f: &crate::synthetic::SyntheticFiles, window: &WindowConfig) -> Reference {
        use crate::norm::ChannelStats;
        let params: BTreeMap<i64, (Split, [f64; 14])> = read_params(&f.params)
            .unwrap()
            .into_iter()
            .map(|(i, s, p)| (i, (s, p)))
            .collect();
        let t = read_parquet(&f.simulation, None).unwrap();
        let ids = t.i64(schema::SAMPLE_ID).unwrap();
        let time = t.f64(schema::TIME).unwrap();
        let names = needed_simulation_columns();
        let cols: Vec<&[f64]> = names[2..].iter().map(|n| t.f64(n).unwrap()).collect();
        let mut phys: Vec<[Vec<f64>; 5]> = vec![];
        let mut out_ids = vec![];
        let mut train = vec![];
        let mut lo = 0;
        while lo < ids.len() {
            let hi = (lo..ids.len())
                .find(|&k| ids[k] != ids[lo])
                .unwrap_or(ids.len());
            let n = hi - lo;
            let keep: Vec<usize> = (window.first_index(n)..n)
                .step_by(window.time_stride)
                .map(|k| lo + k)
                .collect();
            let cols = &cols;
            let block = |r0: usize, r1: usize| -> Vec<f64> {
                keep.iter()
                    .flat_map(|&k| (r0..r1).map(move |c| cols[c][k]))
                    .collect()
            };
            let (split, p) = params[&ids[lo]];
            let tw: Vec<f64> = keep.iter().map(|&k| time[k]).collect();
            let eta = block(E0, SERIES);
            if split == Split::Train {
                train.push(phys.len());
            }
            phys.push([
                input_block(&tw, &eta, &p),
                block(U0, V0),
                block(V0, A0),
                block(A0, E0),
                eta,
            ]);
            out_ids.push(ids[lo]);
            lo = hi;
        }
        let stats = |g: usize, names: &[&str]| {
            ChannelStats::from_blocks(names, train.iter().map(|&i| phys[i][g].as_slice()))
        };
        let vel = velocity_names();
        let acc = acceleration_names();
        let norm = Normalisation {
            inputs: stats(0, &input_names()),
            outputs: stats(1, &schema::output_channels()),
            velocities: stats(2, &vel.iter().map(String::as_str).collect::<Vec<_>>()),
            accelerations: stats(3, &acc.iter().map(String::as_str).collect::<Vec<_>>()),
        };
        Reference {
            ids: out_ids,
            phys,
            norm,
        }
    }

    fn close(a: &crate::norm::ChannelStats, b: &crate::norm::ChannelStats) {
        assert_eq!(a.names, b.names);
        for k in 0..a.len() {
            let tol = 1e-12 * (a.mean[k].abs() + a.std[k]);
            assert!((a.mean[k] - b.mean[k]).abs() <= tol, "{} mean", a.names[k]);
            assert!(
                (a.std[k] - b.std[k]).abs() <= 1e-10 * a.std[k],
                "{} std",
                a.names[k]
            );
        }
    }

    #[test]
    fn streamed_f32_storage_matches_the_f64_path_and_splits_are_kept_apart() {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 3,
            n_validation: 2,
            n_test: 2,
            duration: 0.1,
            ..Default::default()
        };
        let f = write_dataset(&spec, dir.path()).unwrap();
        let window = WindowConfig {
            startup_fraction: 0.1,
            time_stride: 2,
        };
        let r = reference(&f, &window);
        let ds = load_dataset(
            &f.params,
            std::slice::from_ref(&f.simulation),
            None,
            &window,
        )
        .unwrap();
        // Training never sees the test split.
        assert_eq!(ds.split_indices(Split::Test), Vec::<usize>::new());
        assert_eq!(ds.split_indices(Split::Validation), vec![3, 4]);
        assert_eq!(ds.samples.len(), 5);
        // Statistics accumulated in one streaming f64 pass equal the two-pass ones.
        let norm = ds.normalisation().unwrap();
        close(&norm.inputs, &r.norm.inputs);
        close(&norm.outputs, &r.norm.outputs);
        close(&norm.velocities, &r.norm.velocities);
        close(&norm.accelerations, &r.norm.accelerations);
        assert_eq!(norm.outputs.names[14..], ["p_1", "p_2", "p_3", "p_4"]);
        // With the same statistics, the stored samples and the batches (inputs built at batch
        // time, parameters stored once) are bitwise those of the f64 path.
        let items = prepare(&ds, &norm).unwrap();
        let t = ds.t_points();
        let all: Vec<usize> = (0..items.len()).collect();
        let b = make_batch(&items, &all, t, &Device::Cpu).unwrap();
        let x: Vec<f32> = b.x.flatten_all().unwrap().to_vec1().unwrap();
        let u: Vec<f32> = b.u.flatten_all().unwrap().to_vec1().unwrap();
        let eta: Vec<f64> = b.eta.flatten_all().unwrap().to_vec1().unwrap();
        assert_eq!((items.len(), r.ids.len()), (5, 7));
        for (i, ph) in r.phys.iter().take(5).enumerate() {
            assert_eq!((items.id(i), ds.samples[i].id), (r.ids[i], r.ids[i]));
            let n = t * IN_CHANNELS;
            assert_eq!(&x[i * n..(i + 1) * n], &norm.inputs.normalise(&ph[0])[..]);
            let n = t * OUT_CHANNELS;
            assert_eq!(&u[i * n..(i + 1) * n], &norm.outputs.normalise(&ph[1])[..]);
            let se = items.series(i).unwrap();
            assert_eq!(se.v, norm.velocities.normalise(&ph[2]));
            assert_eq!(se.a, norm.accelerations.normalise(&ph[3]));
            assert_eq!(se.eta, ph[4]);
            let n = (t - 2) * 4;
            assert_eq!(&eta[i * n..(i + 1) * n], &ph[4][4..(t - 1) * 4]);
            // The f32 storage round-trips to the f64 values within f32 precision of the
            // z-scored value.
            let back = norm.outputs.denormalise(&se.u);
            for (k, (y, x)) in back.iter().zip(&ph[1]).enumerate() {
                let s = norm.outputs.std[k % OUT_CHANNELS];
                let z = (x - norm.outputs.mean[k % OUT_CHANNELS]) / s;
                assert!((y - x).abs() <= 1e-7 * s * z.abs().max(1.0), "{x} {y}");
            }
        }
        // One split alone, in one pass: the same values, index for index.
        let (test_ds, test_items) = load_split(
            &f.params,
            std::slice::from_ref(&f.simulation),
            &window,
            Split::Test,
            &norm,
        )
        .unwrap();
        assert_eq!(test_items.len(), 2);
        assert!(test_ds.samples.iter().all(|s| s.split == Split::Test));
        for (k, ph) in r.phys[5..].iter().enumerate() {
            assert_eq!(test_items.id(k), r.ids[5 + k]);
            let se = test_items.series(k).unwrap();
            assert_eq!(se.u, norm.outputs.normalise(&ph[1]));
            assert_eq!(se.a, norm.accelerations.normalise(&ph[3]));
            assert_eq!(se.eta, ph[4]);
        }
        assert_eq!(
            splits_present(&f.params).unwrap(),
            [Split::Train, Split::Validation, Split::Test].into()
        );
    }
}
