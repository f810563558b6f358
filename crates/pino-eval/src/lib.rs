//! Evaluation on the test split (the validation split, flagged, when a dataset has none): the
//! paper's Table 4 with a truth row, per-channel errors in physical units, prediction speed,
//! and PNG plots. Only the scored split is read.
//!
//! Table 4 (`docs/learning.md`), over the channel groups of the model's layout: per algorithm,
//! the mean over scored samples of the relative L2 error (%) of the z-scored displacement
//! solutions, of the rigid DOFs' velocities and accelerations (central differences of the
//! prediction at interior points), plus the predicted forces and the peak force error (% of
//! the sample's static contact force, the wheel load W of the vehicle-track model). The truth
//! row feeds the exact solutions through the same metric: 0 on solutions, the
//! central-difference floor on derivatives.
//! Per channel: `||pred - exact|| / ||exact||` in physical units (mean over samples, %), the
//! RMS error in an engineer's unit (mm, mrad, mm/s, mrad/s, m/s^2, rad/s^2, kN) and the worst
//! sample; the predicted forces and, for each Hertz contact whose deflection the model
//! predicts, `<force>_hertz`, the force implied by the predicted deflection and the exact
//! excitation. Speed: simulated seconds (scored samples x window length) per wall second of
//! forward passes.
//!
//! The `evaluate` stage's library, on top of the others: the model's outputs and indices
//! (`pino-outputs`), the coverage of its calibration (`pino-calibration`) and the surrogate's
//! report (`pino-surrogate`). Private modules: `channel_errors` (per-channel errors and display
//! units), `plots` (sample and training-curve PNGs), `outputs` (Table 4 and the other files).

#![warn(missing_docs)]

mod channel_errors;
mod outputs;
mod plots;

pub use channel_errors::ChannelError;
use channel_errors::{channel_errors, peak_force_error};
use outputs::{write_outputs, ASKED_VALIDATION_NOTE, FALLBACK_VALIDATION_WARNING};
pub use plots::plot_channels;
use plots::plot_sample;

use candle_core::{DType, Device, Tensor};
use pino_calibration::coverage::{split_coverage, ConditionalRow, CoverageRow};
use pino_calibration::report::write_coverage;
use pino_calibration::scored::Run;
use pino_calibration::{Calibration, ModelIdentity};
use pino_learn::checkpoint::{load_model, ModelMeta};
use pino_learn::data::{make_batch, splits_present, Batch, Dataset, DatasetInfo, Prepared, Split};
use pino_learn::infer::predict_samples;
use pino_learn::layout::Layout;
use pino_learn::loss::{rel_l2_per_sample, LossContext};
use pino_learn::model::Fno;
use pino_learn::spectral::Transform;
use pino_learn::Error as LearnError;
use pino_outputs::indices_eval::{
    model_indices, truth_indices, write_indices, IndexInputs, ModelIndices, StoredColumns,
};
use pino_outputs::physical::{to_physical, Physical};
use pino_outputs::split::{EvalData, ScoredData};
pub use pino_outputs::{Error, Result};
use std::path::{Path, PathBuf};

/// Name of Table 4's truth row.
pub const TRUTH_NAME: &str = "truth (exact solutions, central differences)";

fn d_device() -> pino_learn::config::DeviceKind {
    pino_learn::config::DeviceKind::Cpu
}

/// The `evaluate` stage's parameters as they appear in pipeline.yaml (all required but the
/// device: their home is the pipeline file).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalParams {
    /// Scored samples plotted per model.
    pub plot_samples: usize,
    /// The rigid-DOF columns plotted (one row each: displacement, velocity, acceleration).
    pub plot_channels: Vec<String>,
    /// Samples per forward pass.
    pub batch_size: usize,
    /// Whether Table 4 carries the paper's figures beside ours (the vehicle-track model only).
    pub compare_with_paper: bool,
    /// "cpu" or "cuda".
    #[serde(default = "d_device")]
    pub device: pino_learn::config::DeviceKind,
    /// Overrides of the description's values, as the data stages take them (read in check
    /// mode, where the description the command names stands in for the dataset's record).
    #[serde(default)]
    pub system_values: std::collections::BTreeMap<String, mbd_system::Override>,
    /// The split scored: `test` (absent: the test split, the validation split when the
    /// dataset has none) or `validation` (a selection study's figures, keeping the test split
    /// for the one final report).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split: Option<ScoredSplit>,
}

/// A split `evaluate` may be asked to score.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScoredSplit {
    /// The held-out test split (Table 4's).
    Test,
    /// The validation split (settings are chosen on it).
    Validation,
}

