//! Prediction for design exploration: a trained model, designs (values of its system's
//! sampled parameters) and the profiles under the system in, every output channel of the
//! model (displacements and forces), the rigid DOFs' velocities and accelerations and the
//! excitations out, from one forward pass per batch. Nothing here knows a particular system:
//! names, counts and defaults come from the model's description (`model.json`).
//!
//! A design lists values by parameter name; the parameters it leaves out take the
//! description's nominal values (with the overrides the model's data were simulated with).
//! The excitation under each element follows the simulation exactly
//! ([`mbd_engine::Excitations`]): the model's run controls (`x0`, start-up ramp, duration)
//! from the dataset's `run.json`, the profile points from a profile file (the `irregularity`
//! artifact, one sample) or generated as `irregularity` generates them (the dataset's spacing
//! and length, a seed and sample id). The model sees the window of times it was trained on;
//! output rows are the interior points of the window (`n = 1..T-2`), where the
//! central-difference derivatives exist: `set, t, <outputs>, <dof>_v.., <dof>_a..,
//! <excitations>` (SI units, forces N).
//!
//! Designs come from YAML, a list of maps or `{sets: [...]}`, from `name=value` overrides
//! applied to every set, and from sweeps ([`parse_sweep`]): a grid or a seeded random sample
//! over ranges. [`Predictor`] runs them in batches (side by side on the CPU) and computes the
//! description's engineering indices ([`Predictor::indices`], as `evaluate` rebuilds them from
//! a prediction). Designs outside the model's training ranges
//! ([`pino_learn::checkpoint::TrainingRanges`]) are reported by [`Predictor::outside_training`]
//! and flagged on every row of their histories ([`Predictor::flag_rows`]).
//!
//! Modules: the designs ([`DesignSpace`]), their profiles ([`profiles`]) and sweeps
//! ([`parse_sweep`]) live in private modules re-exported here; [`solve`] runs a design through
//! the exact solver in a prediction's form (the explorer's "Solve exactly", the studies' solver
//! checks). The channels of a prediction and its indices are `pino-outputs`'; the calibration
//! an answer carries is `pino-calibration`'s.
#![warn(missing_docs)]

pub mod solve;

mod design;
mod profiles;
mod request;
mod sweep;

pub use design::DesignSpace;
use pino_outputs::channels::{prediction_channels, ChannelSource};
use profiles::generated_names;
pub use profiles::{
    profiles, profiles_of_samples, profiles_of_table, GeneratedProfiles, ProfileChoice,
    ProfileSource, PROFILE_COLUMN,
};
pub use request::{outside_message, DesignSource, OUTSIDE_SHOWN};
pub use sweep::{parse_sweep, MAX_SWEEP};

use candle_core::{Device, Tensor};
use mbd_engine::{Excitations, Profile, RunConfig};
use mbd_system::system::Quantity;
use mbd_system::System;
use pino_calibration::difficulty::ResidualProbe;
use pino_calibration::{CalibratedAnswer, Calibration, ModelIdentity};
use pino_data::{schema, Column, Table};
use pino_indices::system::IndexInfo;
use pino_indices::IndexConfig;
use pino_learn::checkpoint::{load_model, ModelMeta, OutOfRange};
use pino_learn::data::input_block;
use pino_learn::model::Fno;
use pino_learn::spectral::Transform;
use pino_learn::Error as LearnError;
use pino_outputs::indices_eval::{eval_config, IndexInputs, SampleIndices};
use pino_outputs::physical::{to_physical, Physical};
pub use pino_outputs::{Error, Result};
use std::path::Path;
use std::sync::Arc;

/// A trained model loaded for prediction.
pub struct Predictor {
    model: Fno,
    /// Its metadata (window, statistics, training ranges, system, run controls).
    pub meta: ModelMeta,
    /// Its system's design parameters.
    pub space: DesignSpace,
    system: Arc<System>,
    /// What each excitation column holds (a profile or its rate, [`Excitations::column`]).
    excitation_columns: Vec<Quantity>,
    indices: IndexInputs,
    device: Device,
    identity: ModelIdentity,
    calibration: Option<Calibration>,
    probe: Option<ResidualProbe>,
    /// What a refusal calls the designs (`sets[k]`, `predict`'s; [`Predictor::name_designs`]).
    designs: String,
}

/// One design's answer: its indices, and what a calibration adds to them.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignAnswer {
    /// The predicted indices with their point verdict.
    pub indices: SampleIndices,
    /// Intervals, bands and three-valued verdicts, when the model is calibrated.
    pub calibrated: Option<CalibratedAnswer>,
}

/// One design's prediction in physical units: outputs `[T, O]`, interior velocities and
/// accelerations `[T-2, D]` ([`Physical`]), and the excitations `[T, E]`.
#[derive(Debug, Clone)]
pub struct SetPrediction {
    /// Outputs and derivatives.
    pub physical: Physical,
    /// The excitations (m).
    pub eta: Vec<f64>,
}

