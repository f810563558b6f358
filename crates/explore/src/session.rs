//! The explorer's model session: one trained model (and, when known, its dataset) with every
//! answer of the API computed from it by name: the summary (parameters with units, nominal
//! values and training ranges; channels by group; indices with limits; test samples), the
//! prediction of a design, a one-parameter sweep, the exact solve beside the prediction and the
//! downloads. Nothing here knows a particular system: names, units, groups and limits come from
//! the model's description and layout (`model.json`).
//!
//! Times and rows: a prediction's curves are the interior points of the model's window
//! (`n = 1..T-2`, where its central-difference derivatives exist): the rows `predict --out`
//! writes, so the page shows exactly what the command gives. The exact solve runs the
//! `simulate` stage's engine with the dataset's run controls and is cut to the same rows.
//!
//! Error bars: with the model's calibration ([`Explorer::load_calibration`],
//! docs/uncertainty.md) every prediction carries, at the request's coverage, each index's
//! interval and three-valued verdict and each predicted channel's band (half-widths at the same
//! interior rows); sweeps carry each index curve's intervals. Without one the answers say why
//! ([`Explorer::calibration_note`]).

use crate::channel::{channels_of, Channel};
use crate::request::{ApiError, DesignRequest, Excitation, RequestRules, SweepRequest};
use crate::solve::{self, Rates};
use mbd_engine::{Profile, RunConfig};
use pino_calibration::{CalibratedAnswer, REPORTED_LEVELS};
use pino_indices::IndexConfig;
use pino_outputs::indices_eval::StoredColumns;
use pino_predict::{DesignAnswer, Predictor, ProfileChoice, ProfileSource, SetPrediction};
use pino_surrogate::Surrogate;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

/// Errors of opening a model.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The model or its dataset could not be read.
    #[error(transparent)]
    Eval(#[from] pino_outputs::Error),
    /// Reading the dataset's files.
    #[error(transparent)]
    Data(#[from] pino_data::Error),
    /// The calibration refused (missing, corrupt, of another model), naming the file.
    #[error("{0}")]
    Calibration(String),
    /// Anything else, with its context.
    #[error("{0}")]
    Other(String),
}

/// The request limits of a session.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Limits {
    /// Most designs in one sweep.
    pub sweep_max_designs: usize,
    /// Most solver points in one sweep.
    pub sweep_max_solve_points: usize,
    /// Longest simulated duration a solve may run (s).
    pub solve_max_duration_s: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            sweep_max_designs: 400,
            sweep_max_solve_points: 8,
            solve_max_duration_s: 30.0,
        }
    }
}

/// Where a model's dataset lives (the `sample-params` and `irregularity` outputs).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DatasetFiles {
    /// `params.parquet` file(s).
    pub params: Vec<PathBuf>,
    /// `irregularity.parquet` file(s) (empty for a system without generated profiles).
    pub profiles: Vec<PathBuf>,
}

/// A test sample of the dataset: its design and its profiles.
#[derive(Debug, Clone)]
pub struct TestSample {
    /// Sample id.
    pub id: i64,
    /// Its parameters (model order).
    pub design: Vec<f64>,
    profiles: Profiles,
}

/// The model's identity as downloads and the summary carry it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelIdentity {
    /// The model directory.
    pub dir: String,
    /// blake3 of `model.json` and `model.safetensors` (hex).
    pub identity: String,
    /// Algorithm of Table 3.
    pub algorithm: i64,
    /// The system's name.
    pub system: String,
}

/// The curves and indices of one design (prediction or solve).
#[derive(Debug, Clone, PartialEq)]
pub struct Response {
    /// Interior times of the window (s).
    pub t: Vec<f64>,
    /// Per summary channel, its values at `t`.
    pub channels: Vec<Vec<f64>>,
    /// Index values (summary order); empty when the model computes none.
    pub indices: Vec<f64>,
    /// Indices over their limits.
    pub failed: Vec<String>,
    /// The intervals, bands and three-valued verdicts of a calibrated prediction (`None` for
    /// a solve, or without a calibration).
    pub calibrated: Option<CalibratedAnswer>,
}