impl ScoredSplit {
    /// The dataset's split.
    pub fn split(self) -> Split {
        match self {
            Self::Test => Split::Test,
            Self::Validation => Split::Validation,
        }
    }
}

/// Evaluation settings.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    /// Scored samples plotted per model.
    pub plot_samples: usize,
    /// Rigid-DOF columns plotted.
    pub plot_channels: Vec<String>,
    /// Samples per forward pass.
    pub batch_size: usize,
    /// Transform implementation.
    pub transform: Transform,
    /// Whether Table 4 carries the paper's figures.
    pub compare_with_paper: bool,
    /// The `calibrate` stage's output (or one `calibration.json`), when the models are
    /// calibrated: their coverage on the scored split is reported.
    pub calibration: Option<PathBuf>,
    /// The split asked for (absent: [`scored_split`]'s choice).
    pub split: Option<ScoredSplit>,
    /// The `surrogate` stage's output, when there is one: its per-quantity errors and coverage
    /// on the scored split are reported ([`pino_surrogate::report`]).
    pub surrogate: Option<PathBuf>,
}

/// One model's results.
#[derive(Debug, Clone)]
pub struct ModelResult {
    /// Its directory.
    pub dir: PathBuf,
    /// Its metadata.
    pub meta: ModelMeta,
    /// Table 4 values (%): solutions, first, second derivatives.
    pub table4: [f64; 3],
    /// Relative L2 (%) of the predicted forces (z-scored, as Table 4; NaN without forces).
    pub forces_pct: f64,
    /// Mean peak force error (% of the static contact force) over samples and forces.
    pub peak_force_error_pct_w: f64,
    /// Per-channel errors.
    pub channels: Vec<ChannelError>,
    /// Simulated seconds per wall second of prediction.
    pub speed: f64,
    /// Wall seconds of the forward passes over the scored split.
    pub wall_s: f64,
    /// Samples scored.
    pub samples: usize,
}

/// Per-sample Table 4 metrics (fractions) of a z-scored prediction `u_n [B, T, O]`:
/// relative L2 of the displacement solutions (the paper's metric), of the first and second
/// derivatives (central differences of the rigid DOFs against the exact `_v`/`_a`, z-scored,
/// interior points), and of the forces (z-scored; NaN without force outputs).
pub fn table4_per_sample(ctx: &LossContext, u_n: &Tensor, batch: &Batch) -> Result<[Vec<f64>; 4]> {
    let [sol, first, second] = ctx.metrics_per_sample(u_n, batch)?;
    let r = ctx.layout().forces();
    let f = if r.is_empty() {
        vec![f64::NAN; sol.len()]
    } else {
        let forces = |u: &Tensor| -> Result<Tensor> {
            Ok(u.narrow(2, r.start, r.len())?.to_dtype(DType::F64)?)
        };
        rel_l2_per_sample(&forces(u_n)?, &forces(&batch.u)?)?.to_vec1::<f64>()?
    };
    Ok([sol, first, second, f])
}

/// Scores of one split: per-sample metrics of the model, of the truth (the exact solutions
/// fed through the same metric: 0 on solutions and forces, the central-difference floor on
/// derivatives), the z-scored predictions, and the wall time of the forward passes.
struct Scores {
    model: [Vec<f64>; 4],
    truth: [Vec<f64>; 4],
    preds: Vec<Vec<f32>>,
    wall: f64,
}

fn score_split(
    model: &Fno,
    ctx: &LossContext,
    items: &Prepared,
    idx: &[usize],
    batch_size: usize,
    device: &Device,
) -> Result<Scores> {
    use rayon::prelude::*;
    let t = items.t_points();
    let batch_size = batch_size.max(1);
    let (preds, wall) = predict_samples(model, items, idx, t, batch_size, device)?;
    // Scoring is per sample: batches are scored side by side and concatenated in order.
    let score = |(chunk, pred): (&[usize], &[Vec<f32>])| -> Result<[[Vec<f64>; 4]; 2]> {
        let batch = make_batch(items, chunk, t, device)?;
        let flat: Vec<f32> = pred.concat();
        let u = Tensor::from_vec(flat, (chunk.len(), t, ctx.layout().n_outputs()), device)?;
        Ok([
            table4_per_sample(ctx, &u, &batch)?,
            table4_per_sample(ctx, &batch.u, &batch)?,
        ])
    };
    let pairs: Vec<(&[usize], &[Vec<f32>])> = idx
        .chunks(batch_size)
        .zip(preds.chunks(batch_size))
        .collect();
    let scored: Vec<[[Vec<f64>; 4]; 2]> = if device.is_cpu() {
        pairs.into_par_iter().map(score).collect::<Result<_>>()?
    } else {
        pairs.into_iter().map(score).collect::<Result<_>>()?
    };
    let mut out = Scores {
        model: Default::default(),
        truth: Default::default(),
        preds,
        wall,
    };
    for [m, o] in &scored {
        for k in 0..4 {
            out.model[k].extend_from_slice(&m[k]);
            out.truth[k].extend_from_slice(&o[k]);
        }
    }
    Ok(out)
}

