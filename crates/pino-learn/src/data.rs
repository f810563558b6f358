//! Datasets: Parquet artifacts -> a sample index and streamed windows -> z-scored f32
//! storage -> batches.
//!
//! Inputs are the artifacts of the physics stages: `params.parquet` (`sample_id`, `split`, the
//! sampled parameters), `simulation.parquet` shards (rows sorted by `sample_id` then `t`) and,
//! for algorithm 3, `weights.parquet` (`sample_id`, `phi_<dof>` of each equation); which
//! columns are read follows the [`Layout`] of the system description. Each record must have the
//! same uniform time grid; the window drops the first `startup_fraction` of it and keeps every
//! `time_stride`-th point, leaving `T` points with spacing `dt`.
//!
//! Memory is bounded by streaming: the simulation files are read batch by batch with column
//! projection (`pino_data::for_each_batch`), one record at a time is assembled in f64, and
//! only its window is kept, z-scored, in f32. [`load_dataset`] makes one such pass that
//! checks every record and accumulates the training split's normalisation statistics in f64
//! (no time series kept); [`prepare`] makes a second pass storing each sample once:
//! outputs `u [T, O]`, derivative targets `v, a [T, D]` (f32, z-scored), the excitations
//! `eta [T, E]` (f64, physical, for the ODE residual), in a [`SeriesStore`] (memory, or a
//! spill file past the memory budget), and the `P` parameters once per sample.
//! The `[T, 1 + E + P]` input block (`t`, excitations, parameters) is built only at batch
//! time, with the same arithmetic as an all-in-memory f64 load, bitwise.
//! [`load_split`] reads one split in a single pass (the `evaluate` stage).
//!
//! A [`Batch`] holds f32 z-scored tensors `x [B, T, 1 + E + P]`, `u [B, T, O]`, interior
//! derivative targets `v, a [B, T-2, D]`, and f64 physical `params [B, P]`, `eta [B, T, E]`,
//! `phi [B, Q]` (`Q` equations) and the force scale `f_scale [B]` for the ODE residual.

use crate::config::WindowConfig;
use crate::layout::{Layout, Record};
use crate::norm::{Normalisation, StatsAccumulator};
use crate::store::{SampleSeries, SeriesStore};
use crate::{Error, Result};
use candle_core::{DType, Device, Tensor};
use mbd_system::{Sampled, System};
use pino_data::{read_parquet, schema};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use mbd_dataset::Split;

/// The splits training reads: training and validation (the test and calibration splits stay
/// unseen by every choice the training makes).
fn trained_on(s: Split) -> bool {
    matches!(s, Split::Train | Split::Validation)
}

/// The message of an unknown split label.
fn unknown_split(label: &str) -> String {
    let allowed: Vec<String> = Split::ALL
        .iter()
        .map(|s| format!("`{}`", s.as_str()))
        .collect();
    format!("split `{label}`, allowed {}", allowed.join(", "))
}

/// One sample's identity: everything but its time series.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// `sample_id`.
    pub id: i64,
    /// Its split.
    pub split: Split,
    /// Its design: the sampled parameters' values.
    pub params: Sampled,
    /// ODE magnitude weights (N, N m) of each equation, when a weights file was given.
    pub phi: Option<Vec<f64>>,
    /// The force scale of its ODE residual (N): the mean static force of its contact
    /// elements (`mbd_engine::statics::contact_scale`), when it has some.
    pub force_scale: Option<f64>,
}

/// A windowed dataset: the index of the simulated samples, the window's grid, the training
/// split's normalisation statistics, and where to stream the time series from.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The channel layout.
    pub layout: Layout,
    /// Samples sorted by id.
    pub samples: Vec<Sample>,
    /// Times of the window (s), `T` values.
    pub t: Vec<f64>,
    /// Spacing of the window (s).
    pub dt: f64,
    /// Points of each full record before windowing.
    pub record_points: usize,
    simulation_files: Vec<PathBuf>,
    /// `params.parquet` as read by the index pass, kept for [`prepare`]'s second pass.
    params: Arc<ParamsTable>,
    window: WindowConfig,
    train_stats: Option<Normalisation>,
    info: DatasetInfo,
}

fn dataset_err(path: &Path, message: String) -> Error {
    Error::Dataset {
        path: path.to_owned(),
        message,
    }
}

/// Reads `params.parquet` ([`pino_data::records::read_params`]): `(sample_id, split, design)`
/// rows, a design of `system` each, each split label known.
pub fn read_params(path: &Path, system: &System) -> Result<Vec<(i64, Split, Sampled)>> {
    let names = system.sampled_names();
    let table = pino_data::records::read_params(std::slice::from_ref(&path.to_path_buf()), &names)?;
    table
        .ids
        .into_iter()
        .zip(&table.splits)
        .zip(table.values)
        .map(|((id, label), values)| {
            let split = Split::from_label(label).ok_or_else(|| {
                dataset_err(path, format!("sample {id}: {}", unknown_split(label)))
            })?;
            Ok((id, split, system.sampled_values(values)?))
        })
        .collect()
}