/// The points of each profile of the system (`None`: analytic or level), shared.
type Profiles = Arc<Vec<Option<Profile>>>;

/// How many generated profile sets are kept for reuse.
const PROFILE_CACHE: usize = 8;

/// A model opened for exploration.
pub struct Explorer {
    surrogate: Surrogate,
    identity: ModelIdentity,
    run: RunConfig,
    index_cfg: IndexConfig,
    index_limits: Vec<Option<f64>>,
    channels: Vec<Channel>,
    rules: RequestRules,
    units: Vec<String>,
    /// The units of the columns of the model's system, carried by the downloaded tables.
    column_units: pino_data::units::Units,
    test: Vec<TestSample>,
    dataset: DatasetFiles,
    generated: Vec<String>,
    cache: Mutex<Vec<((u64, u64), Profiles)>>,
    limits: Limits,
    calibration_file: Option<PathBuf>,
    calibration_note: Option<String>,
    model_dir: PathBuf,
}

/// Why answers carry no interval when no calibration was given.
pub const NO_CALIBRATION: &str = "no error bar: no calibration was given, the answers are point values (give --calibration, or run the pipeline's `calibrate` stage; docs/uncertainty.md)";

fn internal(e: impl std::fmt::Display) -> ApiError {
    ApiError::internal(e)
}

impl Explorer {
    /// Opens the model in `model_dir` (and its dataset, when given) on the CPU; its
    /// calibration comes with [`Explorer::load_calibration`].
    pub fn open(model_dir: &Path, dataset: DatasetFiles, limits: Limits) -> Result<Self, Error> {
        let predictor = Predictor::load(model_dir, &candle_core::Device::Cpu)?;
        Self::of(Surrogate::of_model(predictor), model_dir, dataset, limits)
    }

    /// Opens the surrogate in `dir` (the `surrogate` stage's output: its members, each with
    /// its calibration) on the CPU: every index and channel answered by its member.
    pub fn open_surrogate(
        dir: &Path,
        dataset: DatasetFiles,
        limits: Limits,
    ) -> Result<Self, Error> {
        let surrogate = Surrogate::load(dir, &candle_core::Device::Cpu)?;
        let mut ex = Self::of(surrogate, dir, dataset, limits)?;
        ex.calibration_file = Some(dir.to_owned());
        ex.intervals_loaded(dir, None);
        Ok(ex)
    }

    fn of(
        surrogate: Surrogate,
        model_dir: &Path,
        dataset: DatasetFiles,
        limits: Limits,
    ) -> Result<Self, Error> {
        let predictor = surrogate.primary();
        let system = predictor.system().clone();
        let column_units =
            pino_data::system::units_of(&system)?.with(pino_indices::column_units(&system))?;
        let meta = &predictor.meta;
        let run = predictor.run_config(None)?;
        let index_cfg = predictor.index_config()?;
        let index_limits = predictor.index_inputs().limits(&system, &index_cfg);
        let channels = channels_of(&surrogate);
        let names = predictor.space.names().to_vec();
        let ranges = names
            .iter()
            .map(|n| {
                let r = &meta.training_ranges;
                match r.names.iter().position(|x| x == n) {
                    Some(k) => [r.min[k], r.max[k]],
                    None => [f64::NEG_INFINITY, f64::INFINITY],
                }
            })
            .collect();
        let units = names
            .iter()
            .map(|n| {
                system
                    .parameter(n)
                    .map_or("-", |p| system.parameters[p].unit.as_str())
                    .to_owned()
            })
            .collect();
        let rules = RequestRules {
            nominal: predictor.space.nominal(),
            names,
            ranges,
            sweep_max_designs: limits.sweep_max_designs,
            sweep_max_solve_points: limits.sweep_max_solve_points,
            calibration_n: None,
            band_channels: Vec::new(),
        };
        let generated = system
            .profiles
            .iter()
            .filter(|p| matches!(p, mbd_system::system::Profile::Generated { .. }))
            .map(|p| p.name().to_owned())
            .collect();
        let identity = ModelIdentity {
            dir: model_dir.display().to_string(),
            identity: predictor.identity().blake3.clone(),
            algorithm: meta.train.algorithm.id(),
            system: system.name.clone(),
        };
        let test = test_samples(predictor, &rules.names, &dataset)?;
        Ok(Self {
            surrogate,
            identity,
            run,
            index_cfg,
            index_limits,
            channels,
            rules,
            units,
            column_units,
            test,
            dataset,
            generated,
            cache: Mutex::new(Vec::new()),
            limits,
            calibration_file: None,
            calibration_note: Some(NO_CALIBRATION.to_owned()),
            model_dir: model_dir.to_owned(),
        })
    }