/// The split an evaluation scored, and why: every output that reports the split (Table 4's
/// note, the stage's summary) reads it from here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScoredOn {
    /// The test split (asked for, or the default).
    Test,
    /// The validation split, asked for (`split: validation`): a selection study's figures.
    AskedValidation,
    /// The validation split because the dataset has no test split: optimistic figures.
    FallbackValidation,
}

impl ScoredOn {
    /// The dataset's split.
    pub fn split(self) -> Split {
        match self {
            Self::Test => Split::Test,
            Self::AskedValidation | Self::FallbackValidation => Split::Validation,
        }
    }

    /// Table 4's note (Markdown), absent on the test split.
    pub fn note(self) -> Option<&'static str> {
        match self {
            Self::Test => None,
            Self::AskedValidation => Some(ASKED_VALIDATION_NOTE),
            Self::FallbackValidation => Some(FALLBACK_VALIDATION_WARNING),
        }
    }

    /// A short flag for one-line summaries (empty on the test split).
    pub fn flag(self) -> &'static str {
        match self {
            Self::Test => "",
            Self::AskedValidation => " (as asked: settings are chosen on it)",
            Self::FallbackValidation => " (NO TEST SPLIT: validation, optimistic)",
        }
    }
}

/// Which split `evaluate` scores: the one asked for, which must hold samples; else `test` when
/// `params.parquet` has one, else `validation` (flagged in every output as a fallback: the
/// study chose settings on it).
pub fn scored_split(params_file: &Path, asked: Option<ScoredSplit>) -> Result<ScoredOn> {
    let present = splits_present(params_file)?;
    if let Some(asked) = asked {
        let split = asked.split();
        if !present.contains(&split) {
            return Err(LearnError::Dataset {
                path: params_file.to_owned(),
                message: format!(
                    "no sample of split `{}`, which `split` asks to score",
                    split.as_str()
                ),
            }
            .into());
        }
        return Ok(match asked {
            ScoredSplit::Test => ScoredOn::Test,
            ScoredSplit::Validation => ScoredOn::AskedValidation,
        });
    }
    if present.contains(&Split::Test) {
        Ok(ScoredOn::Test)
    } else if present.contains(&Split::Validation) {
        Ok(ScoredOn::FallbackValidation)
    } else {
        Err(LearnError::Dataset {
            path: params_file.to_owned(),
            message: "no sample of split `test` or `validation` to score".into(),
        }
        .into())
    }
}

/// Table 4 of the truth: the exact solutions fed through the metric (0 % on solutions and
/// forces, the central-difference floor on derivatives), on the same samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthRow {
    /// Solutions, first, second derivatives, forces (%).
    pub table4: [f64; 4],
    /// Samples scored.
    pub samples: usize,
}

/// Everything `evaluate` wrote into its tables.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// The split scored, and why.
    pub scored_on: ScoredOn,
    /// Per model, by algorithm.
    pub models: Vec<ModelResult>,
    /// The truth row (of the first model's window and statistics).
    pub truth: Option<TruthRow>,
}

impl Evaluation {
    /// The evaluation in one line (the `evaluate` stage's summary): Table 4 per algorithm with
    /// its peak force error, and the slowest model's prediction speed.
    pub fn summary(&self) -> String {
        let rows: Vec<String> = self
            .models
            .iter()
            .map(|r| {
                format!(
                    "{}: {:.2}/{:.2}/{:.2}% (peak force {:.2}% of the static force)",
                    r.meta.train.algorithm.id(),
                    r.table4[0],
                    r.table4[1],
                    r.table4[2],
                    r.peak_force_error_pct_w
                )
            })
            .collect();
        let speed = self
            .models
            .iter()
            .map(|r| r.speed)
            .fold(f64::INFINITY, f64::min);
        format!(
            "Table 4 on the {} split{} (solutions/first/second) {}; prediction >= {speed:.0} simulated s per wall s",
            self.scored_on.split().as_str(),
            self.scored_on.flag(),
            rows.join(", ")
        )
    }
}

