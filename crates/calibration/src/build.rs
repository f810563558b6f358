//! Fitting a calibration (the `calibrate` stage): the validation split fixes the channels'
//! time scales, the residual reference levels and the error heads; then the calibration split
//! gives the scores. Nothing of the calibration split is seen before its scores are taken, so
//! they stay exchangeable with new designs of the same dataset design.
//!
//! Per model, three streaming passes (samples predicted in chunks, nothing of a split kept but
//! per-sample numbers): validation (index errors, residuals, each channel's mean absolute
//! error at each time), validation again (each channel's band error against the now fixed
//! scale), calibration (the scores under every normaliser).

use super::answer::Difficulty;
use super::difficulty::{reference_levels, relative_residual};
use super::scored::{band_channels, Named, Run, ScoredSample, Scorer};
use super::{
    Calibration, ChannelBand, DesignIdentity, HeadInput, ModelIdentity, Normaliser, QuantityScores,
    ValidationError, CALIBRATION_FORMAT, REPORTED_LEVELS, RESIDUAL_FEATURE,
};
use crate::Result;
use candle_core::Device;
use pino_conformal::{sup_score, ErrorHead, ScoreSet};
use pino_learn::checkpoint::{load_model, ModelMeta};
use pino_learn::data::{Prepared, Split};
use pino_learn::layout::Layout;
use pino_learn::spectral::Transform;
use pino_learn::Error as LearnError;
use pino_outputs::indices_eval::{IndexInputs, StoredColumns};
use pino_outputs::split::{EvalData, ScoredData};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The `calibrate` stage's settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrateParams {
    /// The normaliser answers use.
    pub normaliser: Normaliser,
    /// What the error heads read (`parameters`, `residual`), in feature order.
    pub head_inputs: Vec<HeadInput>,
    /// Ridge penalty of the error heads (on standardised features).
    pub ridge: f64,
    /// Samples per forward pass.
    pub batch_size: usize,
    /// "cpu" or "cuda".
    #[serde(default = "cpu")]
    pub device: pino_learn::config::DeviceKind,
}

fn cpu() -> pino_learn::config::DeviceKind {
    pino_learn::config::DeviceKind::Cpu
}

impl CalibrateParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<()> {
        if !(self.ridge >= 0.0 && self.ridge.is_finite()) {
            return Err(LearnError::OutOfRange {
                field: "ridge".into(),
                value: self.ridge.to_string(),
                allowed: "a finite number >= 0".into(),
            }
            .into());
        }
        if self.head_inputs.is_empty() {
            return Err(LearnError::OutOfRange {
                field: "head_inputs".into(),
                value: "[]".into(),
                allowed: "a list of `parameters` and/or `residual`".into(),
            }
            .into());
        }
        if self.batch_size == 0 {
            return Err(LearnError::OutOfRange {
                field: "batch_size".into(),
                value: "0".into(),
                allowed: "an integer >= 1".into(),
            }
            .into());
        }
        Ok(())
    }
}

/// Half-width of the moving average smoothing a channel's error profile, as a fraction of
/// the window (1 %: 20 points of a 2000-point window).
pub const SMOOTHING_FRACTION: f64 = 0.01;

/// Floor of a channel's time scale, as a fraction of the median of its smoothed profile: no
/// time point gets a band narrower than this for having been lucky on the validation split.
pub const SCALE_FLOOR_OF_MEDIAN: f64 = 0.1;

/// The directory of one model's calibration in the stage's output: its label
/// ([`ModelIdentity::label`]), with the first 8 digits of its hash when an earlier model of
/// the same run has that label (`taken`).
pub fn model_subdir(identity: &ModelIdentity, taken: &[String]) -> String {
    let label = identity.label();
    if taken.contains(&label) {
        format!(
            "{label}-{}",
            &identity.blake3[..identity.blake3.len().min(8)]
        )
    } else {
        label
    }
}