    /// Loads the model's calibration (a `calibration.json` or the `calibrate` stage's output
    /// directory): refused, naming the file, when missing, corrupt or of another model. A
    /// calibration without intervals (`n_calibration: 0`) is accepted and its reason noted.
    pub fn load_calibration(&mut self, path: &Path) -> Result<(), Error> {
        let why = self
            .surrogate
            .load_calibration(path)
            .map_err(|e| Error::Calibration(format!("calibration {}: {e}", path.display())))?
            .no_intervals
            .clone();
        self.calibration_file = Some(path.to_owned());
        self.intervals_loaded(path, why);
        Ok(())
    }

    /// The request rules and the note after the calibration(s) from `path` were loaded
    /// (`why`: the reason a calibration without intervals gives).
    fn intervals_loaded(&mut self, path: &Path, why: Option<String>) {
        let n = self.predictor().calibration().map(|c| c.n);
        match n.filter(|_| self.surrogate.has_intervals()) {
            Some(n) => {
                self.rules.calibration_n = Some(n);
                self.calibration_note = None;
                self.rules.band_channels = (0..self.channels.len())
                    .filter(|&k| self.band_index(k).is_some())
                    .map(|k| self.channels[k].name.clone())
                    .collect();
            }
            None => {
                self.rules.calibration_n = None;
                self.rules.band_channels.clear();
                self.calibration_note = Some(format!(
                    "no error bar: the calibration {} has no intervals: {}",
                    path.display(),
                    why.unwrap_or_else(|| "it has no calibration samples".into())
                ));
            }
        }
    }

    /// Records why no calibration was loaded (shown on the page and in the summary).
    pub fn no_calibration(&mut self, why: impl Into<String>) {
        self.calibration_note = Some(why.into());
    }

    /// Why the answers carry no interval; `None` when they do.
    pub fn calibration_note(&self) -> Option<&str> {
        self.calibration_note.as_deref()
    }

    /// Whether the answers carry intervals.
    pub fn has_intervals(&self) -> bool {
        self.rules.calibration_n.is_some()
    }

    /// Where channel `channel`'s band sits in a calibrated answer's `bands` (its own index:
    /// the bands follow [`Explorer::channels`]); `None` for excitations, exact inputs, and
    /// without intervals.
    pub fn band_index(&self, channel: usize) -> Option<usize> {
        if !self.has_intervals() {
            return None;
        }
        self.surrogate.channel_band(channel).map(|_| channel)
    }

    /// The calibration as the summary lists it (`null` without intervals).
    fn calibration_summary(&self) -> serde_json::Value {
        let Some(cal) = self.predictor().calibration().filter(|c| c.has_intervals()) else {
            return serde_json::Value::Null;
        };
        let levels: Vec<_> = REPORTED_LEVELS
            .iter()
            .map(|&level| match cal.at(level) {
                Ok(_) => serde_json::json!({"level": level, "supported": true, "why": null}),
                Err(e) => {
                    serde_json::json!({"level": level, "supported": false, "why": e.to_string()})
                }
            })
            .collect();
        serde_json::json!({
            "file": self.calibration_file.as_ref().map(|p| p.display().to_string()),
            "n": cal.n,
            "normaliser": cal.normaliser.as_str(),
            "max_coverage": pino_calibration::max_coverage(cal.n),
            "levels": levels,
            "default_coverage": crate::request::DEFAULT_COVERAGE,
        })
    }

    /// The model's directory (a `train` output) or the surrogate's.
    pub fn model_dir(&self) -> &Path {
        &self.model_dir
    }

    /// The surrogate answering (a single model is one of one member).
    pub fn surrogate(&self) -> &Surrogate {
        &self.surrogate
    }