/// `params.parquet` read once, by sample id: what a streaming pass ([`scan`]) looks each
/// record up in.
#[derive(Debug)]
struct ParamsTable {
    /// The file (named in errors).
    file: PathBuf,
    /// Split and design per `sample_id`, ids ascending.
    by_id: BTreeMap<i64, (Split, Sampled)>,
}

impl ParamsTable {
    /// [`read_params`] of `file`, keyed by sample id.
    fn read(file: &Path, system: &System) -> Result<Arc<Self>> {
        let by_id = read_params(file, system)?
            .into_iter()
            .map(|(id, s, p)| (id, (s, p)))
            .collect();
        Ok(Arc::new(Self {
            file: file.to_owned(),
            by_id,
        }))
    }
}

/// Reads `weights.parquet` into `(sample_id, phi)` rows (the `phi_<dof>` of each equation of
/// `layout`); every phi must be finite and > 0.
pub fn read_weights(path: &Path, layout: &Layout) -> Result<Vec<(i64, Vec<f64>)>> {
    let names = layout.phi_columns();
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
        let phi: Vec<f64> = phis.iter().map(|p| p[r]).collect();
        if let Some(i) = phi.iter().position(|p| !(p.is_finite() && *p > 0.0)) {
            return Err(dataset_err(
                path,
                format!(
                    "sample {id}: {} = {} must be finite and > 0",
                    names[i], phi[i]
                ),
            ));
        }
        out.push((id, phi));
    }
    Ok(out)
}

