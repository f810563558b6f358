//! Conformal calibration of a trained model (`docs/uncertainty.md`): the intervals and bands
//! every surrogate answer carries, from held-out solver runs.
//!
//! For one model, the `calibrate` stage ([`build`]) predicts the dataset's calibration split
//! (solver runs never used for training or for choosing settings) and records, per quantity,
//! the sorted nonconformity scores `s_i = e_i / sigma_i` of the samples:
//! - each index of the description (railway family and simple indices): `e = |y - f|` in the
//!   index's unit;
//! - each predicted channel (outputs, and the rigid DOFs' velocities and accelerations as
//!   central differences, over the interior window points a prediction is written at), as a
//!   simultaneous band: `e = max_t |y(t) - f(t)| / scale(t)`, `scale(t)` the mean absolute
//!   error of the channel at time `t` over the validation split, smoothed and floored (the
//!   band is wide where the model is usually wrong, at the window's ends say, and narrow
//!   elsewhere), fixed before any calibration score is computed.
//!
//! `sigma_i` is the [`Normaliser`]'s difficulty of sample `i`, known without the solver. An
//! answer at coverage `c` is `f +- q_c sigma` (a band `f(t) +- q_c sigma scale(t)`), `q_c` the
//! conformal quantile of the scores ([`pino_conformal::ScoreSet`]). A calibration belongs to one
//! model ([`ModelIdentity`]: the hashes of its files) and one dataset design (the description
//! and its sampling ranges); `predict` and `explore` refuse any other ([`Calibration::load`]).
//!
//! - [`build`]: the `calibrate` stage (scores on the calibration split, the scales and heads).
//! - [`scored`]: a model's samples of a split scored against the solver (what [`build`] and
//!   [`coverage`] read).
//! - [`difficulty`]: the residual probe, a design's difficulty known without the solver.
//! - [`answer`]: a calibration applied to an answer: intervals, bands and verdicts.
//! - [`coverage`]: the empirical coverage of the intervals on a scored split.
//! - [`report`]: the coverage files of `evaluate`.
//!
//! The conformal mathematics is `pino-conformal`'s, free of any model; this crate binds it to
//! the learning engine's models and datasets.
#![warn(missing_docs)]

pub mod answer;
pub mod build;
pub mod coverage;
pub mod difficulty;
pub mod report;
pub mod scored;

pub use answer::{Calibrated, CalibratedAnswer};

pub use pino_conformal::scores::{max_coverage, rank as conformal_rank};
use pino_conformal::{ErrorHead, ScoreSet};
use pino_learn::Error as LearnError;
pub use pino_outputs::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The file a calibration is written to.
pub const CALIBRATION_FILE: &str = "calibration.json";

/// Its format tag.
pub const CALIBRATION_FORMAT: &str = "pino-mbd calibration 1";

/// The levels every report states (`evaluate`'s coverage table, the explorer's choices).
pub const REPORTED_LEVELS: [f64; 3] = [0.8, 0.9, 0.95];

/// The coverage an answer carries unless another is asked for.
pub const DEFAULT_COVERAGE: f64 = 0.9;

/// The name of the residual feature of the error head.
pub const RESIDUAL_FEATURE: &str = "ln_relative_residual";

/// How a sample's difficulty `sigma` is estimated without the solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Normaliser {
    /// `sigma = 1`: intervals of constant width.
    None,
    /// `sigma = g`, the prediction's relative physics residual ([`difficulty`]).
    Residual,
    /// `sigma` from a log-linear error head per quantity ([`pino_conformal::ErrorHead`]) over
    /// the design's parameters and `ln g`, fitted on the validation split's errors.
    ErrorHead,
}

impl Normaliser {
    /// Every normaliser, in report order.
    pub const ALL: [Normaliser; 3] = [
        Normaliser::None,
        Normaliser::Residual,
        Normaliser::ErrorHead,
    ];

    /// The label used in files and tables.
    pub fn as_str(self) -> &'static str {
        match self {
            Normaliser::None => "none",
            Normaliser::Residual => "residual",
            Normaliser::ErrorHead => "error_head",
        }
    }
}