    /// The calibration file or directory the intervals come from, when one was loaded.
    pub fn calibration_file(&self) -> Option<&Path> {
        self.calibration_file.as_deref()
    }

    /// The model whose system, design space, time grid and ranges the answers share (the
    /// surrogate's primary member).
    pub fn predictor(&self) -> &Predictor {
        self.surrogate.primary()
    }

    /// The parser of this model's requests.
    pub fn rules(&self) -> &RequestRules {
        &self.rules
    }

    /// The model's identity.
    pub fn identity(&self) -> &ModelIdentity {
        &self.identity
    }

    /// The channels, in the order of [`Response::channels`].
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// The units of the columns of the model's system (parameters, channels, indices), which
    /// the downloaded tables carry.
    pub fn column_units(&self) -> &pino_data::units::Units {
        &self.column_units
    }

    /// The test samples of the dataset (empty without one).
    pub fn test_samples(&self) -> &[TestSample] {
        &self.test
    }

    /// The request limits.
    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// The default excitation: the first test sample, else seed 1 id 0.
    pub fn default_excitation(&self) -> Excitation {
        match self.test.first() {
            Some(s) => Excitation::Test { sample_id: s.id },
            None => Excitation::Seed { seed: 1, id: 0 },
        }
    }

    /// The summary (`GET /api/model`).
    pub fn summary(&self) -> serde_json::Value {
        let meta = &self.predictor().meta;
        let r = &self.rules;
        let parameters: Vec<_> = (0..r.names.len())
            .map(|k| {
                serde_json::json!({
                    "name": r.names[k],
                    "unit": self.units[k],
                    "nominal": r.nominal[k],
                    "min": r.ranges[k][0],
                    "max": r.ranges[k][1],
                })
            })
            .collect();
        let inputs = self.predictor().index_inputs();
        let columns = if inputs.computable() {
            inputs.columns()
        } else {
            &[]
        };
        let indices: Vec<_> = columns
            .iter()
            .zip(&self.index_limits)
            .map(|(c, limit)| {
                serde_json::json!({
                    "name": c.name,
                    "unit": c.unit,
                    "definition": c.definition,
                    "limit": limit.map(|v| serde_json::json!({"kind": "max", "value": v})),
                })
            })
            .collect();
        let tests: Vec<_> = self
            .test
            .iter()
            .map(|s| serde_json::json!({"sample_id": s.id, "design": self.design_map(&s.design)}))
            .collect();
        serde_json::json!({
            "system": self.identity.system,
            "model": self.identity,
            "parameters": parameters,
            "channels": self.channels,
            "indices": indices,
            "indices_note": if self.predictor().index_inputs().computable() { String::new() } else { self.predictor().index_inputs().why_not() },
            "excitation": {
                "generated_profiles": self.generated,
                "test_samples": tests,
                "default": self.default_excitation(),
            },
            "time": {"t0": meta.grid.t0, "dt": meta.grid.dt, "points": meta.grid.t_points},
            "limits": self.limits,
            "calibration": self.calibration_summary(),
            "calibration_note": self.calibration_note,
        })
    }

    /// A design as a JSON object by name.
    pub fn design_map(&self, design: &[f64]) -> serde_json::Map<String, serde_json::Value> {
        self.rules
            .names
            .iter()
            .zip(design)
            .map(|(n, v)| (n.clone(), serde_json::Value::from(*v)))
            .collect()
    }

    /// The parameters of `design` outside the training ranges, read by name, as JSON; a design
    /// of another count (built by the server, not the client) is a fault of the server.
    pub fn outside(&self, design: &[f64]) -> Result<Vec<serde_json::Value>, ApiError> {
        let design = self
            .predictor()
            .system()
            .sampled_values(design)
            .map_err(ApiError::internal)?;
        Ok(self
            .predictor()
            .meta
            .training_ranges
            .outside(&design)
            .iter()
            .map(|o| {
                serde_json::json!({"name": o.name, "value": o.value, "min": o.range[0], "max": o.range[1]})
            })
            .collect())
    }