impl Predictor {
    /// Loads `model.safetensors` + `model.json` from `model_dir`.
    pub fn load(model_dir: &Path, device: &Device) -> Result<Self> {
        let (model, meta) = load_model(model_dir, Transform::for_device(device), device)?;
        let meta_path = model_dir.join(pino_learn::checkpoint::MODEL_META);
        let system = Arc::new(meta.compile_system(&meta_path)?);
        if !meta.layout.follows(&system) {
            return Err(Error::format(
                &meta_path,
                "the stored layout does not follow from the stored system description (an edited model.json?)".into(),
            ));
        }
        let excitation_columns = meta
            .layout
            .excitations
            .iter()
            .map(
                |name| match system.channel(name).map(|c| system.channels[c].quantity) {
                    Some(q @ (Quantity::Excitation(_) | Quantity::ExcitationRate(_))) => Ok(q),
                    _ => Err(Error::format(
                        &meta_path,
                        format!("`{name}` is not an excitation of the system"),
                    )),
                },
            )
            .collect::<Result<_>>()?;
        let indices = IndexInputs::of(&system, &meta.layout)?;
        Ok(Self {
            model,
            space: DesignSpace::of(system.clone()),
            probe: ResidualProbe::new(&system, &meta.layout),
            system,
            excitation_columns,
            indices,
            meta,
            device: device.clone(),
            identity: ModelIdentity::of(model_dir)?,
            calibration: None,
            designs: "sets".to_owned(),
        })
    }

    /// Names the designs `label` in refusals (`label[k].NAME`; default `sets`, the name of
    /// `predict`'s YAML list): the Python package's are `designs`.
    pub fn name_designs(&mut self, label: &str) {
        label.clone_into(&mut self.designs);
    }

    /// The model's identity (the hashes of its files).
    pub fn identity(&self) -> &ModelIdentity {
        &self.identity
    }

    /// Reads the model's calibration from `path` (a `calibration.json` or the `calibrate`
    /// stage's output): refused when missing, corrupt, of another model, or when its
    /// quantities are not this model's indices and channels.
    pub fn load_calibration(&mut self, path: &Path) -> Result<&Calibration> {
        let cal = Calibration::load(path, &self.identity)?;
        if cal.has_intervals() {
            let names = |v: Vec<&str>| v.join(", ");
            let indices: Vec<&str> = self
                .indices
                .columns()
                .iter()
                .map(|c| c.name.as_str())
                .collect();
            let cal_indices: Vec<&str> = cal.indices.iter().map(|q| q.name.as_str()).collect();
            let channels = pino_calibration::scored::band_channels(&self.meta.layout);
            let chans: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
            let cal_chans: Vec<&str> = cal
                .channels
                .iter()
                .map(|c| c.quantity.name.as_str())
                .collect();
            let computable = self.indices.computable();
            if (computable && indices != cal_indices) || chans != cal_chans {
                return Err(Error::format(
                    path,
                    format!(
                        "the calibration's quantities (indices {}; channels {}) are not the model's (indices {}; channels {})",
                        names(cal_indices),
                        names(cal_chans),
                        names(if computable { indices } else { Vec::new() }),
                        names(chans)
                    ),
                ));
            }
        }
        Ok(self.calibration.insert(cal))
    }

    /// The level of the answers' intervals: `None` without a calibration or when it has no
    /// intervals (its `no_intervals` says why), else `coverage` (default
    /// [`pino_calibration::DEFAULT_COVERAGE`]) once the calibration can support it.
    pub fn interval_level(&self, coverage: Option<f64>) -> Result<Option<f64>> {
        let Some(cal) = self
            .calibration
            .as_ref()
            .filter(|c| c.no_intervals.is_none())
        else {
            return Ok(None);
        };
        let level = coverage.unwrap_or(pino_calibration::DEFAULT_COVERAGE);
        cal.at(level)?;
        Ok(Some(level))
    }

    /// The loaded calibration.
    pub fn calibration(&self) -> Option<&Calibration> {
        self.calibration.as_ref()
    }

    /// The calibrated answer of one prediction `p` of design `design` with index values
    /// `values` at `coverage` (with the channels' bands when `bands`); `None` without a
    /// calibration that has intervals.
    pub fn calibrated(
        &self,
        design: &[f64],
        p: &SetPrediction,
        values: &[f64],
        coverage: f64,
        bands: bool,
    ) -> Result<Option<CalibratedAnswer>> {
        let Some(cal) = self.calibration.as_ref().filter(|c| c.has_intervals()) else {
            return Ok(None);
        };
        let at = cal.at(coverage)?;
        let d = cal.difficulty(
            &self.system,
            self.probe.as_ref(),
            design,
            &p.physical,
            &p.eta,
            self.meta.grid.dt,
        )?;
        let limits = if values.is_empty() || cal.indices.is_empty() {
            Vec::new()
        } else {
            self.indices.limits(&self.system, &self.index_config()?)
        };
        let values = if cal.indices.is_empty() {
            &[][..]
        } else {
            values
        };
        let extrapolated = !self
            .meta
            .training_ranges
            .outside(&self.system.sampled_values(design)?)
            .is_empty();
        at.answer(&d, values, &limits, extrapolated, bands)
            .map(Some)
    }

    /// The model's system.
    pub fn system(&self) -> &Arc<System> {
        &self.system
    }

    /// The units of the columns of the model's system (parameters, channels, indices), which
    /// the tables of its answers carry ([`pino_data::system::units_of`] and
    /// [`pino_indices::column_units`]).
    pub fn units(&self) -> Result<pino_data::units::Units> {
        let units = pino_data::system::units_of(&self.system)?;
        Ok(units.with(pino_indices::column_units(&self.system))?)
    }

    /// The run controls of the model's data (`x0` replaced when given), or an error when the
    /// dataset recorded none.
    pub fn run_config(&self, x0: Option<f64>) -> Result<RunConfig> {
        let data = self.meta.data.as_ref().ok_or_else(|| {
            Error::format(
                Path::new(pino_data::artifacts::MODEL_META),
                "the model's dataset records no run controls (run.json of `simulate`): retrain on a dataset that has them".into(),
            )
        })?;
        let mut run = data.run;
        if let Some(x0) = x0 {
            run.x0 = x0;
        }
        Ok(run)
    }

