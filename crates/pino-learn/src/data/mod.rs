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
//! `eta [T, E]` (f64, physical, for the ODE residual), in a
//! [`SeriesStore`](crate::store::SeriesStore) (memory, or a spill file past the memory
//! budget), and the `P` parameters once per sample.
//! The `[T, 1 + E + P]` input block (`t`, excitations, parameters) is built only at batch
//! time, with the same arithmetic as an all-in-memory f64 load, bitwise.
//! [`load_split`] reads one split in a single pass (the `evaluate` stage).
//!
//! A [`Batch`] holds f32 z-scored tensors `x [B, T, 1 + E + P]`, `u [B, T, O]`, interior
//! derivative targets `v, a [B, T-2, D]`, and f64 physical `params [B, P]`, `eta [B, T, E]`,
//! `phi [B, Q]` (`Q` equations) and the force scale `f_scale [B]` for the ODE residual.

mod batch;
mod files;
mod prepared;

pub use batch::{make_batch, Batch};
use files::{dataset_err, ParamsTable};
pub use files::{read_params, read_weights, splits_present};
pub use prepared::{input_block, load_split, prepare, Prepared};

use crate::config::WindowConfig;
use crate::layout::{Layout, Record};
use crate::norm::{Normalisation, StatsAccumulator};
use crate::{Error, Result};
use mbd_system::{Sampled, System};
use pino_data::schema;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use mbd_dataset::Split;

/// The splits training reads: training and validation (the test and calibration splits stay
/// unseen by every choice the training makes).
fn trained_on(s: Split) -> bool {
    matches!(s, Split::Train | Split::Validation)
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
        let run = dirs[0].join(pino_data::artifacts::RUN_FILE);
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
    /// each sample's mean static contact force (`W` for the vehicle-track models,
    /// [`mbd_engine::statics::contact_scale`]); `None` when a sample has none.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{write_dataset, SyntheticSpec};
    use candle_core::Device;
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
                Column::Bool(v) => Column::Bool(rows.iter().map(|&r| v[r]).collect()),
                Column::OptStr(v) => Column::OptStr(rows.iter().map(|&r| v[r].clone()).collect()),
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