    /// The profiles of an excitation (the default when `None`).
    pub fn profiles(&self, ex: Option<Excitation>) -> Result<Profiles, ApiError> {
        if self.generated.is_empty() {
            return Ok(Arc::new(vec![
                None;
                self.predictor().system().profiles.len()
            ]));
        }
        match ex.unwrap_or_else(|| self.default_excitation()) {
            Excitation::Test { sample_id } => self
                .test
                .iter()
                .find(|s| s.id == sample_id)
                .map(|s| s.profiles.clone())
                .ok_or_else(|| {
                    let ids: Vec<String> = self.test.iter().map(|s| s.id.to_string()).collect();
                    ApiError::bad(
                        "excitation.sample_id",
                        format!("no test sample {sample_id} in the model's dataset"),
                        if ids.is_empty() {
                            "none: this model was opened without its dataset; use {\"kind\": \"seed\"}".to_owned()
                        } else {
                            format!("test sample ids: {}", ids.join(", "))
                        },
                    )
                }),
            Excitation::Seed { seed, id } => {
                let key = (seed, id);
                if let Some((_, p)) = self.cache.lock().map_err(internal)?.iter().find(|(k, _)| *k == key) {
                    return Ok(p.clone());
                }
                let p = self
                    .predictor()
                    .profiles(Some(&ProfileChoice::Generated { seed, id }))
                    .map_err(|e| ApiError::bad("excitation", e.to_string(), "a seed the dataset's generator accepts"))?;
                let p = Arc::new(p);
                let mut cache = self.cache.lock().map_err(internal)?;
                if cache.len() >= PROFILE_CACHE {
                    cache.remove(0);
                }
                cache.push((key, p.clone()));
                Ok(p)
            }
        }
    }

    /// Refuses a design outside the description's domains (a negative mass), whose run leaves
    /// its profiles or beams (a speed too high) or that the network cannot read (1e300), the
    /// error naming the design parameter at fault (`design.NAME`, the row the page marks) and,
    /// for a run, its limit.
    fn check(&self, design: &[f64], profiles: &[Option<Profile>]) -> Result<(), ApiError> {
        self.predictor()
            .excitations_of(design, profiles, &self.run, "design")
            .and_then(|_| self.predictor().readable(design, "design"))
            .map_err(|e| match e {
                pino_outputs::Error::Learn(pino_learn::Error::OutOfRange {
                    field,
                    value,
                    allowed,
                }) => ApiError::bad(
                    field.clone(),
                    format!("`{field}` = {} is out of range", short_number(&value)),
                    allowed,
                ),
                // A run no design parameter explains: the profiles under it.
                other => ApiError::bad(
                    "excitation",
                    other.to_string(),
                    "profiles that cover the run",
                ),
            })
    }

    /// Refuses `design` under `excitation` as a prediction would: a value outside the
    /// description's domains, a run that leaves its profiles or beams, a value the network
    /// cannot read (the parameter at fault named, `design.NAME`).
    pub fn check_design(&self, design: &[f64], excitation: Excitation) -> Result<(), ApiError> {
        let profiles = self.profiles(Some(excitation))?;
        self.check(design, &profiles)
    }

    /// Every member's prediction of `design` (`None` for a member answering nothing).
    fn predict_raw(
        &self,
        design: &[f64],
        profiles: &[Option<Profile>],
    ) -> Result<Vec<Option<SetPrediction>>, ApiError> {
        self.check(design, profiles)?;
        let sets = [design.to_vec()];
        Ok(self
            .surrogate
            .forward_with(0, &sets, &ProfileSource::Shared(profiles), &self.run)
            .map_err(|e| self.refusal(e, None))?
            .into_iter()
            .map(|m| m.and_then(|mut v| v.pop()))
            .collect())
    }

    /// A refusal of the predictor in the request's words: a design parameter at fault
    /// (`sets[k].NAME`) is `design.NAME`, or in a sweep the end (`from`, `to`) a swept
    /// parameter lies towards; anything else is the excitation's.
    fn refusal(&self, e: pino_outputs::Error, sweep: Option<&SweepRequest>) -> ApiError {
        if let pino_outputs::Error::Learn(pino_learn::Error::OutOfRange {
            field,
            value,
            allowed,
        }) = &e
        {
            let at = field
                .strip_prefix("sets[")
                .and_then(|rest| rest.split_once("]."))
                .and_then(|(k, name)| Some((k.parse::<usize>().ok()?, name)));
            if let Some((k, name)) = at {
                let field = format!("design.{name}");
                let error = ApiError::bad(
                    field.clone(),
                    format!("`{field}` = {} is out of range", short_number(value)),
                    allowed.clone(),
                );
                return match sweep {
                    Some(req) => self.at_sweep_end(error, req, k),
                    None => error,
                };
            }
        }
        ApiError::bad("excitation", e.to_string(), "profiles that cover the run")
    }