    /// The points of the system's generated profiles from `choice`.
    pub fn profiles(&self, choice: Option<&ProfileChoice>) -> Result<Vec<Option<Profile>>> {
        let settings = self.meta.data.as_ref().and_then(|d| d.profiles.as_ref());
        profiles(&self.system, settings, choice)
    }

    /// The generators of the system's profiles at `seed` with the dataset's settings (none
    /// needed when every profile is analytic).
    pub fn profile_generators(&self, seed: u64) -> Result<GeneratedProfiles> {
        if generated_names(&self.system).is_empty() {
            return Ok(GeneratedProfiles {
                generators: vec![None; self.system.profiles.len()],
                what: String::new(),
            });
        }
        let settings = self.meta.data.as_ref().and_then(|d| d.profiles.as_ref());
        let settings = settings.ok_or_else(|| {
            Error::format(
                Path::new(pino_data::artifacts::MODEL_META),
                "the model's dataset records no profile settings (run.json): retrain on a dataset that has them".into(),
            )
        })?;
        GeneratedProfiles::new(&self.system, settings, seed)
    }

    /// The parameters of each design outside the model's training ranges, read by name; a
    /// design that is not one of the system's (another count) is refused.
    pub fn outside_training(&self, sets: &[Vec<f64>]) -> Result<Vec<Vec<OutOfRange>>> {
        sets.iter()
            .map(|p| {
                let design = self.system.sampled_values(p.as_slice())?;
                Ok(self.meta.training_ranges.outside(&design))
            })
            .collect()
    }

    /// The excitations of `design` under `run`: the design checked against the description's
    /// domains and the run against its profiles and beams, each refusal blamed on the design
    /// parameter at fault (`{label}.NAME`, [`DesignSpace::check`], [`DesignSpace::blame_run`]).
    pub fn excitations_of(
        &self,
        design: &[f64],
        profiles: &[Option<Profile>],
        run: &RunConfig,
        label: &str,
    ) -> Result<Excitations> {
        let model = self.space.check(design, label)?;
        let excitations = |model: &mbd_system::model::Model| {
            Excitations::new(&self.system, model, run, profiles.to_vec())
        };
        excitations(&model).map_err(|e| {
            self.space.blame_run(design, label, &e.to_string(), |d| {
                let model = self
                    .system
                    .sampled_values(d)
                    .map(|d| self.system.instantiate(&d));
                model.is_ok_and(|m| m.is_ok_and(|m| excitations(&m).is_ok()))
            })
        })
    }

    /// The excitations `[T, E]` of design `k` at the window's times.
    fn excitations(
        &self,
        k: usize,
        design: &[f64],
        profiles: &[Option<Profile>],
        run: &RunConfig,
    ) -> Result<Vec<f64>> {
        let ex = self.excitations_of(design, profiles, run, &format!("{}[{k}]", self.designs))?;
        let times = self.meta.grid.times();
        let mut out = Vec::with_capacity(times.len() * self.excitation_columns.len());
        for &t in &times {
            out.extend(
                self.excitation_columns
                    .iter()
                    .filter_map(|&q| ex.column(q, t)),
            );
        }
        Ok(out)
    }

    /// Refuses a design the network cannot read: a parameter whose z-scored value (by the
    /// training data's mean and spread, as the network's input) overflows the network's single
    /// precision, named `{label}.NAME` with its training range.
    pub fn readable(&self, design: &[f64], label: &str) -> Result<()> {
        let stats = &self.meta.norm.inputs;
        // The parameters are the last input channels (`input_block`).
        let first = stats.len() - design.len();
        let z = |j: usize| ((design[j] - stats.mean[first + j]) / stats.std[first + j]) as f32;
        let Some(j) = (0..design.len()).find(|&j| !z(j).is_finite()) else {
            return Ok(());
        };
        let name = &self.space.names()[j];
        let ranges = &self.meta.training_ranges;
        let trained = match ranges.names.iter().position(|n| n == name) {
            Some(i) => format!("; trained on [{}, {}]", ranges.min[i], ranges.max[i]),
            None => String::new(),
        };
        Err(LearnError::OutOfRange {
            field: format!("{label}.{name}"),
            value: design[j].to_string(),
            allowed: format!(
                "a value the network can read (z-scored by its training data, this one overflows single precision){trained}"
            ),
        }.into())
    }

    /// Predicts designs `sets` (the first numbered `first`) in one forward pass.
    pub fn forward(
        &self,
        first: usize,
        sets: &[Vec<f64>],
        profiles: &[Option<Profile>],
        run: &RunConfig,
    ) -> Result<Vec<SetPrediction>> {
        self.forward_with(first, sets, &ProfileSource::Shared(profiles), run)
    }

    /// [`Predictor::forward`] with the profiles of each design from `profiles`.
    pub fn forward_with(
        &self,
        first: usize,
        sets: &[Vec<f64>],
        profiles: &ProfileSource<'_>,
        run: &RunConfig,
    ) -> Result<Vec<SetPrediction>> {
        let meta = &self.meta;
        let times = meta.grid.times();
        let (tp, n_in) = (meta.grid.t_points, meta.layout.n_inputs());
        let mut x = Vec::with_capacity(sets.len() * tp * n_in);
        let mut etas = Vec::with_capacity(sets.len());
        for (k, p) in sets.iter().enumerate() {
            let eta = match profiles {
                ProfileSource::Shared(shared) => self.excitations(first + k, p, shared, run)?,
                ProfileSource::PerDesign(of) => {
                    self.excitations(first + k, p, &of(first + k)?, run)?
                }
            };
            self.readable(p, &format!("{}[{}]", self.designs, first + k))?;
            x.extend(meta.norm.inputs.normalise(&input_block(&times, &eta, p)));
            etas.push(eta);
        }
        let xt = Tensor::from_vec(x, (sets.len(), tp, n_in), &self.device)?;
        let u = self
            .model
            .predictor()?
            .predict(&xt)?
            .flatten_all()?
            .to_vec1::<f32>()?;
        Ok(u.chunks(tp * meta.layout.n_outputs())
            .zip(etas)
            .map(|(chunk, eta)| SetPrediction {
                physical: to_physical(chunk, meta),
                eta,
            })
            .collect())
    }