/// Evaluates every model directory on the test split (the validation split when the dataset
/// has none, flagged) and writes, into `out`: `table4.{parquet,csv,md}`,
/// `channel_errors.{parquet,csv}`, `pred_alg{A}_sample{ID}.png`, `training_curves.png`,
/// `plots.md` and `speed.csv` (the only machine-dependent file), and the engineering indices of
/// the description against the solver. Only the scored split is read from the simulation
/// files; every model must have been trained on the dataset's description.
pub fn evaluate(
    data: &EvalData<'_>,
    model_dirs: &[PathBuf],
    out: &Path,
    opts: &EvalOptions,
    device: &Device,
    progress: &mut dyn FnMut(usize, &str),
) -> Result<Evaluation> {
    let scored_on = scored_split(data.params_file, opts.split)?;
    let split = scored_on.split();
    let system = &data.info.system;
    let layout = Layout::of(system);
    let mut run = Gathering {
        data,
        split,
        opts,
        device,
        out,
        plot_channels: plot_channels(&opts.plot_channels, &layout, system)?,
        // Engineering indices of every model (and the truth row) against the solver.
        index_inputs: IndexInputs::of(system, &layout)?,
        cache: Vec::new(),
        truth: None,
        index_sets: Vec::new(),
        coverage: CoverageReport::default(),
    };
    let mut results = Vec::new();
    for (m, dir) in model_dirs.iter().enumerate() {
        let r = run.model(dir)?;
        let [sol, first, second] = r.table4;
        progress(
            m + 1,
            &format!(
                "algorithm {}: {sol:.2}% / {first:.2}% / {second:.2}%, forces {:.2}%, peak force {:.2}% of the static contact force",
                r.meta.train.algorithm.id(),
                r.forces_pct,
                r.peak_force_error_pct_w
            ),
        );
        results.push(r);
    }
    results.sort_by_key(|r| r.meta.train.algorithm.id());
    run.index_sets.sort_by_key(|m| m.algorithm);
    write_indices(out, split, &run.index_inputs, &layout, &run.index_sets)?;
    if opts.calibration.is_some() {
        run.coverage.write(out)?;
    }
    if let Some(dir) = &opts.surrogate {
        let rows =
            pino_surrogate::report::surrogate_rows(data, dir, split, opts.batch_size, device)?;
        pino_surrogate::report::write_surrogate(out, split, &rows)?;
    }
    let evaluation = Evaluation {
        scored_on,
        models: results,
        truth: run.truth,
    };
    write_outputs(out, &evaluation, &layout, opts)?;
    Ok(evaluation)
}

/// What an evaluation gathers model by model: the scored split (one load per window and
/// statistics, shared by the models trained on the same data), the truth row, every model's
/// indices and its calibration's coverage.
struct Gathering<'a> {
    data: &'a EvalData<'a>,
    split: Split,
    opts: &'a EvalOptions,
    device: &'a Device,
    out: &'a Path,
    plot_channels: Vec<usize>,
    index_inputs: IndexInputs,
    cache: Vec<ScoredData>,
    truth: Option<TruthRow>,
    index_sets: Vec<ModelIndices>,
    coverage: CoverageReport,
}

impl Gathering<'_> {
    /// Where the scored split as the model of `meta` reads it sits in the cache (loaded if new).
    fn scored(&mut self, meta: &ModelMeta) -> Result<usize> {
        if let Some(at) = self.cache.iter().position(|c| c.serves(meta)) {
            return Ok(at);
        }
        let data = ScoredData::load(self.data, self.split, meta, &self.index_inputs)?;
        self.cache.push(data);
        Ok(self.cache.len() - 1)
    }

    /// Scores the model in `dir`: its Table 4 row and channel errors, its indices, sample plots
    /// and coverage gathered on the way.
    fn model(&mut self, dir: &Path) -> Result<ModelResult> {
        let (opts, device, system) = (self.opts, self.device, &self.data.info.system);
        let (model, meta) = load_model(dir, opts.transform, device)?;
        check_same_system(dir, &meta, self.data.info)?;
        // The model's own channels (a model that outputs rates reads its indices from them).
        let model_inputs = IndexInputs::of(system, &meta.layout)?;
        let at = self.scored(&meta)?;
        let ScoredData {
            ds, items, stored, ..
        } = &self.cache[at];
        check_same_grid(dir, &meta, ds, self.data.simulation_files)?;
        let idx: Vec<usize> = (0..items.len()).collect();
        if idx.is_empty() {
            return Err(LearnError::Dataset {
                path: self.data.params_file.to_owned(),
                message: format!("no simulated sample of split `{}`", self.split.as_str()),
            }
            .into());
        }
        let ctx = LossContext::of_model(&meta, system.clone());
        let sc = score_split(&model, &ctx, items, &idx, opts.batch_size, device)?;
        let mean = |v: &[f64]| 100.0 * v.iter().sum::<f64>() / v.len() as f64;
        self.truth.get_or_insert(TruthRow {
            table4: std::array::from_fn(|k| mean(&sc.truth[k])),
            samples: idx.len(),
        });
        let phys: Vec<Physical> = sc.preds.iter().map(|p| to_physical(p, &meta)).collect();
        let channels = channel_errors(items, &idx, &phys, &meta, system)?;
        if self.index_inputs.computable() {
            if self.index_sets.is_empty() {
                let truth = truth_indices(system, &self.index_inputs, items, &idx, stored, &meta)?;
                self.index_sets.push(truth);
            }
            let indices = model_indices(system, &model_inputs, items, &idx, &phys, stored, &meta)?;
            self.index_sets.push(indices);
        }
        let alg = meta.train.algorithm.id();
        for (k, &i) in idx.iter().take(opts.plot_samples).enumerate() {
            let path = self
                .out
                .join(format!("pred_alg{alg}_sample{}.png", items.id(i)));
            plot_sample(&path, ds, items, i, &phys[k], &meta, &self.plot_channels)?;
        }
        if let Some(path) = &opts.calibration {
            let batch = opts.batch_size;
            let run = Run {
                model: &model,
                meta: &meta,
                batch,
                device,
            };
            self.coverage
                .add(path, dir, system, run, &model_inputs, items, stored)?;
        }
        let simulated = idx.len() as f64 * ds.t_points() as f64 * ds.dt;
        Ok(ModelResult {
            dir: dir.to_owned(),
            table4: [mean(&sc.model[0]), mean(&sc.model[1]), mean(&sc.model[2])],
            forces_pct: mean(&sc.model[3]),
            peak_force_error_pct_w: peak_force_error(&channels, &meta.layout),
            meta,
            channels,
            speed: simulated / sc.wall.max(1e-12),
            wall_s: sc.wall,
            samples: idx.len(),
        })
    }
}