/// What an error head reads of a design (the `calibrate` stage's `head_inputs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeadInput {
    /// The design's sampled parameters (one feature each).
    Parameters,
    /// `ln g`, the log of the prediction's relative physics residual.
    Residual,
}

/// A model's identity: blake3 of its files.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModelIdentity {
    /// blake3 over `model.json` and `model.safetensors` (each name, length and bytes), hex.
    pub blake3: String,
    /// Algorithm of Table 3.
    pub algorithm: i64,
    /// The system's name.
    pub system: String,
    /// What the model is, in a word ([`model_label`]): `algorithm-5`, `algorithm-5-rates`, ...
    /// (absent in files written before labels: the algorithm's).
    #[serde(default)]
    pub label: String,
}

/// A model's label: `algorithm-<A>`, then `-rates` when it outputs rates directly, `-forces`
/// when trained with a force term, `-beams` with a beam term (what tells the variants of one
/// algorithm apart in file names, tables and a surrogate's routes; not unique by itself).
pub fn model_label(meta: &pino_learn::checkpoint::ModelMeta) -> String {
    let mut label = format!("algorithm-{}", meta.train.algorithm.id());
    if !meta.layout.rate_outputs().is_empty() {
        label.push_str("-rates");
    }
    if meta.train.force_weight() > 0.0 {
        label.push_str("-forces");
    }
    if meta.train.beam_weight > 0.0 {
        label.push_str("-beams");
    }
    label
}

/// How wrong a model was on one quantity over the validation split: what a surrogate chooses
/// the model of each quantity by (`pino-surrogate`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ValidationError {
    /// Validation samples.
    pub n: usize,
    /// Mean relative error (%): an index's `|y - f| / |y|` over the samples with `y != 0`; a
    /// channel's relative L2 error `||y - f|| / ||y||` over its interior points (`None` when no
    /// sample defines it: every exact value zero).
    pub mean_relative_pct: Option<f64>,
    /// Mean absolute error, in the quantity's unit (a channel: over its points too).
    pub mean_abs: f64,
}

impl ModelIdentity {
    /// Its label, the algorithm's for a file written before labels.
    pub fn label(&self) -> String {
        if self.label.is_empty() {
            format!("algorithm-{}", self.algorithm)
        } else {
            self.label.clone()
        }
    }

    /// The identity of the model in `dir` (its `model.json` read for the algorithm and system).
    pub fn of(dir: &Path) -> Result<Self> {
        let mut h = blake3::Hasher::new();
        let mut meta_text = String::new();
        for name in [pino_learn::checkpoint::MODEL_META, MODEL_WEIGHTS] {
            let path = dir.join(name);
            let bytes = std::fs::read(&path).map_err(|e| LearnError::Io {
                path: path.clone(),
                source: e,
            })?;
            if name == pino_learn::checkpoint::MODEL_META {
                meta_text = String::from_utf8_lossy(&bytes).into_owned();
            }
            h.update(name.as_bytes());
            h.update(&(bytes.len() as u64).to_le_bytes());
            h.update(&bytes);
        }
        let meta: pino_learn::checkpoint::ModelMeta =
            serde_json::from_str(&meta_text).map_err(|e| LearnError::Format {
                path: dir.join(pino_learn::checkpoint::MODEL_META),
                message: e.to_string(),
            })?;
        Ok(Self {
            blake3: h.finalize().to_hex().to_string(),
            algorithm: meta.train.algorithm.id(),
            system: meta
                .compile_system(&dir.join(pino_learn::checkpoint::MODEL_META))?
                .name,
            label: model_label(&meta),
        })
    }
}

/// The weights file of a model directory.
pub use pino_data::artifacts::MODEL_WEIGHTS;

/// The dataset design a calibration was drawn from: the description (with its overrides) and
/// the sampling ranges. Calibration samples are exchangeable with new designs only from the
/// same design.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DesignIdentity {
    /// blake3 of the description text and overrides (`mbd_system::SystemSource::hash`).
    pub system_hash: String,
    /// Sampled parameters with their ranges `[min, max]`, description order.
    pub ranges: Vec<(String, [f64; 2])>,
}