/// Calibrates every model of `model_dirs` on `data`'s validation and calibration splits and
/// writes `<out>/<label>/calibration.json` for each ([`model_subdir`]; and returns them).
pub fn calibrate(
    data: &EvalData<'_>,
    model_dirs: &[PathBuf],
    out: &Path,
    params: &CalibrateParams,
    device: &Device,
    progress: &mut dyn FnMut(usize, &str),
) -> Result<Vec<Calibration>> {
    params.validate()?;
    let system = &data.info.system;
    let layout = Layout::of(system);
    let inputs = IndexInputs::of(system, &layout)?;
    let transform = Transform::for_device(device);
    let mut done = Vec::new();
    let mut seen: BTreeMap<String, PathBuf> = BTreeMap::new();
    let mut subdirs: Vec<String> = Vec::new();
    for (m, dir) in model_dirs.iter().enumerate() {
        let (model, meta) = load_model(dir, transform, device)?;
        check_model(dir, &meta, data)?;
        // The model's own channels (a model that outputs rates is calibrated on them).
        let model_inputs = IndexInputs::of(system, &meta.layout)?;
        let identity = ModelIdentity::of(dir)?;
        if let Some(other) = seen.insert(identity.blake3.clone(), dir.clone()) {
            return Err(LearnError::OutOfRange {
                field: "models".into(),
                value: format!("{} and {}", other.display(), dir.display()),
                allowed: "each model once (the two hold the same model)".into(),
            }
            .into());
        }
        let load = |split: Split| -> Result<(Prepared, StoredColumns)> {
            let scored = ScoredData::load(data, split, &meta, &inputs)?;
            Ok((scored.items, scored.stored))
        };
        let fit = load(Split::Validation)?;
        let cal = load(Split::Calibration)?;
        let run = Run {
            model: &model,
            meta: &meta,
            batch: params.batch_size,
            device,
        };
        let ctx = Fitting {
            scorer: Scorer::new(system, run, &model_inputs)?,
            params,
        };
        let design = DesignIdentity {
            system_hash: data.info.source.hash(),
            ranges: meta
                .training_ranges
                .names
                .iter()
                .zip(
                    meta.training_ranges
                        .min
                        .iter()
                        .zip(&meta.training_ranges.max),
                )
                .map(|(n, (&lo, &hi))| (n.clone(), [lo, hi]))
                .collect(),
        };
        let calibration =
            ctx.calibration(identity, design, &meta.layout, &model_inputs, &fit, &cal)?;
        let name = model_subdir(&calibration.model, &subdirs);
        let sub = out.join(&name);
        subdirs.push(name);
        std::fs::create_dir_all(&sub).map_err(|e| LearnError::Io {
            path: sub.clone(),
            source: e,
        })?;
        calibration.write(&sub)?;
        progress(
            m + 1,
            &format!(
                "{}: {} calibration samples, normaliser {}",
                calibration.model.label(),
                calibration.n,
                calibration.normaliser.as_str()
            ),
        );
        done.push(calibration);
    }
    Ok(done)
}

/// A model must have been trained on the dataset's description and design.
fn check_model(dir: &Path, meta: &ModelMeta, data: &EvalData<'_>) -> Result<()> {
    let path = dir.join(pino_learn::checkpoint::MODEL_META);
    if meta.system.hash() != data.info.source.hash() || !meta.layout.follows(&data.info.system) {
        return Err(LearnError::Format {
            path,
            message: format!(
                "the model was trained on another system description ({}) than the dataset's ({}): calibrate it on its own dataset",
                meta.system.file, data.info.source.file
            ),
        }.into());
    }
    let ranges = pino_learn::checkpoint::TrainingRanges::of(&data.info.system);
    if ranges.names != meta.training_ranges.names
        || ranges.min != meta.training_ranges.min
        || ranges.max != meta.training_ranges.max
    {
        return Err(LearnError::Format {
            path,
            message: "the model's training ranges differ from the dataset's sampling ranges: its calibration samples would come from another design".into(),
        }.into());
    }
    Ok(())
}

/// One model's fit.
struct Fitting<'a> {
    scorer: Scorer<'a>,
    params: &'a CalibrateParams,
}