/// Refuses a model trained on another description than the dataset's.
fn check_same_system(dir: &Path, meta: &ModelMeta, info: &DatasetInfo) -> Result<()> {
    if meta.system.hash() == info.source.hash() && meta.layout.follows(&info.system) {
        return Ok(());
    }
    Err(LearnError::Format {
        path: dir.join(pino_data::artifacts::MODEL_META),
        message: format!(
            "the model was trained on another system description ({}) than the dataset's ({}): retrain it on this dataset",
            meta.system.file, info.source.file
        ),
    }.into())
}

/// Refuses a model trained on another time grid than the dataset window's.
fn check_same_grid(
    dir: &Path,
    meta: &ModelMeta,
    ds: &Dataset,
    simulation_files: &[PathBuf],
) -> Result<()> {
    if ds.t_points() == meta.grid.t_points && (ds.dt - meta.grid.dt).abs() <= 1e-9 * meta.grid.dt {
        return Ok(());
    }
    Err(LearnError::Dataset {
        path: simulation_files.first().cloned().unwrap_or_default(),
        message: format!(
            "model {} was trained on {} points at dt {} s, the dataset window has {} points at dt {} s",
            dir.display(),
            meta.grid.t_points,
            meta.grid.dt,
            ds.t_points(),
            ds.dt
        ),
    }.into())
}

/// The calibrated models' coverage on the scored split, gathered model by model.
#[derive(Default)]
struct CoverageReport {
    calibrations: Vec<Calibration>,
    rows: Vec<CoverageRow>,
    conditional: Vec<ConditionalRow>,
}

impl CoverageReport {
    /// Adds the coverage of the model in `dir` (its calibration found under `path`).
    #[allow(clippy::too_many_arguments)]
    fn add(
        &mut self,
        path: &Path,
        dir: &Path,
        system: &mbd_system::System,
        run: Run<'_>,
        inputs: &IndexInputs,
        items: &Prepared,
        stored: &StoredColumns,
    ) -> Result<()> {
        let calibration = Calibration::load(path, &ModelIdentity::of(dir)?)?;
        let (rows, conditional) = split_coverage(system, run, inputs, items, stored, &calibration)?;
        self.rows.extend(rows);
        self.conditional.extend(conditional);
        self.calibrations.push(calibration);
        Ok(())
    }