    /// An error on design `k` of a sweep, the first refused: when it blames the swept
    /// parameter, it is the sweep's `from` when that design is the first, else its `to` (the
    /// sweep runs in a line from an accepted `from` to the refused values).
    fn at_sweep_end(&self, mut e: ApiError, req: &SweepRequest, k: usize) -> ApiError {
        let swept = format!("design.{}", self.rules.names[req.parameter]);
        if e.field.as_deref() == Some(swept.as_str()) {
            let end = if k == 0 { "from" } else { "to" };
            e.error = format!("sweep `{end}`: {}", e.error);
            e.field = Some(end.to_owned());
        }
        e
    }

    /// The solver's answer of `design` (its values `exact` laid out as the primary member's
    /// prediction, with its `stored` columns): the curves at the interior rows and the indices.
    fn exact_response(
        &self,
        design: &[f64],
        exact: &SetPrediction,
        stored: &StoredColumns,
    ) -> Result<Response, ApiError> {
        let meta = &self.predictor().meta;
        let inputs = self.predictor().index_inputs();
        let ix = if inputs.computable() {
            let ix = inputs
                .sample(
                    self.predictor().system(),
                    &meta.layout,
                    design,
                    0,
                    &exact.physical,
                    Some(stored),
                    &exact.eta,
                    &meta.grid,
                    &self.index_cfg,
                )
                .map_err(internal)?;
            Some(ix)
        } else {
            None
        };
        let (t, channels) = solve::curves(&self.channels, &meta.grid, |c| {
            Some((exact, meta, c.exact?, Rates::EveryPoint))
        });
        Ok(Response {
            t,
            channels,
            failed: ix.as_ref().map_or_else(Vec::new, |ix| ix.failed.clone()),
            indices: ix.map_or_else(Vec::new, |ix| ix.values),
            calibrated: None,
        })
    }

    /// The answer of `design` from its members' predictions `per`: each channel's curve at the
    /// interior rows and each index from the member answering it, with the intervals, bands and
    /// verdicts at `coverage` when calibrated.
    fn predicted_response(
        &self,
        design: &[f64],
        per: &[Option<SetPrediction>],
        coverage: f64,
    ) -> Result<Response, ApiError> {
        let refs: Vec<Option<&SetPrediction>> = per.iter().map(Option::as_ref).collect();
        let coverage = Some(coverage).filter(|_| self.has_intervals());
        let (ix, calibrated) = self
            .surrogate
            .respond(design, &refs, &self.index_cfg, coverage)
            .map_err(calibration_error)?;
        let members = self.surrogate.members();
        let (t, channels) = solve::curves(&self.channels, &self.predictor().meta.grid, |c| {
            Some((
                refs[c.member]?,
                &members[c.member].meta,
                c.slot,
                Rates::Interior,
            ))
        });
        let computable = self.predictor().index_inputs().computable();
        Ok(Response {
            t,
            channels,
            failed: if computable { ix.failed } else { Vec::new() },
            indices: if computable { ix.values } else { Vec::new() },
            calibrated,
        })
    }

    /// Predicts one design.
    pub fn predict(&self, req: &DesignRequest) -> Result<Response, ApiError> {
        let profiles = self.profiles(req.excitation)?;
        let per = self.predict_raw(&req.design, &profiles)?;
        self.predicted_response(&req.design, &per, req.coverage)
    }

    /// The designs of a sweep.
    pub fn sweep_designs(&self, req: &SweepRequest) -> Vec<Vec<f64>> {
        (0..req.steps)
            .map(|k| {
                let mut d = req.base.design.clone();
                let f = k as f64 / (req.steps - 1) as f64;
                d[req.parameter] = if k + 1 == req.steps {
                    req.to
                } else {
                    req.from + f * (req.to - req.from)
                };
                d
            })
            .collect()
    }