    /// Runs `f` on the predictions of `sets` in batches of `batch` sets (side by side on the
    /// CPU; results in set order, independent of the thread count).
    fn batched<T: Send>(
        &self,
        sets: &[Vec<f64>],
        profiles: &ProfileSource<'_>,
        run: &RunConfig,
        batch: usize,
        f: &(dyn Fn(usize, &SetPrediction) -> Result<T> + Sync),
    ) -> Result<Vec<T>> {
        use rayon::prelude::*;
        let batch = batch.max(1);
        let chunks: Vec<(usize, &[Vec<f64>])> = sets
            .chunks(batch)
            .enumerate()
            .map(|(k, c)| (k * batch, c))
            .collect();
        let go = |(start, chunk): &(usize, &[Vec<f64>])| -> Result<Vec<T>> {
            self.forward_with(*start, chunk, profiles, run)?
                .iter()
                .enumerate()
                .map(|(k, p)| f(start + k, p))
                .collect()
        };
        // One batch runs on the calling thread: handing it to the pool only adds the wake-up
        // of a worker (milliseconds on a loaded machine) to a one-design answer.
        let parts: Vec<Vec<T>> = if self.device.is_cpu() && chunks.len() > 1 {
            chunks.par_iter().map(go).collect::<Result<_>>()?
        } else {
            chunks.iter().map(go).collect::<Result<_>>()?
        };
        Ok(parts.into_iter().flatten().collect())
    }

    /// The time histories of every design (module doc) as one table, each design under the
    /// profiles `profiles` gives it; with a calibration and `coverage`, each channel's band
    /// `<channel>_lo`, `<channel>_hi` beside (the outputs and rates; excitations are exact
    /// inputs).
    pub fn histories(
        &self,
        sets: &[Vec<f64>],
        profiles: &ProfileSource<'_>,
        run: &RunConfig,
        batch: usize,
        coverage: Option<f64>,
    ) -> Result<Table> {
        let layout = &self.meta.layout;
        let (o, d, e) = (layout.n_outputs(), layout.n_dofs(), layout.n_excitations());
        let times = self.meta.grid.times();
        let tp = self.meta.grid.t_points;
        let preds = self.batched(sets, profiles, run, batch, &|k, p| {
            let bands = match coverage {
                Some(c) => self.calibrated(&sets[k], p, &[], c, true)?,
                None => None,
            };
            Ok((p.clone(), bands))
        })?;
        let columns = prediction_channels(layout);
        let names: Vec<&str> = columns.iter().map(|(n, _)| n.as_str()).collect();
        let mut cols: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
        let banded = preds.iter().all(|(_, b)| b.is_some()) && !preds.is_empty();
        let n_banded = columns
            .iter()
            .filter(|(_, s)| s.band(o, d).is_some())
            .count();
        let mut lo: Vec<Vec<f64>> = vec![Vec::new(); if banded { n_banded } else { 0 }];
        let mut hi = lo.clone();
        let mut set_col = Vec::new();
        let mut t_col = Vec::new();
        for (s, (pred, band)) in preds.iter().enumerate() {
            let ph = &pred.physical;
            for (n, &t) in times.iter().enumerate().take(tp - 1).skip(1) {
                set_col.push(s as i64);
                t_col.push(t);
                for (c, (col, (_, source))) in cols.iter_mut().zip(&columns).enumerate() {
                    let x = match *source {
                        ChannelSource::Output(k) => ph.u[n * o + k],
                        ChannelSource::Velocity(j) => ph.v[(n - 1) * d + j],
                        ChannelSource::Acceleration(j) => ph.a[(n - 1) * d + j],
                        ChannelSource::Excitation(j) => pred.eta[n * e + j],
                    };
                    col.push(x);
                    if let (Some(b), Some(k), true) = (band, source.band(o, d), banded) {
                        let h = b.bands[k][n - 1];
                        lo[c].push(x - h);
                        hi[c].push(x + h);
                    }
                }
            }
        }
        let mut table = Table::default().with_units(self.units()?);
        table.push("set", Column::I64(set_col))?;
        table.push(schema::TIME, Column::F64(t_col))?;
        for (name, values) in names.iter().zip(cols) {
            table.push(name, Column::F64(values))?;
        }
        if banded {
            // The banded columns lead (outputs and rates; the excitations are exact inputs).
            table.add_units(names[..n_banded].iter().flat_map(|n| {
                let u = layout.unit(n);
                [(format!("{n}_lo"), u), (format!("{n}_hi"), u)]
            }))?;
            for ((name, l), h) in names.iter().zip(lo).zip(hi) {
                table.push(&format!("{name}_lo"), Column::F64(l))?;
                table.push(&format!("{name}_hi"), Column::F64(h))?;
            }
        }
        Ok(table)
    }

    /// Appends the column [`OUTSIDE_COLUMN`] to the histories `table` of `sets` (the same
    /// number of rows per design): on each row, the [`outside_flag`] of its design, null inside
    /// the training ranges.
    pub fn flag_rows(&self, table: &mut Table, sets: &[Vec<f64>]) -> Result<()> {
        let per_row = (table.num_rows() / sets.len().max(1)).max(1);
        let rows = self
            .outside_training(sets)?
            .iter()
            .flat_map(|o| std::iter::repeat_n(outside_flag(o), per_row))
            .collect::<Vec<_>>();
        table.push(OUTSIDE_COLUMN, Column::null_if_empty(rows))?;
        Ok(())
    }