/// Column `j` of per-sample rows.
fn column(rows: &[Vec<f64>], j: usize) -> Vec<f64> {
    rows.iter().map(|r| r[j]).collect()
}

/// Per-sample numbers of a split: index errors, channel band errors, difficulty.
#[derive(Default)]
struct SplitErrors {
    params: Vec<Vec<f64>>,
    /// `|y - f|` per sample and index.
    index: Vec<Vec<f64>>,
    /// `|y - f| / |y|` per sample and index (NaN where `y = 0`).
    index_rel: Vec<Vec<f64>>,
    /// `max_t |y - f| / scale(t)` per sample and channel.
    channel: Vec<Vec<f64>>,
    /// Per sample and channel: `||y - f|| / ||y||` and the mean of `|y - f|` over the points.
    channel_rel: Vec<Vec<[f64; 2]>>,
    /// `rms_q` per sample, when the model has equations.
    rms: Vec<Vec<f64>>,
}

impl SplitErrors {
    fn add(&mut self, s: &ScoredSample, scales: &[Vec<f64>]) -> Result<()> {
        self.params.push(s.params.clone());
        let pairs = || s.predicted_indices.iter().zip(&s.exact_indices);
        self.index
            .push(pairs().map(|(f, y)| (y - f).abs()).collect());
        self.index_rel.push(
            pairs()
                .map(|(f, y)| {
                    if *y == 0.0 {
                        f64::NAN
                    } else {
                        ((y - f) / y).abs()
                    }
                })
                .collect(),
        );
        let mut channel = Vec::with_capacity(scales.len());
        let mut channel_rel = Vec::with_capacity(scales.len());
        for ((p, x), sc) in s.predicted.iter().zip(&s.exact).zip(scales) {
            channel.push(sup_score(p, x, sc).map_err(|e| LearnError::Dataset {
                path: PathBuf::from("calibrate"),
                message: format!("sample {}: {e}", s.id),
            })?);
            let (mut err2, mut norm2, mut abs) = (0.0, 0.0, 0.0);
            for (p, x) in p.iter().zip(x) {
                err2 += (x - p) * (x - p);
                norm2 += x * x;
                abs += (x - p).abs();
            }
            let rel = if norm2 > 0.0 {
                (err2 / norm2).sqrt()
            } else {
                f64::NAN
            };
            channel_rel.push([rel, abs / p.len().max(1) as f64]);
        }
        self.channel.push(channel);
        self.channel_rel.push(channel_rel);
        if let Some(r) = &s.residual_rms {
            self.rms.push(r.clone());
        }
        Ok(())
    }

    fn len(&self) -> usize {
        self.params.len()
    }

    /// Index `j`'s error over the split.
    fn index_validation(&self, j: usize) -> ValidationError {
        validation_error(
            self.len(),
            &column(&self.index_rel, j),
            &column(&self.index, j),
        )
    }

    /// Channel `c`'s error over the split.
    fn channel_validation(&self, c: usize) -> ValidationError {
        let of = |k: usize| -> Vec<f64> { self.channel_rel.iter().map(|r| r[c][k]).collect() };
        validation_error(self.len(), &of(0), &of(1))
    }
}

/// The summary of per-sample relative (NaN: undefined, left out) and absolute errors.
fn validation_error(n: usize, relative: &[f64], abs: &[f64]) -> ValidationError {
    let defined: Vec<f64> = relative.iter().copied().filter(|v| v.is_finite()).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    ValidationError {
        n,
        mean_relative_pct: (!defined.is_empty()).then(|| 100.0 * mean(&defined)),
        mean_abs: mean(abs),
    }
}

/// The names and units of the description's indices (none when they cannot be computed).
fn index_names(inputs: &IndexInputs) -> Vec<Named> {
    if !inputs.computable() {
        return Vec::new();
    }
    inputs
        .columns()
        .iter()
        .map(|c| Named {
            name: c.name.clone(),
            unit: c.unit.clone(),
        })
        .collect()
}