/// The splits present in `params.parquet`, without reading any simulation.
pub fn splits_present(params_file: &Path) -> Result<BTreeSet<Split>> {
    Ok(splits_of(params_file)?.into_iter().collect())
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

/// A dataset's system description, read from its shards' records (`system.json`), with how
/// its data were simulated (`run.json`), when recorded.
#[derive(Debug, Clone)]
pub struct DatasetInfo {
    /// The description's text and overrides.
    pub source: mbd_system::SystemSource,
    /// It compiled.
    pub system: Arc<System>,
    /// The run and profile controls of the simulation.
    pub settings: Option<crate::checkpoint::DataSettings>,
    /// The channel layout a training reads: the description's, with the rate outputs a
    /// training asks for ([`DatasetInfo::with_rate_outputs`]).
    layout: Layout,
}

impl DatasetInfo {
    /// Reads the records of every shard directory (one description, checked).
    pub fn from_dirs(dirs: &[PathBuf]) -> Result<Self> {
        let (source, system) = pino_data::system::read_record(dirs)?;
        let run = dirs[0].join(pino_data::system::RUN_FILE);
        let settings = if run.is_file() {
            let v = pino_data::system::read_json(&run)?;
            Some(serde_json::from_value(v).map_err(|e| Error::Format {
                path: run.clone(),
                message: e.to_string(),
            })?)
        } else {
            None
        };
        Ok(Self {
            layout: Layout::of(&system),
            source,
            system: Arc::new(system),
            settings,
        })
    }

    /// From a description alone (tests, synthetic data).
    pub fn of(source: mbd_system::SystemSource) -> Result<Self> {
        let system = source.compile().map_err(|e| Error::Format {
            path: PathBuf::from(&source.file),
            message: e.to_string(),
        })?;
        Ok(Self {
            layout: Layout::of(&system),
            source,
            system: Arc::new(system),
            settings: None,
        })
    }

    /// The channel layout the datasets of this info are read with.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// This info reading the stored rates `names` as network outputs too
    /// ([`Layout::with_rate_outputs`]); refused for a column the description does not store.
    pub fn with_rate_outputs(mut self, names: &[String]) -> Result<Self> {
        self.layout = self.layout.with_rate_outputs(&self.system, names)?;
        Ok(self)
    }
}

/// Receives one windowed sample: the sample, the window's times and its series.
type WindowSink<'a> = dyn FnMut(&Sample, &[f64], &[Vec<f64>]) -> Result<()> + 'a;

/// The index pass: streams every record, checks ids and grids, and calls `on_window` with
/// the window's times and series (column-major, [`Layout::training_record`]'s columns of `T`
/// values) of each sample
/// whose id and split `want` accepts. Returns the dataset of those samples (no statistics).
fn scan(
    info: &DatasetInfo,
    params_table: &Arc<ParamsTable>,
    simulation_files: &[PathBuf],
    weights_file: Option<&Path>,
    window: &WindowConfig,
    want: &dyn Fn(i64, Split) -> bool,
    on_window: &mut WindowSink<'_>,
) -> Result<Dataset> {
    window.validate()?;
    let (params_file, params) = (params_table.file.as_path(), &params_table.by_id);
    let system = &info.system;
    let layout = info.layout().clone();
    // The weights stage covers the training split only; `train` checks that every training
    // sample has its phi when the algorithm needs it.
    let weights: BTreeMap<i64, Vec<f64>> = match weights_file {
        Some(w) => read_weights(w, &layout)?.into_iter().collect(),
        None => BTreeMap::new(),
    };
    let names = layout.simulation_columns();
    let columns: Vec<&str> = names[1..].iter().map(String::as_str).collect();
    let first_file = simulation_files.first().ok_or_else(|| {
        dataset_err(
            params_file,
            "no simulation.parquet given for these parameters".into(),
        )
    })?;
    let mut grid: Option<Grid> = None;
    let mut samples = Vec::new();
    let mut t_window: Vec<f64> = Vec::new();
    let mut windowed: Vec<Vec<f64>> = vec![Vec::new(); layout.training_record().width()];
    pino_data::records::for_each_record::<Error>(simulation_files, &columns, &mut |file, rec| {
        let (id, cols) = (rec.id, &rec.columns);
        check_grid(file, id, &cols[0], &mut grid)?;
        let Some((split, p)) = params.get(&id) else {
            return Err(dataset_err(
                params_file,
                format!("sample {id} is in the simulation but not in the parameters file"),
            ));
        };
        let n = cols[0].len();
        let keep = window.rows(n);
        if t_window.is_empty() {
            t_window = keep.clone().map(|k| cols[0][k]).collect();
        }
        if !want(id, *split) {
            return Ok(());
        }
        let force_scale = system
            .instantiate(p)
            .ok()
            .and_then(|m| mbd_engine::statics::contact_scale(system, &m));
        let sample = Sample {
            id,
            split: *split,
            params: p.clone(),
            phi: weights.get(&id).cloned(),
            force_scale,
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
        layout,
        samples,
        t: t_window,
        dt: dt * window.time_stride as f64,
        record_points,
        simulation_files: simulation_files.to_vec(),
        params: Arc::clone(params_table),
        window: *window,
        train_stats: None,
        info: info.clone(),
    })
}

/// Streaming accumulators of the four statistic groups.
struct NormAccumulator {
    record: Record,
    t: StatsAccumulator,
    eta: StatsAccumulator,
    params: StatsAccumulator,
    outputs: StatsAccumulator,
    velocities: StatsAccumulator,
    accelerations: StatsAccumulator,
}

impl NormAccumulator {
    fn new(l: &Layout) -> Self {
        let names = |v: &[String]| -> Vec<String> { v.to_vec() };
        let acc = |v: Vec<String>| {
            let r: Vec<&str> = v.iter().map(String::as_str).collect();
            StatsAccumulator::new(&r)
        };
        Self {
            record: l.training_record(),
            t: StatsAccumulator::new(&[schema::TIME]),
            eta: acc(names(&l.excitations)),
            params: acc(names(&l.params)),
            outputs: acc(names(&l.outputs)),
            velocities: acc(l.velocities()),
            accelerations: acc(l.accelerations()),
        }
    }

    fn add(&mut self, t: &[f64], s: &Sample, w: &[Vec<f64>]) {
        let refs =
            |r: std::ops::Range<usize>| -> Vec<&[f64]> { w[r].iter().map(Vec::as_slice).collect() };
        let r = &self.record;
        self.t.add_columns(&[t]);
        self.eta.add_columns(&refs(r.excitations.clone()));
        self.params.add_constant(s.params.as_slice(), t.len());
        self.outputs.add_columns(&refs(r.displacements.clone()));
        self.velocities.add_columns(&refs(r.velocities.clone()));
        self.accelerations
            .add_columns(&refs(r.accelerations.clone()));
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
    info: &DatasetInfo,
    params_file: &Path,
    simulation_files: &[PathBuf],
    weights_file: Option<&Path>,
    window: &WindowConfig,
) -> Result<Dataset> {
    load_dataset_subset(
        info,
        params_file,
        simulation_files,
        weights_file,
        window,
        None,
    )
}

/// [`load_dataset`] keeping only the first `train_samples` samples of the training split (by
/// sample id; `None`: all of them), the validation split whole: a budget study trains on less
/// data of the same dataset and is judged on the same validation samples. The normalisation
/// statistics are those of the samples kept.
pub fn load_dataset_subset(
    info: &DatasetInfo,
    params_file: &Path,
    simulation_files: &[PathBuf],
    weights_file: Option<&Path>,
    window: &WindowConfig,
    train_samples: Option<usize>,
) -> Result<Dataset> {
    let layout = info.layout();
    let params = ParamsTable::read(params_file, &info.system)?;
    // Ids in ascending order (a BTreeMap's): the first `n` of the training split.
    let kept_train: Option<BTreeSet<i64>> = train_samples.map(|n| {
        params
            .by_id
            .iter()
            .filter(|(_, (split, _))| *split == Split::Train)
            .map(|(&id, _)| id)
            .take(n)
            .collect()
    });
    let mut acc = NormAccumulator::new(layout);
    let mut any_train = false;
    let mut ds = scan(
        info,
        &params,
        simulation_files,
        weights_file,
        window,
        &|id, s| {
            trained_on(s)
                && (s != Split::Train || kept_train.as_ref().is_none_or(|k| k.contains(&id)))
        },
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

    /// The force scale `F_ref` of the global ODE loss (N): the mean over the training split of
    /// each sample's mean static contact force (`W` for the vehicle-track model); `None` when
    /// the description has no contact element or its rigid part is not statically determinate.
    pub fn force_scale(&self) -> Option<f64> {
        let train: Vec<&Sample> = self
            .samples
            .iter()
            .filter(|s| s.split == Split::Train)
            .collect();
        let scales: Option<Vec<f64>> = train.iter().map(|s| s.force_scale).collect();
        let scales = scales.filter(|v| !v.is_empty())?;
        let sum: f64 = scales.iter().sum();
        Some(sum / scales.len() as f64)
    }

    /// The system description of the data.
    pub fn system(&self) -> &Arc<System> {
        &self.info.system
    }

    /// The description's record and the simulation settings.
    pub fn info(&self) -> &DatasetInfo {
        &self.info
    }

    /// Z-score statistics over the training split (accumulated by [`load_dataset`]).
    pub fn normalisation(&self) -> Result<Normalisation> {
        self.train_stats.clone().ok_or_else(|| Error::Dataset {
            path: self.params.file.clone(),
            message: "no sample of split `train`: normalisation needs training data".into(),
        })
    }

    /// The `params.parquet` it was indexed from.
    pub fn params_file(&self) -> &Path {
        &self.params.file
    }

    /// The simulation files it streams from.
    pub fn simulation_files(&self) -> &[PathBuf] {
        &self.simulation_files
    }
}

/// Physical input block `[T, 1 + E + P]`: `t`, the excitations (`eta` row-major `[T, E]`),
/// the parameters.
pub fn input_block(t: &[f64], eta: &[f64], params: &[f64]) -> Vec<f64> {
    let e = if t.is_empty() { 0 } else { eta.len() / t.len() };
    let mut out = Vec::with_capacity(t.len() * (1 + e + params.len()));
    for (k, &tk) in t.iter().enumerate() {
        out.push(tk);
        out.extend_from_slice(&eta[e * k..e * k + e]);
        out.extend_from_slice(params);
    }
    out
}

/// Samples prepared for batching, each stored once: z-scored f32 outputs `[T, O]` and
/// derivative targets `[T, D]`, physical f64 excitations `[T, E]` (in a [`SeriesStore`], in
/// memory or spilled to disk), the parameters once per sample (physical f64 and z-scored f32).
/// Index `i` is the `i`-th sample of the dataset (or of the split) it was prepared from.
#[derive(Debug)]
pub struct Prepared {
    layout: Layout,
    t_points: usize,
    /// z-scored window times `[T]`, shared by every sample.
    t_n: Vec<f32>,
    eta_mean: Vec<f64>,
    eta_std: Vec<f64>,
    ids: Vec<i64>,
    params: Vec<Vec<f64>>,
    params_n: Vec<Vec<f32>>,
    phi: Vec<Vec<f64>>,
    force_scale: Vec<f64>,
    /// Record of each sample in the store.
    slots: Vec<usize>,
    store: SeriesStore,
}

/// Z-scores a window's column-major group into a row-major f32 block.
fn zscore(cols: &[Vec<f64>], st: &crate::norm::ChannelStats) -> Vec<f32> {
    let c = cols.len();
    let rows = cols.first().map_or(0, Vec::len);
    let mut out = vec![0.0f32; rows * c];
    for (k, row) in out.chunks_exact_mut(c.max(1)).enumerate().take(rows) {
        for (j, x) in row.iter_mut().enumerate().take(c) {
            *x = ((cols[j][k] - st.mean[j]) / st.std[j]) as f32;
        }
    }
    out
}

/// Builds a [`Prepared`] from streamed windows (any order), then orders it like a dataset.
struct Builder<'a> {
    norm: &'a Normalisation,
    record: Record,
    store: SeriesStore,
    by_id: BTreeMap<i64, usize>,
}

impl<'a> Builder<'a> {
    fn new(
        norm: &'a Normalisation,
        layout: &Layout,
        t_points: usize,
        expected: usize,
    ) -> Result<Self> {
        Ok(Self {
            norm,
            record: layout.training_record(),
            store: SeriesStore::new(t_points, layout.series_shape(), expected)?,
            by_id: BTreeMap::new(),
        })
    }

    fn add(&mut self, s: &Sample, w: &[Vec<f64>]) -> Result<()> {
        let (n, r) = (self.norm, &self.record);
        let rows = w[0].len();
        let ne = r.excitations.len();
        let mut eta = vec![0.0; rows * ne];
        for (k, row) in eta
            .chunks_exact_mut(ne.max(1))
            .enumerate()
            .take(if ne == 0 { 0 } else { rows })
        {
            for (i, x) in row.iter_mut().enumerate() {
                *x = w[r.excitations.start + i][k];
            }
        }
        let slot = self.store.push(&SampleSeries {
            u: zscore(&w[r.displacements.clone()], &n.outputs),
            v: zscore(&w[r.velocities.clone()], &n.velocities),
            a: zscore(&w[r.accelerations.clone()], &n.accelerations),
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
            ..
        } = self;
        let ins = &norm.inputs;
        let layout = ds.layout.clone();
        let inputs = layout.input_ranges();
        let n_eq = layout.equations.len();
        let mut p = Prepared {
            t_points: ds.t.len(),
            t_n: ds
                .t
                .iter()
                .map(|&x| ((x - ins.mean[inputs.time]) / ins.std[inputs.time]) as f32)
                .collect(),
            eta_mean: ins.mean[inputs.excitations.clone()].to_vec(),
            eta_std: ins.std[inputs.excitations.clone()].to_vec(),
            ids: Vec::with_capacity(ds.samples.len()),
            params: Vec::with_capacity(ds.samples.len()),
            params_n: Vec::with_capacity(ds.samples.len()),
            phi: Vec::with_capacity(ds.samples.len()),
            force_scale: Vec::with_capacity(ds.samples.len()),
            slots: Vec::with_capacity(ds.samples.len()),
            store,
            layout,
        };
        for s in &ds.samples {
            let slot = by_id.remove(&s.id).expect("every indexed sample streamed");
            p.ids.push(s.id);
            p.params.push(s.params.as_slice().to_vec());
            p.params_n.push(
                s.params
                    .as_slice()
                    .iter()
                    .zip(inputs.params.clone())
                    .map(|(v, k)| ((v - ins.mean[k]) / ins.std[k]) as f32)
                    .collect(),
            );
            p.phi.push(s.phi.clone().unwrap_or_else(|| vec![1.0; n_eq]));
            p.force_scale.push(s.force_scale.unwrap_or(1.0));
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

    /// The layout.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The series of sample `i`: z-scored `u [T, O]`, `v, a [T, D]`, physical `eta [T, E]`.
    pub fn series(&self, i: usize) -> Result<SampleSeries> {
        self.store.get(self.slots[i])
    }

    /// Parameters of sample `i`.
    pub fn params(&self, i: usize) -> &[f64] {
        &self.params[i]
    }

    /// Force scale of sample `i` (N): its mean static contact force (1 when it has none).
    pub fn force_scale(&self, i: usize) -> f64 {
        self.force_scale[i]
    }

    /// Whether the series were spilled to disk (over the memory budget).
    pub fn spilled(&self) -> bool {
        self.store.spilled()
    }

    /// z-scored input block `[T, 1 + E + P]` of a sample with excitations `eta` and index `i`,
    /// appended to `out`: the same values as `norm.inputs.normalise(&input_block(..))`.
    fn push_inputs(&self, i: usize, eta: &[f64], out: &mut Vec<f32>) {
        let pn = &self.params_n[i];
        let ne = self.eta_mean.len();
        for (k, &tn) in self.t_n.iter().enumerate() {
            out.push(tn);
            for j in 0..ne {
                out.push(((eta[ne * k + j] - self.eta_mean[j]) / self.eta_std[j]) as f32);
            }
            out.extend_from_slice(pn);
        }
    }

    /// Bytes held in memory by the samples (series in memory plus per-sample values).
    pub fn heap_bytes(&self) -> usize {
        let p = self.layout.params.len();
        self.store.memory_bytes()
            + 4 * self.t_n.len()
            + self.ids.len() * (8 + p * 8 + p * 4 + self.layout.equations.len() * 8 + 16)
    }
}

/// Loads and z-scores every sample of `ds` (a second streaming pass over its simulation
/// files; the parameters are those the index pass read).
pub fn prepare(ds: &Dataset, norm: &Normalisation) -> Result<Prepared> {
    let mut b = Builder::new(norm, &ds.layout, ds.t.len(), ds.samples.len())?;
    let wanted: BTreeSet<i64> = ds.samples.iter().map(|s| s.id).collect();
    scan(
        &ds.info,
        &ds.params,
        &ds.simulation_files,
        None,
        &ds.window,
        &|id, _| wanted.contains(&id),
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
    info: &DatasetInfo,
    params_file: &Path,
    simulation_files: &[PathBuf],
    window: &WindowConfig,
    split: Split,
    norm: &Normalisation,
) -> Result<(Dataset, Prepared)> {
    let layout = info.layout();
    let params = ParamsTable::read(params_file, &info.system)?;
    let expected = params.by_id.values().filter(|(s, _)| *s == split).count();
    let mut builder: Option<Builder> = None;
    let ds = scan(
        info,
        &params,
        simulation_files,
        None,
        window,
        &|_, s| s == split,
        &mut |s, t, w| {
            if builder.is_none() {
                builder = Some(Builder::new(norm, layout, t.len(), expected)?);
            }
            builder.as_mut().expect("created").add(s, w)
        },
    )?;
    let b = match builder {
        Some(b) => b,
        None => Builder::new(norm, layout, ds.t.len(), 0)?,
    };
    let items = b.finish(&ds);
    Ok((ds, items))
}

/// One batch of tensors (see the module doc for shapes).
#[derive(Debug, Clone)]
pub struct Batch {
    /// Inputs `[B, T, 1 + E + P]` f32 z-scored.
    pub x: Tensor,
    /// Target outputs `[B, T, O]` f32 z-scored (solutions, then forces).
    pub u: Tensor,
    /// Target velocities at interior points `[B, T-2, D]` f32 z-scored.
    pub v: Tensor,
    /// Target accelerations at interior points `[B, T-2, D]` f32 z-scored.
    pub a: Tensor,
    /// Parameters `[B, P]` f64 physical.
    pub params: Tensor,
    /// Excitations `[B, T, E]` f64 physical (m).
    pub eta: Tensor,
    /// ODE magnitude weights `[B, Q]` f64 (ones when absent).
    pub phi: Tensor,
    /// The samples' force scales `[B]` f64 (N; 1 when absent).
    pub f_scale: Tensor,
    /// Index of each sample in its [`Prepared`].
    pub index: Vec<usize>,
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
    let l = &items.layout;
    let (n_in, n_out, d, e) = (l.n_inputs(), l.n_outputs(), l.n_dofs(), l.n_excitations());
    let mut x = Vec::with_capacity(b * t * n_in);
    let mut u = Vec::with_capacity(b * t * n_out);
    let mut v = Vec::with_capacity(b * (t - 2) * d);
    let mut a = Vec::with_capacity(b * (t - 2) * d);
    let mut eta = Vec::with_capacity(b * t * e);
    for &i in idx {
        let s = items.series(i)?;
        items.push_inputs(i, &s.eta, &mut x);
        u.extend_from_slice(&s.u);
        v.extend_from_slice(&s.v[d..(t - 1) * d]);
        a.extend_from_slice(&s.a[d..(t - 1) * d]);
        eta.extend_from_slice(&s.eta);
    }
    let params: Vec<f64> = idx
        .iter()
        .flat_map(|&i| items.params[i].iter().copied())
        .collect();
    let phi: Vec<f64> = idx
        .iter()
        .flat_map(|&i| items.phi[i].iter().copied())
        .collect();
    let f_scale: Vec<f64> = idx.iter().map(|&i| items.force_scale[i]).collect();
    let n_eq = l.equations.len();
    Ok(Batch {
        x: Tensor::from_vec(x, (b, t, n_in), device)?,
        u: Tensor::from_vec(u, (b, t, n_out), device)?,
        v: Tensor::from_vec(v, (b, t - 2, d), device)?,
        a: Tensor::from_vec(a, (b, t - 2, d), device)?,
        params: Tensor::from_vec(params, (b, l.params.len()), device)?,
        eta: Tensor::from_vec(eta, (b, t, e), device)?,
        phi: Tensor::from_vec(phi, (b, n_eq), device)?.to_dtype(DType::F64)?,
        f_scale: Tensor::from_vec(f_scale, b, device)?,
        index: idx.to_vec(),
    })
}

/// The split label of every row of `params.parquet`.
fn splits_of(params_file: &Path) -> Result<Vec<Split>> {
    let t = read_parquet(params_file, Some(&[schema::SPLIT]))?;
    t.str(schema::SPLIT)?
        .iter()
        .map(|label| {
            Split::from_label(label).ok_or_else(|| dataset_err(params_file, unknown_split(label)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{write_dataset, SyntheticSpec};
    use pino_data::units::Units;
    use pino_data::{read_parquet, write_parquet, Column, Table};

    /// Rewrites `file` (columns with `units`) keeping the rows where `keep(row)` and the
    /// columns where `col(name)`.
    fn rewrite(
        file: &Path,
        units: &Units,
        keep: &dyn Fn(usize) -> bool,
        col: &dyn Fn(&str) -> bool,
    ) {
        let t = read_parquet(file, None).unwrap();
        let rows: Vec<usize> = (0..t.num_rows()).filter(|&r| keep(r)).collect();
        let mut out = Table::default().with_units(units.clone());
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
        let units = pino_data::system::units_of(&spec.system.compile().unwrap()).unwrap();
        let ds = f.load(&window(), true).unwrap();
        let layout = ds.layout.clone();
        // 100 points, the first 10 dropped.
        assert_eq!((ds.t_points(), ds.record_points), (90, 100));
        assert!((ds.t[0] - 0.01).abs() < 1e-12 && (ds.dt - 1e-3).abs() < 1e-15);
        assert_eq!(ds.split_indices(Split::Validation), vec![2]);
        let norm = ds.normalisation().unwrap();
        // Stats come from the training split only: sample 2's parameters do not move them.
        let m_c = layout.input_ranges().params.start;
        assert_eq!(norm.inputs.names[m_c], layout.params[0]);
        let m_c_of = |i: usize| ds.samples[i].params.get("m_c").unwrap();
        let m_c_mean = (m_c_of(0) + m_c_of(1)) / 2.0;
        assert!((norm.inputs.mean[m_c] - m_c_mean).abs() < 1e-9 * m_c_mean);
        assert_ne!(m_c_of(2), m_c_mean);

        // Mismatched record lengths: sample 1 loses its last row.
        rewrite(&f.simulation, &units, &|r| r != 199, &|_| true);
        let err = f.load(&window(), false).unwrap_err().to_string();
        assert!(
            err.contains("sample 1 has 99 time points but sample 0 has 100"),
            "{err}"
        );

        // A missing column is named with its file.
        rewrite(&f.simulation, &units, &|_| true, &|c| c != "beta_t2_v");
        let err = f.load(&window(), false).unwrap_err().to_string();
        assert!(
            err.contains("simulation.parquet") && err.contains("missing column `beta_t2_v`"),
            "{err}"
        );

        // A missing contact-force column (an output channel, read before the derivatives) is
        // named with its file.
        rewrite(&f.simulation, &units, &|_| true, &|c| c != "p_3");
        let err = f.load(&window(), false).unwrap_err().to_string();
        assert!(
            err.contains("simulation.parquet") && err.contains("missing column `p_3`"),
            "{err}"
        );

        // A non-positive phi is refused with its sample and column.
        let w = read_parquet(&f.weights, None).unwrap();
        let mut bad = Table::default().with_units(units.clone());
        for (name, c) in w.columns() {
            let c = match (name.as_str(), c) {
                ("phi_z_t2", Column::F64(v)) => Column::F64(v.iter().map(|_| 0.0).collect()),
                _ => c.clone(),
            };
            bad.push(name, c).unwrap();
        }
        write_parquet(&f.weights, &bad).unwrap();
        let err = read_weights(&f.weights, &layout).unwrap_err().to_string();
        assert!(err.contains("sample 0: phi_z_t2 = 0"), "{err}");

        // An unknown split label is refused with the allowed ones.
        rewrite(&f.params, &units, &|_| true, &|_| true);
        let p = read_parquet(&f.params, None).unwrap();
        let mut bad = Table::default().with_units(units.clone());
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
        let system = f.info().unwrap().system;
        let err = read_params(&f.params, &system).unwrap_err().to_string();
        assert!(
            err.contains("params.parquet")
                && err.contains(
                    "split `holdout`, allowed `train`, `validation`, `test`, `calibration`"
                ),
            "{err}"
        );
    }

    /// The training window of these tests: the first 10 % dropped, every point kept.
    fn window() -> WindowConfig {
        WindowConfig {
            startup_fraction: 0.1,
            time_stride: 1,
        }
    }

    /// The previous all-in-memory path, kept here as the reference: the whole table in f64,
    /// windows in f64 (`[inputs, outputs, _v, _a, eta]` blocks per sample), two-pass
    /// statistics over the training split.
    struct Reference {
        ids: Vec<i64>,
        phys: Vec<[Vec<f64>; 5]>,
        norm: Normalisation,
    }

    fn reference(
        f: &crate::synthetic::SyntheticFiles,
        layout: &Layout,
        window: &WindowConfig,
    ) -> Reference {
        use crate::norm::ChannelStats;
        let system = f.info().unwrap().system;
        let params: BTreeMap<i64, (Split, Sampled)> = read_params(&f.params, &system)
            .unwrap()
            .into_iter()
            .map(|(i, s, p)| (i, (s, p)))
            .collect();
        let t = read_parquet(&f.simulation, None).unwrap();
        let ids = t.i64(schema::SAMPLE_ID).unwrap();
        let time = t.f64(schema::TIME).unwrap();
        let names = layout.simulation_columns();
        let cols: Vec<&[f64]> = names[2..].iter().map(|n| t.f64(n).unwrap()).collect();
        let r = layout.training_record();
        let mut phys: Vec<[Vec<f64>; 5]> = vec![];
        let mut out_ids = vec![];
        let mut train = vec![];
        let mut lo = 0;
        while lo < ids.len() {
            let hi = (lo..ids.len())
                .find(|&k| ids[k] != ids[lo])
                .unwrap_or(ids.len());
            let keep: Vec<usize> = window.rows(hi - lo).map(|k| lo + k).collect();
            let cols = &cols;
            let block = |range: std::ops::Range<usize>| -> Vec<f64> {
                keep.iter()
                    .flat_map(|&k| range.clone().map(move |c| cols[c][k]))
                    .collect()
            };
            let (split, p) = &params[&ids[lo]];
            let tw: Vec<f64> = keep.iter().map(|&k| time[k]).collect();
            let eta = block(r.excitations.clone());
            if *split == Split::Train {
                train.push(phys.len());
            }
            phys.push([
                input_block(&tw, &eta, p.as_slice()),
                block(r.displacements.clone()),
                block(r.velocities.clone()),
                block(r.accelerations.clone()),
                eta,
            ]);
            out_ids.push(ids[lo]);
            lo = hi;
        }
        let stats = |k: usize, names: &[String]| {
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            ChannelStats::from_blocks(&names, train.iter().map(|&i| phys[i][k].as_slice()))
        };
        let norm = Normalisation {
            inputs: stats(0, &layout.inputs()),
            outputs: stats(1, &layout.outputs),
            velocities: stats(2, &layout.velocities()),
            accelerations: stats(3, &layout.accelerations()),
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
    fn a_training_subset_keeps_the_first_training_samples_and_the_whole_validation_split() {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 4,
            n_validation: 2,
            n_test: 1,
            duration: 0.1,
            ..Default::default()
        };
        let f = write_dataset(&spec, dir.path()).unwrap();
        let window = WindowConfig {
            startup_fraction: 0.1,
            time_stride: 1,
        };
        let load = |n| {
            load_dataset_subset(
                &f.info().unwrap(),
                &f.params,
                std::slice::from_ref(&f.simulation),
                None,
                &window,
                n,
            )
            .unwrap()
        };
        let ids = |ds: &Dataset, split| -> Vec<i64> {
            ds.split_indices(split)
                .iter()
                .map(|&i| ds.samples[i].id)
                .collect()
        };
        let all = load(None);
        let two = load(Some(2));
        assert_eq!(ids(&all, Split::Train), vec![0, 1, 2, 3]);
        assert_eq!(ids(&two, Split::Train), vec![0, 1]);
        assert_eq!(ids(&two, Split::Validation), ids(&all, Split::Validation));
        // The statistics are those of the samples kept, not of the whole split.
        let (a, b) = (all.normalisation().unwrap(), two.normalisation().unwrap());
        assert_ne!(a.outputs.mean, b.outputs.mean);
        // More than the split holds keeps it whole; none is an error naming the split.
        assert_eq!(ids(&load(Some(10)), Split::Train), vec![0, 1, 2, 3]);
        let err = load(Some(0)).normalisation().unwrap_err().to_string();
        assert!(err.contains("no sample of split `train`"), "{err}");
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
        let ds = f.load(&window, false).unwrap();
        let layout = ds.layout.clone();
        let (n_in, n_out, n_e) = (
            layout.n_inputs(),
            layout.n_outputs(),
            layout.n_excitations(),
        );
        let r = reference(&f, &layout, &window);
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
        assert_eq!(
            norm.outputs.names[layout.forces()],
            ["p_1", "p_2", "p_3", "p_4"]
        );
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
            let n = t * n_in;
            assert_eq!(&x[i * n..(i + 1) * n], &norm.inputs.normalise(&ph[0])[..]);
            let n = t * n_out;
            assert_eq!(&u[i * n..(i + 1) * n], &norm.outputs.normalise(&ph[1])[..]);
            let se = items.series(i).unwrap();
            assert_eq!(se.v, norm.velocities.normalise(&ph[2]));
            assert_eq!(se.a, norm.accelerations.normalise(&ph[3]));
            assert_eq!(se.eta, ph[4]);
            let n = t * n_e;
            assert_eq!(&eta[i * n..(i + 1) * n], &ph[4][..]);
            // The f32 storage round-trips to the f64 values within f32 precision of the
            // z-scored value.
            let back = norm.outputs.denormalise(&se.u);
            for (k, (y, x)) in back.iter().zip(&ph[1]).enumerate() {
                let s = norm.outputs.std[k % n_out];
                let z = (x - norm.outputs.mean[k % n_out]) / s;
                assert!((y - x).abs() <= 1e-7 * s * z.abs().max(1.0), "{x} {y}");
            }
        }
        // One split alone, in one pass: the same values, index for index.
        let (test_ds, test_items) = f.load_split(&window, Split::Test, &norm).unwrap();
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