    /// The settings of the indices of a prediction: the `indices` stage's defaults with no
    /// start-up fraction (the model's window already excludes it), from the description's
    /// `indices_from` on.
    pub fn index_config(&self) -> Result<IndexConfig> {
        eval_config(&self.system)
    }

    /// The index columns of the model's system.
    pub fn index_inputs(&self) -> &IndexInputs {
        &self.indices
    }

    /// Refuses indices when the description defines none or they read a column the model
    /// cannot give.
    fn check_indices(&self) -> Result<()> {
        if self.indices.computable() {
            return Ok(());
        }
        Err(Error::format(
            Path::new("--indices"),
            format!(
                "the system `{}` has no index this model can compute: {}",
                self.system.name,
                self.indices.why_not()
            ),
        ))
    }

    /// The engineering indices of every design, rebuilt from its prediction as `evaluate`
    /// rebuilds them (the interior points of the window); batches of `batch` sets. Refused
    /// when the description defines none or reads a column the model cannot give.
    pub fn indices(
        &self,
        sets: &[Vec<f64>],
        profiles: &[Option<Profile>],
        run: &RunConfig,
        cfg: &IndexConfig,
        batch: usize,
    ) -> Result<Vec<SampleIndices>> {
        self.check_indices()?;
        self.batched(
            sets,
            &ProfileSource::Shared(profiles),
            run,
            batch,
            &|k, p| self.design_indices(&sets[k], k, p, cfg),
        )
    }

    /// The indices of design `k` (parameters `set`) from its prediction `p`.
    pub fn design_indices(
        &self,
        set: &[f64],
        k: usize,
        p: &SetPrediction,
        cfg: &IndexConfig,
    ) -> Result<SampleIndices> {
        self.indices.sample(
            &self.system,
            &self.meta.layout,
            set,
            k as i64,
            &p.physical,
            None,
            &p.eta,
            &self.meta.grid,
            cfg,
        )
    }

    /// Every design's indices and, with a calibration, their intervals and three-valued
    /// verdicts at `coverage` (batches of `batch` sets, as [`Predictor::indices`]), each design
    /// under the profiles `profiles` gives it.
    pub fn answers(
        &self,
        sets: &[Vec<f64>],
        profiles: &ProfileSource<'_>,
        run: &RunConfig,
        cfg: &IndexConfig,
        batch: usize,
        coverage: f64,
    ) -> Result<Vec<DesignAnswer>> {
        self.check_indices()?;
        self.batched(sets, profiles, run, batch, &|k, p| {
            let indices = self.design_indices(&sets[k], k, p, cfg)?;
            let calibrated = self.calibrated(&sets[k], p, &indices.values, coverage, false)?;
            Ok(DesignAnswer {
                indices,
                calibrated,
            })
        })
    }

    /// The indices table of `predict`: `set`, the design's parameters, the indices of the
    /// description, `window_s`, `pass` (Boolean), `failed` and [`OUTSIDE_COLUMN`] (null when
    /// none); with calibrated answers also `coverage`, `extrapolated` (Boolean),
    /// `relative_residual` (when the model has equations), `<index>_lo` and `<index>_hi` of
    /// every index, `<index>_verdict` of every index with a limit and the combined `verdict`
    /// (`pass`, `uncertain`, `fail`; null where a design has none).
    pub fn indices_table(
        &self,
        sets: &[Vec<f64>],
        answers: &[DesignAnswer],
        outside: &[Vec<OutOfRange>],
    ) -> Result<Table> {
        let mut t = Table::default().with_units(self.units()?);
        t.push("set", Column::I64((0..sets.len() as i64).collect()))?;
        self.space.push_columns(&mut t, sets)?;
        let columns = self.indices.columns();
        for (k, c) in columns.iter().enumerate() {
            t.push(
                &c.name,
                Column::F64(answers.iter().map(|a| a.indices.values[k]).collect()),
            )?;
        }
        t.push(
            pino_indices::WINDOW_COLUMN,
            Column::F64(answers.iter().map(|a| a.indices.window_s).collect()),
        )?;
        t.push(
            pino_indices::PASS_COLUMN,
            Column::Bool(
                answers
                    .iter()
                    .map(|a| a.indices.failed.is_empty())
                    .collect(),
            ),
        )?;
        t.push(
            pino_indices::FAILED_COLUMN,
            Column::null_if_empty(answers.iter().map(|a| a.indices.failed.join(","))),
        )?;
        t.push(
            OUTSIDE_COLUMN,
            Column::null_if_empty(outside.iter().map(|o| outside_flag(o))),
        )?;
        let calibrated: Option<Vec<&CalibratedAnswer>> =
            answers.iter().map(|a| a.calibrated.as_ref()).collect();
        if let Some(cal) = calibrated.filter(|c| !c.is_empty() && !c[0].indices.is_empty()) {
            push_calibrated(&mut t, columns, &cal)?;
        }
        Ok(t)
    }
}