    /// The index values of every design of a sweep through the surrogate (batches side by side
    /// on the CPU), with their intervals at the request's coverage when calibrated.
    pub fn sweep(
        &self,
        req: &SweepRequest,
    ) -> Result<(Vec<Vec<f64>>, Vec<DesignAnswer>), ApiError> {
        let designs = self.sweep_designs(req);
        if !self.predictor().index_inputs().computable() {
            return Err(ApiError::bad(
                "parameter",
                format!(
                    "this model computes no index: {}",
                    self.predictor().index_inputs().why_not()
                ),
                "a model whose description defines indices",
            ));
        }
        let profiles = self.profiles(req.base.excitation)?;
        for (k, d) in designs.iter().enumerate() {
            self.check(d, &profiles)
                .map_err(|e| self.at_sweep_end(e, req, k))?;
        }
        let batch = designs
            .len()
            .div_ceil(rayon::current_num_threads().max(1))
            .max(1);
        let answers = if self.has_intervals() {
            self.surrogate
                .answers(
                    &designs,
                    &ProfileSource::Shared(&profiles),
                    &self.run,
                    &self.index_cfg,
                    batch,
                    req.base.coverage,
                )
                .map_err(|e| match e {
                    pino_outputs::Error::Learn(pino_learn::Error::OutOfRange {
                        ref field, ..
                    }) if !field.starts_with("sets[") => calibration_error(e),
                    e => self.refusal(e, Some(req)),
                })?
        } else {
            self.surrogate
                .indices(&designs, &profiles, &self.run, &self.index_cfg, batch)
                .map_err(|e| self.refusal(e, Some(req)))?
                .into_iter()
                .map(|indices| DesignAnswer {
                    indices,
                    calibrated: None,
                })
                .collect()
        };
        Ok((designs, answers))
    }

    /// The exact solve of a design beside its prediction; stops early (an error) when `cancel`
    /// is set. Returns the prediction, the solve and the solver's time (ms).
    pub fn solve(
        &self,
        req: &DesignRequest,
        cancel: &AtomicBool,
    ) -> Result<(Response, Response, f64), ApiError> {
        let predicted = self.predict(req)?;
        let (solved, solve_ms) = self.exact(req, cancel)?;
        Ok((predicted, solved, solve_ms))
    }

    /// The solver's answer for a design and the solver's time (ms).
    fn exact(&self, req: &DesignRequest, cancel: &AtomicBool) -> Result<(Response, f64), ApiError> {
        if self.run.duration > self.limits.solve_max_duration_s {
            return Err(ApiError::bad(
                "design",
                format!(
                    "the model's runs are {} s long, over this server's solve limit",
                    self.run.duration
                ),
                format!(
                    "runs up to {} s (--solve-max-duration)",
                    self.limits.solve_max_duration_s
                ),
            ));
        }
        let profiles = self.profiles(req.excitation)?;
        let started = std::time::Instant::now();
        let exact = solve::exact(self.predictor(), &self.run, &req.design, &profiles, cancel)?;
        let solve_ms = started.elapsed().as_secs_f64() * 1e3;
        let stored = StoredColumns::of_sample(self.predictor().index_inputs(), 0, exact.stored);
        let solved = self.exact_response(&req.design, &exact.values, &stored)?;
        Ok((solved, solve_ms))
    }

    /// The indices of one design through the solver (the sweep's solver points).
    pub fn solve_indices(
        &self,
        design: &[f64],
        excitation: Option<Excitation>,
        cancel: &AtomicBool,
    ) -> Result<Vec<f64>, ApiError> {
        let req = DesignRequest {
            design: design.to_vec(),
            excitation,
            coverage: crate::request::DEFAULT_COVERAGE,
            bands: Some(Vec::new()),
            encoding: crate::request::Encoding::Json,
        };
        Ok(self.exact(&req, cancel)?.0.indices)
    }