/// The scores of one quantity (an index, or a channel's band), for every normaliser.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct QuantityScores {
    /// Column name (`peak_wheel_rail_force_kn`, `z_c`, ...).
    pub name: String,
    /// Unit of the quantity (an interval's ends are in it).
    pub unit: String,
    /// Sorted scores of the calibration samples, per normaliser.
    pub scores: BTreeMap<Normaliser, ScoreSet>,
    /// The error head of this quantity (absent when it could not be fitted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub head: Option<ErrorHead>,
    /// For readers of the file: the quantile of the chosen normaliser's scores at each
    /// reported level (`"0.9": q`), where the calibration supports it.
    pub quantiles: BTreeMap<String, f64>,
    /// The model's error on the validation split (absent in files written before it was
    /// recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation: Option<ValidationError>,
}

/// One channel's band: its scores and its time scale.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelBand {
    /// Scores (dimensionless: multiples of `scale`) and the head.
    #[serde(flatten)]
    pub quantity: QuantityScores,
    /// `scale(t)` at the interior window points (the channel's unit).
    pub scale: Vec<f32>,
}

/// A model's calibration, as `calibration.json` holds it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// [`CALIBRATION_FORMAT`].
    pub format: String,
    /// The model it belongs to.
    pub model: ModelIdentity,
    /// The dataset design its samples were drawn from.
    pub design: DesignIdentity,
    /// Calibration samples scored.
    pub n: usize,
    /// Why the answers carry no interval (no calibration samples, ...); `None` when they do.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_intervals: Option<String>,
    /// The normaliser answers use.
    pub normaliser: Normaliser,
    /// Levels reported in `quantiles`.
    pub levels: Vec<f64>,
    /// What the error heads read, in feature order.
    pub head_inputs: Vec<HeadInput>,
    /// The features of the error heads, in order (the sampled parameters' names for
    /// `parameters`, [`RESIDUAL_FEATURE`] for `residual`).
    pub features: Vec<String>,
    /// `ref_q` of each equation (N, N m) for the relative residual; absent without equations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual_reference: Option<Vec<f64>>,
    /// Samples of the validation split the scales and heads were fitted on.
    pub n_fit: usize,
    /// Per index of the description (value order).
    pub indices: Vec<QuantityScores>,
    /// Per predicted channel (outputs, velocities, accelerations).
    pub channels: Vec<ChannelBand>,
}

fn format_err(path: &Path, message: String) -> crate::Error {
    LearnError::Format {
        path: path.to_owned(),
        message,
    }
    .into()
}

impl Calibration {
    /// Reads a calibration: `path` is a `calibration.json` or a directory holding one (the
    /// `calibrate` stage's output holds one directory per model: the one of `model` is
    /// chosen). Refused, naming the file, when it is missing, corrupt, or of another model.
    pub fn load(path: &Path, model: &ModelIdentity) -> Result<Self> {
        let file = Self::find(path, model)?;
        let text = std::fs::read_to_string(&file).map_err(|e| LearnError::Io {
            path: file.clone(),
            source: e,
        })?;
        let cal: Calibration = serde_json::from_str(&text)
            .map_err(|e| format_err(&file, format!("not a calibration: {e}")))?;
        if cal.format != CALIBRATION_FORMAT {
            return Err(format_err(
                &file,
                format!("format `{}`, expected `{CALIBRATION_FORMAT}`", cal.format),
            ));
        }
        if cal.model.blake3 != model.blake3 {
            return Err(format_err(
                &file,
                format!(
                    "a calibration of another model (algorithm {} of `{}`, blake3 {}), not of this one (algorithm {} of `{}`, blake3 {}): calibrate this model (`pipeline run calibrate`) or give its own calibration",
                    cal.model.algorithm,
                    cal.model.system,
                    short(&cal.model.blake3),
                    model.algorithm,
                    model.system,
                    short(&model.blake3)
                ),
            ));
        }
        cal.check(&file)?;
        Ok(cal)
    }