/// The columns a calibration adds to the indices table: the coverage, the extrapolation flag,
/// the relative residual, each index's interval and verdict, and the design's verdict.
fn push_calibrated(t: &mut Table, columns: &[IndexInfo], cal: &[&CalibratedAnswer]) -> Result<()> {
    t.push(
        "coverage",
        Column::F64(cal.iter().map(|c| c.coverage).collect()),
    )?;
    t.push(
        "extrapolated",
        Column::Bool(cal.iter().map(|c| c.extrapolated).collect()),
    )?;
    if cal[0].relative_residual.is_some() {
        t.push(
            "relative_residual",
            Column::F64(
                cal.iter()
                    .map(|c| c.relative_residual.unwrap_or(f64::NAN))
                    .collect(),
            ),
        )?;
    }
    t.add_units(columns.iter().flat_map(|c| {
        [
            (format!("{}_lo", c.name), c.unit.as_str()),
            (format!("{}_hi", c.name), c.unit.as_str()),
            (
                format!("{}_verdict", c.name),
                pino_data::units::DIMENSIONLESS,
            ),
        ]
    }))?;
    for (k, c) in columns.iter().enumerate() {
        t.push(
            &format!("{}_lo", c.name),
            Column::F64(cal.iter().map(|a| a.indices[k].lo).collect()),
        )?;
        t.push(
            &format!("{}_hi", c.name),
            Column::F64(cal.iter().map(|a| a.indices[k].hi).collect()),
        )?;
    }
    for (k, c) in columns.iter().enumerate() {
        if cal[0].verdicts[k].is_some() {
            t.push(
                &format!("{}_verdict", c.name),
                Column::OptStr(
                    cal.iter()
                        .map(|a| a.verdicts[k].map(|v| v.as_str().to_owned()))
                        .collect(),
                ),
            )?;
        }
    }
    if cal[0].verdict.is_some() {
        t.push(
            "verdict",
            Column::OptStr(
                cal.iter()
                    .map(|a| a.verdict.map(|v| v.as_str().to_owned()))
                    .collect(),
            ),
        )?;
    }
    Ok(())
}

/// Column of the indices table naming the parameters outside the training ranges.
pub const OUTSIDE_COLUMN: &str = "outside_training_range";

/// The [`OUTSIDE_COLUMN`] value of one design: its parameters outside the training ranges as
/// `name=value`, comma-separated (empty inside, written as a null).
pub fn outside_flag(outside: &[OutOfRange]) -> String {
    outside
        .iter()
        .map(|r| format!("{}={}", r.name, r.value))
        .collect::<Vec<_>>()
        .join(",")
}

#[cfg(test)]
mod tests {
    use super::design::round_towards;
    use super::*;
    use learn_fixtures::synthetic::{vehicle_track_system, write_dataset, SyntheticSpec};
    use pino_learn::config::TrainParams;

    fn space() -> DesignSpace {
        DesignSpace::of(vehicle_track_system())
    }

    #[test]
    fn yaml_sets_and_overrides() {
        let sp = space();
        let o = Path::new("sets.yaml");
        let ix = |n: &str| sp.index(n, o).unwrap();
        let nominal = sp.nominal();
        let sets = sp
            .parse_sets("- {k_s: 4.0e5}\n- {v_kmh: 310}\n", o)
            .unwrap();
        assert_eq!(sets.len(), 2);
        assert_eq!(sets[0][ix("k_s")], 4.0e5);
        assert_eq!(sets[0][ix("m_c")], nominal[ix("m_c")]);
        assert_eq!(sets[1][ix("v_kmh")], 310.0);
        let sets2 = sp.parse_sets("sets:\n  - {c_p: 2.2e4}\n", o).unwrap();
        assert_eq!(sets2[0][ix("c_p")], 2.2e4);
        let mut s = sets.clone();
        sp.apply_override(&mut s, "l_c=8.5").unwrap();
        assert!(s.iter().all(|p| p[ix("l_c")] == 8.5));
        let err = sp.parse_sets("- {kk: 1}\n", o).unwrap_err().to_string();
        assert!(
            err.contains("sets.yaml")
                && err.contains("unknown parameter `kk`")
                && err.contains("allowed: m_c"),
            "{err}"
        );
        // A parameter the description fixes is not a design parameter of the model.
        let err = sp
            .parse_sets("- {wheel_radius: 0.45}\n", o)
            .unwrap_err()
            .to_string();
        assert!(err.contains("`wheel_radius` is not sampled"), "{err}");
        assert!(sp.apply_override(&mut s, "m_c").is_err());
        // Values outside the description's domains are refused naming the design and field.
        sp.apply_override(&mut s, "m_c=-1").unwrap();
        let err = sp.check(&s[1], "sets[1]").unwrap_err().to_string();
        assert!(
            err.starts_with("`sets[1].m_c` = -1 is out of range: values that keep `bodies.c.mass` finite and > 0 (this one makes it -0.5)"),
            "{err}"
        );
    }

    /// A run refused for a changed speed is blamed on the speed, with the largest value the
    /// run accepts (6 significant digits, on the accepted side); one no changed parameter
    /// explains is the design's.
    #[test]
    fn a_refused_run_is_blamed_on_the_changed_parameter_with_its_limit() {
        let sp = space();
        let k = sp.names().iter().position(|n| n == "v_kmh").unwrap();
        let limit = 341.234_567_89;
        let runs = |d: &[f64]| d[k] <= limit;
        let mut design = sp.nominal();
        design[k] = 1e6;
        let err = sp.blame_run(&design, "design", "too far", runs);
        match &err {
            crate::Error::Learn(LearnError::OutOfRange {
                field,
                value,
                allowed,
            }) => {
                assert_eq!(field, "design.v_kmh");
                assert_eq!(value, "1000000");
                assert_eq!(
                    allowed,
                    "at most 341.234 with the rest of this design: too far"
                );
            }
            other => panic!("{other}"),
        }
        // A slower speed refused (a lower limit): at least, rounded up.
        design[k] = 1.0;
        let err = sp.blame_run(&design, "design", "too slow", |d: &[f64]| {
            d[k] >= 299.000_000_1
        });
        assert!(err.to_string().contains("at least 299.001 "), "{err}");
        // Nothing changed: the run is the design's.
        let err = sp.blame_run(&sp.nominal(), "sets[2]", "too far", runs);
        assert_eq!(err.to_string(), "sets[2]: too far");
        assert_eq!(round_towards(-0.001_234_567_8, 3, false), -0.001_24);
        assert_eq!(round_towards(123_456_789.0, 2, true), 130_000_000.0);
        assert_eq!(round_towards(0.0, 3, true), 0.0);
    }