    fn write(mut self, out: &Path) -> Result<()> {
        self.calibrations.sort_by_key(|c| c.model.algorithm);
        self.rows.sort_by_key(|r| r.algorithm);
        self.conditional.sort_by_key(|r| r.algorithm);
        write_coverage(out, &self.calibrations, &self.rows, &self.conditional)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use learn_fixtures::synthetic::{write_dataset, SyntheticSpec};
    use pino_data::read_parquet;
    use pino_learn::config::TrainParams;
    use pino_learn::train::model_meta;
    use pino_outputs::physical::exact_physical;

    struct Fixture {
        _dir: tempfile::TempDir,
        files: learn_fixtures::synthetic::SyntheticFiles,
        ds: Dataset,
        items: Prepared,
        meta: ModelMeta,
        ctx: LossContext,
        test: Vec<usize>,
    }

    fn fixture() -> Fixture {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 3,
            n_validation: 1,
            n_test: 2,
            duration: 0.2,
            ..Default::default()
        };
        let files = write_dataset(&spec, dir.path()).unwrap();
        let layout = learn_fixtures::synthetic::vehicle_track_layout();
        let (m, t, w) = TrainParams::small(4).configs(&layout).unwrap();
        let ds = files.load(&w, false).unwrap();
        let meta = model_meta(&ds, m, t, w).unwrap();
        // The scored split alone, as `evaluate` reads it.
        let (_, items) = files.load_split(&w, Split::Test, &meta.norm).unwrap();
        let ctx = LossContext::of_model(&meta, ds.system().clone());
        let test: Vec<usize> = (0..items.len()).collect();
        assert_eq!(test.len(), 2);
        Fixture {
            _dir: dir,
            files,
            ds,
            items,
            meta,
            ctx,
            test,
        }
    }