/// Every quantity with its validation error and no score (a dataset without a calibration
/// split: no interval is claimed).
fn unscored_quantities(
    calibration: &mut Calibration,
    index_names: &[Named],
    channels: &[Named],
    val: &SplitErrors,
    scales: &[Vec<f64>],
) {
    let unscored = |name: &Named, validation| QuantityScores {
        name: name.name.clone(),
        unit: name.unit.clone(),
        scores: BTreeMap::new(),
        head: None,
        quantiles: BTreeMap::new(),
        validation: Some(validation),
    };
    calibration.indices = (index_names.iter().enumerate())
        .map(|(j, name)| unscored(name, val.index_validation(j)))
        .collect();
    calibration.channels = (channels.iter().enumerate())
        .map(|(c, name)| ChannelBand {
            quantity: unscored(name, val.channel_validation(c)),
            scale: scales[c].iter().map(|&v| v as f32).collect(),
        })
        .collect();
}

impl Fitting<'_> {
    fn each(
        &self,
        (items, stored): &(Prepared, StoredColumns),
        f: &mut dyn FnMut(&ScoredSample) -> Result<()>,
    ) -> Result<()> {
        let idx: Vec<usize> = (0..items.len()).collect();
        self.scorer.for_each(items, &idx, stored, f)
    }

    fn calibration(
        &self,
        model: ModelIdentity,
        design: DesignIdentity,
        layout: &Layout,
        inputs: &IndexInputs,
        fit: &(Prepared, StoredColumns),
        cal: &(Prepared, StoredColumns),
    ) -> Result<Calibration> {
        let channels = band_channels(layout);
        let index_names = index_names(inputs);
        let features = self.head_features(&design);
        let mut calibration = Calibration {
            format: CALIBRATION_FORMAT.into(),
            model,
            design,
            n: cal.0.len(),
            no_intervals: None,
            normaliser: self.params.normaliser,
            levels: REPORTED_LEVELS.to_vec(),
            head_inputs: self.params.head_inputs.clone(),
            features,
            residual_reference: None,
            n_fit: fit.0.len(),
            indices: Vec::new(),
            channels: Vec::new(),
        };
        self.check_fitting(fit)?;
        // Pass 1: each channel's time scale over the validation split.
        let scales = self.time_scales(fit)?;
        // Pass 2: the validation errors against the fixed scales.
        let mut val = SplitErrors::default();
        self.each(fit, &mut |s| val.add(s, &scales))?;
        if cal.0.is_empty() {
            calibration.no_intervals = Some(
                "the dataset has no calibration split (sample-params.n_calibration = 0): answers carry no interval and no coverage is claimed".into(),
            );
            unscored_quantities(&mut calibration, &index_names, &channels, &val, &scales);
            return Ok(calibration);
        }
        let named = (index_names.as_slice(), channels.as_slice());
        self.scored_quantities(&mut calibration, named, &val, &scales, cal)?;
        Ok(calibration)
    }

    /// Refuses a fitting split without samples, and a residual normaliser for a model without
    /// equations.
    fn check_fitting(&self, fit: &(Prepared, StoredColumns)) -> Result<()> {
        if fit.0.is_empty() {
            return Err(LearnError::Dataset {
                path: PathBuf::from("calibrate"),
                message: "no simulated sample of split `validation`: the bands' time scales and the error heads are fitted on it".into(),
            }.into());
        }
        if self.params.normaliser == Normaliser::Residual && !self.scorer.has_residual() {
            return Err(LearnError::OutOfRange {
                field: "normaliser".into(),
                value: "residual".into(),
                allowed: "`none` or `error_head`: no DOF of this model has an equation with its outputs, so its predictions have no physics residual".into(),
            }.into());
        }
        Ok(())
    }

    /// Pass 3: the calibration split's errors, each quantity's scores against its difficulty
    /// (the residual reference and the error heads from the validation split `val`).
    fn scored_quantities(
        &self,
        calibration: &mut Calibration,
        (index_names, channels): (&[Named], &[Named]),
        val: &SplitErrors,
        scales: &[Vec<f64>],
        cal: &(Prepared, StoredColumns),
    ) -> Result<()> {
        let reference = (!val.rms.is_empty()).then(|| reference_levels(&val.rms));
        calibration.residual_reference = reference.clone();
        let g_of = |rms: &[Vec<f64>], k: usize| -> Option<f64> {
            reference.as_ref().map(|r| relative_residual(&rms[k], r))
        };
        let val_difficulty: Vec<_> = (0..val.len())
            .map(|k| calibration.difficulty_of(&val.params[k], g_of(&val.rms, k)))
            .collect();
        let mut calib = SplitErrors::default();
        self.each(cal, &mut |s| calib.add(s, scales))?;
        let cal_difficulty: Vec<_> = (0..calib.len())
            .map(|k| calibration.difficulty_of(&calib.params[k], g_of(&calib.rms, k)))
            .collect();
        let feats: Vec<Vec<f64>> = val_difficulty.iter().map(|d| d.features.clone()).collect();
        let quantity = |name: &Named, val_err: Vec<f64>, errors: Vec<f64>, summary| {
            let errors = QuantityErrors {
                validation: val_err,
                calibration: errors,
            };
            let mut q = self.quantity_scores(calibration, name, &feats, &cal_difficulty, errors)?;
            q.validation = Some(summary);
            Ok::<_, crate::Error>(q)
        };
        let mut indices = Vec::with_capacity(index_names.len());
        for (j, name) in index_names.iter().enumerate() {
            indices.push(quantity(
                name,
                column(&val.index, j),
                column(&calib.index, j),
                val.index_validation(j),
            )?);
        }
        let mut bands = Vec::with_capacity(channels.len());
        for (c, name) in channels.iter().enumerate() {
            bands.push(ChannelBand {
                quantity: quantity(
                    name,
                    column(&val.channel, c),
                    column(&calib.channel, c),
                    val.channel_validation(c),
                )?,
                scale: scales[c].iter().map(|&v| v as f32).collect(),
            });
        }
        calibration.indices = indices;
        calibration.channels = bands;
        Ok(())
    }

    /// The error heads' input features: the design's parameters and the residual, as the
    /// stage's `head_inputs` ask (the residual only where the model has one).
    fn head_features(&self, design: &DesignIdentity) -> Vec<String> {
        let mut features: Vec<String> = Vec::new();
        for input in &self.params.head_inputs {
            match input {
                HeadInput::Parameters => {
                    features.extend(design.ranges.iter().map(|(n, _)| n.clone()))
                }
                HeadInput::Residual if self.scorer.has_residual() => {
                    features.push(RESIDUAL_FEATURE.into())
                }
                HeadInput::Residual => {}
            }
        }
        features
    }

    /// Each channel's time scale: its mean absolute error at each time over the fitting split,
    /// smoothed ([`time_scale`]) and rounded to f32 as it is stored.
    fn time_scales(&self, fit: &(Prepared, StoredColumns)) -> Result<Vec<Vec<f64>>> {
        let mut sums: Vec<Vec<f64>> = Vec::new();
        self.each(fit, &mut |s| {
            if sums.is_empty() {
                sums = s.predicted.iter().map(|c| vec![0.0; c.len()]).collect();
            }
            for ((acc, p), x) in sums.iter_mut().zip(&s.predicted).zip(&s.exact) {
                for ((a, p), x) in acc.iter_mut().zip(p).zip(x) {
                    *a += (x - p).abs();
                }
            }
            Ok(())
        })?;
        let n_fit = fit.0.len() as f64;
        Ok(sums
            .iter()
            .map(|s| time_scale(&s.iter().map(|v| v / n_fit).collect::<Vec<_>>()))
            .map(|s| s.into_iter().map(|v| v as f32 as f64).collect())
            .collect())
    }

    /// One quantity's conformal scores under every normaliser that applies, its error head
    /// (fitted on the validation errors against `feats`) and the chosen normaliser's
    /// quantiles at the reported levels.
    fn quantity_scores(
        &self,
        calibration: &Calibration,
        name: &Named,
        feats: &[Vec<f64>],
        cal_difficulty: &[Difficulty],
        errors: QuantityErrors,
    ) -> Result<QuantityScores> {
        let head = match ErrorHead::fit(feats, &errors.validation, self.params.ridge) {
            Ok(h) => Some(h),
            Err(e) if self.params.normaliser == Normaliser::ErrorHead => {
                return Err(LearnError::OutOfRange {
                    field: format!("normaliser (`{}`)", name.name),
                    value: "error_head".into(),
                    allowed: format!("an error head fitted on the validation split: {e}"),
                }
                .into())
            }
            Err(_) => None,
        };
        let mut q = QuantityScores {
            name: name.name.clone(),
            unit: name.unit.clone(),
            scores: BTreeMap::new(),
            head,
            quantiles: BTreeMap::new(),
            validation: None,
        };
        for normaliser in Normaliser::ALL {
            let sigmas: Result<Vec<f64>> = cal_difficulty
                .iter()
                .map(|d| calibration.sigma(normaliser, &q, d))
                .collect();
            let Ok(sigmas) = sigmas else { continue };
            let scores = errors
                .calibration
                .iter()
                .zip(&sigmas)
                .map(|(e, s)| e / s)
                .collect();
            let set = ScoreSet::new(scores).map_err(|e| LearnError::Dataset {
                path: PathBuf::from("calibrate"),
                message: format!("`{}` ({}): {e}", name.name, normaliser.as_str()),
            })?;
            q.scores.insert(normaliser, set);
        }
        if let Some(chosen) = q.scores.get(&calibration.normaliser) {
            for level in REPORTED_LEVELS {
                if let Ok(v) = chosen.quantile(level) {
                    q.quantiles.insert(level.to_string(), v);
                }
            }
        }
        Ok(q)
    }
}