    /// A parameter file written for one system, given to a model of another, is refused
    /// naming the file, the parameter and the model's own parameters (both ways).
    #[test]
    fn a_design_of_another_system_is_refused_by_name() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../systems/quarter-car.yaml"
        );
        let text = std::fs::read_to_string(path).unwrap();
        let quarter = mbd_system::load_str(&text, "systems/quarter-car.yaml", &Default::default())
            .unwrap_or_else(|d| panic!("{d}"));
        let quarter = DesignSpace::of(Arc::new(quarter));
        let o = Path::new("vehicle-track-design.yaml");
        // `k_s` is a parameter of both; `k_f` (the fastener) only of the vehicle-track model.
        let err = quarter
            .parse_sets("- {k_s: 4.0e5, k_f: 4.0e7}\n", o)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("vehicle-track-design.yaml")
                && err.contains("unknown parameter `k_f`")
                && err.contains("allowed: m_s"),
            "{err}"
        );
        let err = space()
            .parse_sets("- {k_t: 2.0e5}\n", o)
            .unwrap_err()
            .to_string();
        assert!(err.contains("unknown parameter `k_t`"), "{err}");
    }

    #[test]
    fn sweeps_by_grid_and_by_seeded_random_sample() {
        let sp = space();
        let o = Path::new("sweep.yaml");
        let ix = |n: &str| sp.index(n, o).unwrap();
        let nominal = sp.nominal();
        let g = parse_sweep(
            &sp,
            "base: {v_kmh: 340}\ngrid:\n  k_s: {from: 4.0e+5, to: 5.0e+5, steps: 3}\n  c_s: [1.0e+4, 3.0e+4]\n",
            o,
        )
        .unwrap();
        // Every combination, the last axis fastest; the base and nominal values elsewhere.
        assert_eq!(g.len(), 6);
        let ks: Vec<f64> = g.iter().map(|p| p[ix("k_s")]).collect();
        let cs: Vec<f64> = g.iter().map(|p| p[ix("c_s")]).collect();
        assert_eq!(ks, [4.0e5, 4.0e5, 4.5e5, 4.5e5, 5.0e5, 5.0e5]);
        assert_eq!(cs, [1.0e4, 3.0e4, 1.0e4, 3.0e4, 1.0e4, 3.0e4]);
        assert!(g
            .iter()
            .all(|p| p[ix("v_kmh")] == 340.0 && p[ix("m_c")] == nominal[ix("m_c")]));
        let text =
            "random: {seed: 7, count: 500, ranges: {k_f: [3.5e+7, 4.5e+7], v_kmh: [300, 350]}}\n";
        let r = parse_sweep(&sp, text, o).unwrap();
        assert_eq!(r.len(), 500);
        assert!(r
            .iter()
            .all(|p| (3.5e7..4.5e7).contains(&p[ix("k_f")])
                && (300.0..350.0).contains(&p[ix("v_kmh")])));
        assert!(r.iter().all(|p| p[ix("k_s")] == nominal[ix("k_s")]));
        // Deterministic, and design i depends only on (seed, i).
        assert_eq!(parse_sweep(&sp, text, o).unwrap(), r);
        let fewer = parse_sweep(&sp, &text.replace("500", "20"), o).unwrap();
        assert_eq!(fewer[..], r[..20]);
        let mean = r.iter().map(|p| p[ix("k_f")]).sum::<f64>() / 500.0;
        assert!((mean - 4.0e7).abs() < 0.1e7, "{mean}");
        // Bad input: named file, field and allowed values.
        for (bad, want) in [
            ("grid: {kk: [1]}\n", "unknown parameter `kk`"),
            ("grid: {k_s: {from: 1, to: 2, steps: 0}}\n", "steps = 0"),
            (
                "random: {seed: 1, count: 0, ranges: {}}\n",
                "random.count = 0",
            ),
            (
                "random: {seed: 1, count: 5, ranges: {k_s: [5, 1]}}\n",
                "lo <= hi",
            ),
            ("base: {k_s: 1}\n", "exactly one of `grid:` or `random:`"),
            ("base: {k_s: .nan}\ngrid: {c_s: [1]}\n", "must be finite"),
        ] {
            let e = parse_sweep(&sp, bad, o).unwrap_err().to_string();
            assert!(e.contains("sweep.yaml") && e.contains(want), "{bad}: {e}");
        }
    }

    #[test]
    fn training_ranges_flag_designs_outside() {
        let system = vehicle_track_system();
        let r = pino_learn::checkpoint::TrainingRanges::of(&system);
        let sp = space();
        let nominal = sp.nominal();
        assert!(r
            .outside(&system.sampled_values(nominal.as_slice()).unwrap())
            .is_empty());
        let mut p = nominal.clone();
        let k_f = sp.index("k_f", Path::new("-")).unwrap();
        p[k_f] = 25.0 * r.max[k_f];
        p[0] = r.max[0]; // a bound itself is inside
        let out = r.outside(&system.sampled_values(p.as_slice()).unwrap());
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].name, "k_f");
        assert!(out[0].to_string().contains("(trained on"), "{}", out[0]);
        assert_eq!(outside_flag(&out), format!("k_f={}", p[k_f]));
    }

    /// A model trained on a synthetic dataset predicts a test sample from its parameters and
    /// the profile regenerated from the dataset's seed: the excitations it builds are the
    /// solver's stored ones bit for bit, and the prediction is `evaluate`'s for that sample.
    #[test]
    fn predict_rebuilds_the_datasets_inputs_and_evaluates_prediction() {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 2,
            n_validation: 1,
            n_test: 1,
            duration: 0.3,
            ..Default::default()
        };
        let files = write_dataset(&spec, dir.path()).unwrap();
        let layout = learn_fixtures::synthetic::vehicle_track_layout();
        let mut p = TrainParams::small(1);
        p.epochs = 1;
        let (m, t, w) = p.configs(&layout).unwrap();
        let ds = files.load(&w, false).unwrap();
        let out = dir.path().join("model");
        std::fs::create_dir_all(&out).unwrap();
        let dev = Device::Cpu;
        pino_learn::train::train_to_dir(
            &ds,
            (m, t, w),
            Transform::Fused,
            &out,
            &out,
            &dev,
            &mut |_| {},
        )
        .unwrap();
        let predictor = Predictor::load(&out, &dev).unwrap();
        let meta = &predictor.meta;
        let (test_ds, items) = files
            .load_split(&w, pino_learn::data::Split::Test, &meta.norm)
            .unwrap();
        let id = items.id(0);
        let design = items.params(0).to_vec();
        assert!(predictor
            .outside_training(std::slice::from_ref(&design))
            .unwrap()[0]
            .is_empty());
        // Without a profile the generated track is refused by name.
        let err = predictor.profiles(None).unwrap_err().to_string();
        assert!(err.contains("--seed") && err.contains("track"), "{err}");
        let profiles = predictor
            .profiles(Some(&ProfileChoice::Generated {
                seed: spec.seed,
                id: id as u64,
            }))
            .unwrap();
        let run = predictor.run_config(None).unwrap();
        assert_eq!(run.x0, spec.x0);
        let pred = predictor
            .forward(0, std::slice::from_ref(&design), &profiles, &run)
            .unwrap();
        // The same formula at the same positions; the window's times are rebuilt as
        // `t0 + k dt` where the solver counted steps, so positions agree to an ulp of `t`.
        let stored = items.series(0).unwrap().eta;
        let scale = stored.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0);
        for (k, (a, b)) in pred[0].eta.iter().zip(&stored).enumerate() {
            assert!(
                (a - b).abs() <= 1e-12 * scale,
                "excitation {k}: {a} vs stored {b}"
            );
        }
        for (a, b) in test_ds.t.iter().zip(meta.grid.times()) {
            assert!((a - b).abs() <= 1e-12, "{a} {b}");
        }
        let model = pino_learn::checkpoint::load_model(&out, Transform::Fused, &dev)
            .unwrap()
            .0;
        let (evaluated, _) =
            pino_learn::infer::predict_samples(&model, &items, &[0], items.t_points(), 1, &dev)
                .unwrap();
        assert_eq!(pred[0].physical.u, to_physical(&evaluated[0], meta).u);
        // The time-history table: interior rows, outputs, rates and excitations by name.
        let shared = ProfileSource::Shared(&profiles);
        let table = predictor
            .histories(std::slice::from_ref(&design), &shared, &run, 4, None)
            .unwrap();
        assert_eq!(table.num_rows(), meta.grid.t_points - 2);
        for name in layout.outputs.iter().chain(&layout.excitations) {
            assert!(table.f64(name).is_ok(), "{name}");
        }
        assert!(table.f64("beta_c_a").is_ok() && table.f64("z_w4_v").is_ok());
        // Indices of the prediction with the design's columns.
        let cfg = predictor.index_config().unwrap();
        let ix = predictor
            .answers(std::slice::from_ref(&design), &shared, &run, &cfg, 4, 0.9)
            .unwrap();
        assert!(ix[0].calibrated.is_none(), "no calibration loaded");
        let it = predictor
            .indices_table(std::slice::from_ref(&design), &ix, &[vec![]])
            .unwrap();
        assert!(it.f64("peak_wheel_rail_force_kn_lo").is_err());
        assert_eq!(it.f64("m_c").unwrap()[0], design[0]);
        // The predicted peak force against the solver's for the same design and profiles.
        let predicted = it.f64("peak_wheel_rail_force_kn").unwrap()[0];
        let exact = solve::exact(&predictor, &run, &design, &profiles, None).unwrap();
        let solved = solve::exact_indices(&predictor, &design, exact, &cfg).unwrap();
        let j = (predictor.index_inputs().columns().iter())
            .position(|c| c.name == "peak_wheel_rail_force_kn")
            .unwrap();
        let solver = solved.values[j];
        // Measured: predicted 68.0 kN, solver 75.2 kN (9.6 % apart) for this one-epoch model
        // (`cargo test -p pino-predict predict_rebuilds`, 2026-12-06); the bound, 20 % of the
        // solver's, leaves twice that margin and still fails a force in the wrong unit or of
        // the wrong sign.
        assert!(
            (predicted - solver).abs() <= 0.2 * solver.abs(),
            "peak wheel-rail force: predicted {predicted} kN, solver {solver} kN"
        );
        // A profile too short for the run is refused (4 points: the vehicle track reads its
        // profile cubic, which needs them).
        let short = vec![Some(
            Profile::new(vec![0.0, 1.0, 2.0, 3.0], vec![0.0; 4]).unwrap(),
        )];
        let err = predictor
            .forward(0, std::slice::from_ref(&design), &short, &run)
            .unwrap_err();
        assert!(
            err.to_string().starts_with("sets[0]: profile `track`"),
            "{err}"
        );
    }
}