    /// The calibration file for `model` under `path` (a file, or a directory searched one level
    /// deep for the `calibration.json` of that model).
    pub fn find(path: &Path, model: &ModelIdentity) -> Result<std::path::PathBuf> {
        if !path.is_dir() {
            if !path.exists() {
                return Err(format_err(
                    path,
                    "no such calibration file or directory".into(),
                ));
            }
            return Ok(path.to_owned());
        }
        let direct = path.join(CALIBRATION_FILE);
        if direct.is_file() {
            return Ok(direct);
        }
        let mut candidates = Vec::new();
        let entries = std::fs::read_dir(path).map_err(|e| LearnError::Io {
            path: path.to_owned(),
            source: e,
        })?;
        for entry in entries.flatten() {
            let file = entry.path().join(CALIBRATION_FILE);
            if file.is_file() {
                candidates.push(file);
            }
        }
        candidates.sort();
        for file in &candidates {
            let text = std::fs::read_to_string(file).unwrap_or_default();
            if let Ok(head) = serde_json::from_str::<IdentityOnly>(&text) {
                if head.model.blake3 == model.blake3 {
                    return Ok(file.clone());
                }
            }
        }
        Err(format_err(
            path,
            if candidates.is_empty() {
                format!("holds no {CALIBRATION_FILE}")
            } else {
                format!(
                    "holds {} calibrations ({}), none of this model (algorithm {} of `{}`, blake3 {}): calibrate it (`pipeline run calibrate`)",
                    candidates.len(),
                    candidates
                        .iter()
                        .map(|c| c.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", "),
                    model.algorithm,
                    model.system,
                    short(&model.blake3)
                )
            },
        ))
    }

    /// Consistency of a file read back (hand edits, truncation).
    fn check(&self, file: &Path) -> Result<()> {
        let bad = |m: String| Err(format_err(file, m));
        if self.no_intervals.is_none() {
            for q in self
                .indices
                .iter()
                .chain(self.channels.iter().map(|c| &c.quantity))
            {
                match q.scores.get(&self.normaliser) {
                    Some(s) if s.len() == self.n => {}
                    Some(s) => {
                        return bad(format!(
                            "`{}`: {} scores of normaliser `{}`, the calibration has n = {}",
                            q.name,
                            s.len(),
                            self.normaliser.as_str(),
                            self.n
                        ))
                    }
                    None => {
                        return bad(format!(
                            "`{}`: no scores of its normaliser `{}`",
                            q.name,
                            self.normaliser.as_str()
                        ))
                    }
                }
                if self.normaliser == Normaliser::ErrorHead && q.head.is_none() {
                    return bad(format!("`{}`: no error head", q.name));
                }
            }
            if self.normaliser == Normaliser::Residual && self.residual_reference.is_none() {
                return bad("normaliser `residual` without `residual_reference`".into());
            }
        }
        for c in &self.channels {
            if let Some(bad_scale) = c.scale.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
                return bad(format!(
                    "channel `{}`: scale value {bad_scale} is not > 0",
                    c.quantity.name
                ));
            }
        }
        Ok(())
    }

    /// Whether answers carry intervals.
    pub fn has_intervals(&self) -> bool {
        self.no_intervals.is_none() && self.n > 0
    }

    /// Writes `calibration.json` into `dir` (atomically).
    pub fn write(&self, dir: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(|e| LearnError::Format {
            path: dir.join(CALIBRATION_FILE),
            message: e.to_string(),
        })?;
        Ok(atomic_file::write_atomic(
            &dir.join(CALIBRATION_FILE),
            text.as_bytes(),
        )?)
    }
}

/// The model identity of a calibration file, read without the rest.
#[derive(Deserialize)]
struct IdentityOnly {
    model: ModelIdentity,
}

/// The first 12 digits of a hash, for messages.
pub fn short(hash: &str) -> &str {
    &hash[..hash.len().min(12)]
}