/// One quantity's errors, per sample: on the validation split (the error head's targets) and
/// on the calibration split (the conformal scores' numerators).
struct QuantityErrors {
    validation: Vec<f64>,
    calibration: Vec<f64>,
}

/// A channel's time scale from its mean absolute error profile: a centred moving average of
/// half-width [`SMOOTHING_FRACTION`] of the window, floored at [`SCALE_FLOOR_OF_MEDIAN`] of
/// its median (1 where the profile is zero: a channel predicted exactly).
pub fn time_scale(mean_abs: &[f64]) -> Vec<f64> {
    let n = mean_abs.len();
    if n == 0 {
        return Vec::new();
    }
    let h = ((SMOOTHING_FRACTION * n as f64).round() as usize).max(1);
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    for v in mean_abs {
        prefix.push(prefix.last().copied().unwrap_or(0.0) + v);
    }
    let smooth: Vec<f64> = (0..n)
        .map(|t| {
            let (a, b) = (t.saturating_sub(h), (t + h + 1).min(n));
            (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect();
    let mut sorted = smooth.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[n / 2];
    let floor = if median > 0.0 && median.is_finite() {
        SCALE_FLOOR_OF_MEDIAN * median
    } else {
        1.0
    };
    smooth.into_iter().map(|v| v.max(floor)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_time_scale_is_smoothed_and_floored() {
        let mut profile = vec![1.0; 200];
        profile[100] = 101.0;
        let s = time_scale(&profile);
        // Half-width 2 (1 % of 200): the spike spreads over 5 points.
        assert!((s[100] - 21.0).abs() < 1e-12 && (s[98] - 21.0).abs() < 1e-12);
        assert_eq!(s[97], 1.0);
        let mut dips = vec![1.0; 200];
        for v in dips.iter_mut().take(50) {
            *v = 0.0;
        }
        assert!(time_scale(&dips).iter().all(|&v| v >= 0.1));
        assert!(time_scale(&[0.0; 10]).iter().all(|&v| v == 1.0));
    }
}