    /// Index columns (name, unit) in value order; empty when the model computes none.
    pub fn index_names(&self) -> Vec<String> {
        let inputs = self.predictor().index_inputs();
        if !inputs.computable() {
            return Vec::new();
        }
        inputs.columns().iter().map(|c| c.name.clone()).collect()
    }

    /// The limit of each index (summary order).
    pub fn index_limits(&self) -> &[Option<f64>] {
        &self.index_limits
    }

    /// The `predict` command line that reproduces a design file with this excitation.
    pub fn predict_command(&self, ex: Option<Excitation>, design_file: &str) -> String {
        let flag = if self.surrogate.dir().is_some() {
            "--surrogate"
        } else {
            "--model"
        };
        let mut cmd = format!(
            "predict {flag} {} --params {design_file}",
            self.identity.dir
        );
        if !self.generated.is_empty() {
            match ex.unwrap_or_else(|| self.default_excitation()) {
                Excitation::Test { sample_id } => {
                    let file = self
                        .dataset
                        .profiles
                        .first()
                        .map_or(pino_data::artifacts::IRREGULARITY_FILE.to_owned(), |p| {
                            p.display().to_string()
                        });
                    cmd.push_str(&format!(" --profile {file} --profile-id {sample_id}"));
                }
                Excitation::Seed { seed, id } => {
                    cmd.push_str(&format!(" --seed {seed} --profile-id {id}"));
                }
            }
        }
        cmd + " --out predictions.parquet"
    }

    /// The excitation actually used (the default resolved).
    pub fn excitation_used(&self, ex: Option<Excitation>) -> Option<Excitation> {
        (!self.generated.is_empty()).then(|| ex.unwrap_or_else(|| self.default_excitation()))
    }
}

/// A value as an error message quotes it: a number of many digits (`1e300`, written by the
/// library as 301 digits) in exponent form, anything else as it is.
fn short_number(value: &str) -> String {
    match value.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x != 0.0 && !(1e-6..1e9).contains(&x.abs()) => format!("{x:e}"),
        _ => value.to_owned(),
    }
}

/// A calibration's refusal of a request: a level it cannot support is the request's `coverage`;
/// anything else is a fault of the calibration file.
fn calibration_error(e: pino_outputs::Error) -> ApiError {
    match e {
        pino_outputs::Error::Learn(pino_learn::Error::OutOfRange { field, allowed, .. })
            if field == "coverage" =>
        {
            ApiError::bad("coverage", format!("`coverage`: {allowed}"), allowed)
        }
        other => ApiError::internal(format!("the calibration: {other}")),
    }
}

/// The test split of the dataset, with each sample's profiles.
fn test_samples(
    predictor: &Predictor,
    names: &[String],
    dataset: &DatasetFiles,
) -> Result<Vec<TestSample>, Error> {
    if dataset.params.is_empty() {
        return Ok(Vec::new());
    }
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let table = pino_data::records::read_params(&dataset.params, &refs)?;
    let rows: Vec<usize> = (0..table.ids.len())
        .filter(|&r| table.splits[r] == mbd_dataset::Split::Test.as_str())
        .collect();
    let ids: Vec<i64> = rows.iter().map(|&r| table.ids[r]).collect();
    let system = predictor.system();
    let mut profiles: BTreeMap<i64, Vec<Option<Profile>>> = match dataset.profiles.as_slice() {
        [] => ids
            .iter()
            .map(|&id| (id, vec![None; system.profiles.len()]))
            .collect(),
        files => pino_predict::profiles_of_samples(system, files, &ids)?,
    };
    Ok(rows
        .into_iter()
        .map(|r| TestSample {
            id: table.ids[r],
            design: table.values[r].clone(),
            profiles: Arc::new(profiles.remove(&table.ids[r]).unwrap_or_default()),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::short_number;

    #[test]
    fn numbers_of_many_digits_are_quoted_in_exponent_form() {
        assert_eq!(1e300_f64.to_string().len(), 301);
        assert_eq!(short_number(&1e300_f64.to_string()), "1e300");
        assert_eq!(short_number(&(-2.5e-12_f64).to_string()), "-2.5e-12");
        for same in ["-1", "573.547", "31104", "0", "NaN", "inf", "sample"] {
            assert_eq!(short_number(same), same);
        }
    }
}