    /// The split scored: test when there is one; the validation split when asked (or when
    /// there is none); a split asked for that holds no sample is refused.
    #[test]
    fn the_scored_split_is_test_unless_validation_is_asked_for() {
        let fx = fixture();
        let params = &fx.files.params;
        assert_eq!(scored_split(params, None).unwrap(), ScoredOn::Test);
        assert_eq!(
            scored_split(params, Some(ScoredSplit::Test)).unwrap(),
            ScoredOn::Test
        );
        let asked = scored_split(params, Some(ScoredSplit::Validation)).unwrap();
        assert_eq!(asked, ScoredOn::AskedValidation);
        assert_eq!(asked.split(), Split::Validation);
        assert_eq!(asked.note(), Some(ASKED_VALIDATION_NOTE));
        let p: EvalParams = serde_json::from_value(serde_json::json!({
            "plot_samples": 0, "plot_channels": [], "batch_size": 1,
            "compare_with_paper": false, "split": "validation"
        }))
        .unwrap();
        assert_eq!(p.split, Some(ScoredSplit::Validation));

        // No test split: validation by default (the flagged fallback); asking for test fails.
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 2,
            n_validation: 1,
            n_test: 0,
            duration: 0.1,
            ..Default::default()
        };
        let files = write_dataset(&spec, dir.path()).unwrap();
        let fallback = scored_split(&files.params, None).unwrap();
        assert_eq!(fallback, ScoredOn::FallbackValidation);
        assert_eq!(fallback.split(), Split::Validation);
        assert_eq!(fallback.note(), Some(FALLBACK_VALIDATION_WARNING));
        let e = scored_split(&files.params, Some(ScoredSplit::Test))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no sample of split `test`"), "{e}");
    }

    /// The stage's one-line summary: each model's Table 4 row and peak force error in the
    /// algorithms' order, the split with its flag, and the slowest model's speed.
    #[test]
    fn the_summary_reads_every_model_and_the_slowest_speed() {
        let fx = fixture();
        let model = |table4: [f64; 3], peak: f64, speed: f64| ModelResult {
            dir: PathBuf::from("m"),
            meta: fx.meta.clone(),
            table4,
            forces_pct: 1.0,
            peak_force_error_pct_w: peak,
            channels: Vec::new(),
            speed,
            wall_s: 1.0,
            samples: 2,
        };
        let ev = Evaluation {
            scored_on: ScoredOn::FallbackValidation,
            models: vec![
                model([1.0, 2.346, 3.0], 4.0, 812.4),
                model([0.5, 0.25, 0.126], 0.5, 90.6),
            ],
            truth: None,
        };
        let alg = fx.meta.train.algorithm.id();
        assert_eq!(
            ev.summary(),
            format!(
                "Table 4 on the validation split (NO TEST SPLIT: validation, optimistic) (solutions/first/second) \
                 {alg}: 1.00/2.35/3.00% (peak force 4.00% of the static force), \
                 {alg}: 0.50/0.25/0.13% (peak force 0.50% of the static force); \
                 prediction >= 91 simulated s per wall s"
            )
        );
    }

    /// The truth row computed independently, in f64 from the file's values: per sample,
    /// relative L2 of z-scored central differences of the exact displacements against the
    /// z-scored exact `_v` / `_a`, interior window points.
    fn truth_floor_f64(fx: &Fixture, ids: &[i64]) -> [Vec<f64>; 2] {
        let t = read_parquet(&fx.files.simulation, None).unwrap();
        let sid = t.i64(pino_data::schema::SAMPLE_ID).unwrap();
        let dt = fx.ds.dt;
        let norm = &fx.meta.norm;
        let mut out: [Vec<f64>; 2] = Default::default();
        for &id in ids {
            let rows: Vec<usize> = (0..sid.len()).filter(|&r| sid[r] == id).collect();
            let first = fx.meta.window.first_index(rows.len());
            let rows = &rows[first..];
            let (mut e1, mut x1, mut e2, mut x2) = (0.0, 0.0, 0.0, 0.0);
            for (c, dof) in fx.meta.layout.dofs.iter().enumerate() {
                let z = t.f64(dof).unwrap();
                let v = t.f64(&format!("{dof}_v")).unwrap();
                let a = t.f64(&format!("{dof}_a")).unwrap();
                let zs = |x: f64, s: &pino_learn::norm::ChannelStats| (x - s.mean[c]) / s.std[c];
                for n in 1..rows.len() - 1 {
                    let (p, m, q) = (z[rows[n - 1]], z[rows[n]], z[rows[n + 1]]);
                    let fd1 = zs((q - p) / (2.0 * dt), &norm.velocities);
                    let fd2 = zs((q - 2.0 * m + p) / (dt * dt), &norm.accelerations);
                    let ex1 = zs(v[rows[n]], &norm.velocities);
                    let ex2 = zs(a[rows[n]], &norm.accelerations);
                    e1 += (fd1 - ex1) * (fd1 - ex1);
                    x1 += ex1 * ex1;
                    e2 += (fd2 - ex2) * (fd2 - ex2);
                    x2 += ex2 * ex2;
                }
            }
            out[0].push((e1 / x1).sqrt());
            out[1].push((e2 / x2).sqrt());
        }
        out
    }

    #[test]
    fn an_oracle_scores_zero_on_solutions_and_the_truth_floor_on_derivatives() {
        let fx = fixture();
        let batch = make_batch(&fx.items, &fx.test, fx.ds.t_points(), &Device::Cpu).unwrap();
        let oracle = table4_per_sample(&fx.ctx, &batch.u, &batch).unwrap();
        assert_eq!(oracle[0], vec![0.0; 2], "solutions");
        assert_eq!(oracle[3], vec![0.0; 2], "forces");
        let ids: Vec<i64> = fx.test.iter().map(|&i| fx.items.id(i)).collect();
        let floor = truth_floor_f64(&fx, &ids);
        for k in 0..2 {
            for (got, want) in oracle[1 + k].iter().zip(&floor[k]) {
                // A real floor (the O(dt^2) truncation error of central differences), and the
                // metric reproduces it from the f32 z-scored storage to 5 % of its value
                // (f32 rounding of the displacements, amplified by 1/dt^2 for the second
                // difference, about 1e-4 absolute; the smooth cubic profile leaves a floor of
                // 0.3 %, so that rounding is a larger share of it than under a linear one).
                assert!(*want > 1e-6, "derivative {k}: floor {want}");
                assert!(
                    (got - want).abs() <= 5e-2 * want,
                    "derivative {}: {got} vs f64 {want}",
                    k + 1
                );
            }
        }
    }

    #[test]
    fn a_known_offset_gives_a_known_percentage() {
        let fx = fixture();
        let t = fx.ds.t_points();
        let batch = make_batch(&fx.items, &fx.test, t, &Device::Cpu).unwrap();
        let truth = table4_per_sample(&fx.ctx, &batch.u, &batch).unwrap();
        let u: Vec<f32> = batch.u.flatten_all().unwrap().to_vec1().unwrap();
        let c = 0.25f32;
        let layout = &fx.meta.layout;
        let (o, forces) = (layout.n_outputs(), layout.forces());
        // Offset c on the first solution after the DOFs (the rail under wheel 1, z_r1):
        // solutions error sqrt(T) c / ||u_solutions||, the derivatives (the rigid DOFs only) and
        // forces unchanged. Offset c on the second force (p_2): forces error
        // sqrt(T) c / ||u_forces||, solutions 0.
        assert_eq!(layout.outputs[layout.n_dofs()], "z_r1");
        for (chan, group) in [(layout.n_dofs(), 0usize), (forces.start + 1, 3)] {
            let shifted: Vec<f32> = u
                .iter()
                .enumerate()
                .map(|(k, &x)| if k % o == chan { x + c } else { x })
                .collect();
            let pred = Tensor::from_vec(shifted.clone(), batch.u.shape(), &Device::Cpu).unwrap();
            let m = table4_per_sample(&fx.ctx, &pred, &batch).unwrap();
            let range = if group == 0 {
                0..layout.solutions
            } else {
                forces.clone()
            };
            for s in 0..fx.test.len() {
                let blk = &u[s * t * o..(s + 1) * t * o];
                let sblk = &shifted[s * t * o..(s + 1) * t * o];
                let norm2: f64 = blk
                    .chunks(o)
                    .flat_map(|r| r[range.clone()].iter())
                    .map(|&x| (x as f64).powi(2))
                    .sum();
                // The offset as stored in f32 (x + c rounds), summed exactly.
                let err2: f64 = blk
                    .iter()
                    .zip(sblk)
                    .skip(chan)
                    .step_by(o)
                    .map(|(&a, &b)| (b as f64 - a as f64).powi(2))
                    .sum();
                let want = (err2 / norm2).sqrt();
                assert!(
                    (want - (t as f64).sqrt() * c as f64 / norm2.sqrt()).abs() < 1e-6 * want,
                    "the stored offset is c to f32 rounding"
                );
                assert!(
                    (m[group][s] - want).abs() < 1e-9 * want,
                    "{} vs {want}",
                    m[group][s]
                );
                let other = if group == 0 { 3 } else { 0 };
                assert_eq!(m[other][s], 0.0);
                assert_eq!(m[1][s], truth[1][s]);
                assert_eq!(m[2][s], truth[2][s]);
            }
        }
    }

    #[test]
    fn peak_force_error_is_a_fraction_of_the_static_wheel_load() {
        let fx = fixture();
        let t = fx.ds.t_points();
        let layout = &fx.meta.layout;
        let (o, d, f0) = (layout.n_outputs(), layout.n_dofs(), layout.forces().start);
        // Predictions = exact, with p_1 raised by 5 kN at every time and p_3 lowered by 2 kN
        // at its peak only: peak errors 5 kN and 2 kN per sample, relative L2 of p_2 zero.
        let mut preds = Vec::new();
        for &i in &fx.test {
            let (ex, _) = exact_physical(&fx.items, i, &fx.meta.norm).unwrap();
            let mut u = ex.u.clone();
            let c3 = f0 + 2;
            let kmax = (0..t)
                .max_by(|&a, &b| ex.u[a * o + c3].total_cmp(&ex.u[b * o + c3]))
                .unwrap();
            for r in 0..t {
                u[r * o + f0] += 5e3;
            }
            u[kmax * o + c3] -= 2e3;
            preds.push(Physical {
                u,
                v: ex.v[d..(t - 1) * d].to_vec(),
                a: ex.a[d..(t - 1) * d].to_vec(),
            });
        }
        let system = learn_fixtures::synthetic::vehicle_track_system();
        let ch = channel_errors(&fx.items, &fx.test, &preds, &fx.meta, &system).unwrap();
        let row = |name: &str| ch.iter().find(|c| c.channel == name).unwrap();
        // The static contact force W = (m_c + 2 m_t + 4 m_w) g / 8 of each sample.
        let w: Vec<f64> = fx
            .test
            .iter()
            .map(|&i| {
                let p = |name: &str| {
                    fx.items.params(i)[layout.params.iter().position(|n| n == name).unwrap()]
                };
                (p("m_c") + 2.0 * p("m_t") + 4.0 * p("m_w")) * 9.81 / 8.0
            })
            .collect();
        for (k, &i) in fx.test.iter().enumerate() {
            assert!((fx.items.force_scale(i) - w[k]).abs() < 1e-9 * w[k]);
        }
        let mean_inv_w = w.iter().map(|w| 1.0 / w).sum::<f64>() / w.len() as f64;
        let p1 = row("p_1");
        assert_eq!(p1.unit, "kN");
        assert!((p1.rms_error - 5.0).abs() < 1e-6, "{}", p1.rms_error);
        let pk1 = p1.peak_error_pct_w.unwrap();
        assert!((pk1 - 100.0 * 5e3 * mean_inv_w).abs() < 1e-6 * pk1, "{pk1}");
        let p3 = row("p_3").peak_error_pct_w.unwrap();
        // The peak moves to the next-largest value: an error of at most 2 kN.
        assert!(
            p3 > 0.0 && p3 <= 100.0 * 2e3 * mean_inv_w * (1.0 + 1e-9),
            "{p3}"
        );
        assert_eq!(row("p_2").rel_l2_pct, 0.0);
        assert_eq!(row("p_2").peak_error_pct_w, Some(0.0));
        // Displacements are exact, so the Hertz route gives back the exact force (to the f32
        // storage of displacements).
        assert!(row("p_2_hertz").rel_l2_pct < 1.0);
        assert_eq!(row("z_c").peak_error_pct_w, None);
        assert_eq!(ch.len(), o + 2 * d + 4);
    }
}
