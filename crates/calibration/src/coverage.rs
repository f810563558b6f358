//! How a calibration holds on the test split (`evaluate`): per quantity, normaliser and level,
//! the empirical coverage (the fraction of test samples whose solver answer lies inside the
//! interval, or whose whole curve lies inside the band) and the mean width, in the quantity's
//! unit and as a fraction of the quantity's standard deviation over the test split (a band as
//! wide as the data's spread says nothing). And the conditional coverage at the default level
//! for the calibration's own normaliser: in three bins of difficulty and in the bottom and top
//! quartile of each sampled parameter (where the marginal guarantee may not hold per region).

use super::answer::Difficulty;
use super::difficulty::relative_residual;
use super::scored::ScoredSample;
use super::{Calibration, Normaliser, QuantityScores, DEFAULT_COVERAGE, REPORTED_LEVELS};
use crate::Result;

/// One row of the coverage table.
#[derive(Debug, Clone, PartialEq)]
pub struct CoverageRow {
    /// Algorithm of the model.
    pub algorithm: i64,
    /// `index` or `channel`.
    pub kind: &'static str,
    /// Quantity name.
    pub quantity: String,
    /// Its unit.
    pub unit: String,
    /// The normaliser.
    pub normaliser: Normaliser,
    /// Whether it is the calibration's own (the one answers use).
    pub chosen: bool,
    /// The nominal coverage.
    pub level: f64,
    /// Calibration samples.
    pub n_calibration: usize,
    /// Test samples.
    pub n_test: usize,
    /// Empirical coverage on the test split.
    pub coverage: f64,
    /// Mean width of the interval (of the band, over its points), in `unit`.
    pub mean_width: f64,
    /// `mean_width` over the standard deviation of the quantity over the test split.
    pub width_over_std: f64,
}

/// One row of the conditional coverage table.
#[derive(Debug, Clone, PartialEq)]
pub struct ConditionalRow {
    /// Algorithm of the model.
    pub algorithm: i64,
    /// `index` or `channel`.
    pub kind: &'static str,
    /// Quantity name.
    pub quantity: String,
    /// What the samples are grouped by: `difficulty` or a parameter's name.
    pub group: String,
    /// The bin: `low`, `middle`, `high` (terciles of sigma) or `bottom quartile`,
    /// `top quartile`.
    pub bin: &'static str,
    /// Test samples in the bin.
    pub n: usize,
    /// Their coverage at [`DEFAULT_COVERAGE`].
    pub coverage: f64,
}

/// Per quantity, over the test samples: the error (index: `|y - f|`; channel: the band
/// score `max_t |y - f| / scale(t)`) and the exact values' moments.
struct Quantity<'a> {
    kind: &'static str,
    scores: &'a QuantityScores,
    errors: Vec<f64>,
    /// Mean of the band's scale (1 for an index).
    scale_mean: f64,
    /// Sum, sum of squares and count of the exact values.
    moments: [f64; 3],
}

impl Quantity<'_> {
    /// Population standard deviation of the exact values.
    fn std(&self) -> f64 {
        let [s, s2, n] = self.moments;
        let n = n.max(1.0);
        (s2 / n - (s / n).powi(2)).max(0.0).sqrt()
    }
}

/// The test samples of one model reduced, one at a time, to what the coverage tables need
/// (bounded memory on any split size).
pub struct CoverageAccumulator<'a> {
    calibration: &'a Calibration,
    quantities: Vec<Quantity<'a>>,
    scales: Vec<Vec<f64>>,
    params: Vec<Vec<f64>>,
    difficulty: Vec<Difficulty>,
}

impl<'a> CoverageAccumulator<'a> {
    /// An empty accumulator for `calibration`.
    pub fn new(calibration: &'a Calibration) -> Self {
        let index = calibration.indices.iter().map(|q| Quantity {
            kind: "index",
            scores: q,
            errors: Vec::new(),
            scale_mean: 1.0,
            moments: [0.0; 3],
        });
        let channel = calibration.channels.iter().map(|b| Quantity {
            kind: "channel",
            scores: &b.quantity,
            errors: Vec::new(),
            scale_mean: b.scale.iter().map(|&v| v as f64).sum::<f64>()
                / b.scale.len().max(1) as f64,
            moments: [0.0; 3],
        });
        Self {
            calibration,
            quantities: index.chain(channel).collect(),
            scales: calibration
                .channels
                .iter()
                .map(|b| b.scale.iter().map(|&v| v as f64).collect())
                .collect(),
            params: Vec::new(),
            difficulty: Vec::new(),
        }
    }

    /// Adds one scored test sample.
    pub fn add(&mut self, s: &ScoredSample) -> Result<()> {
        let cal = self.calibration;
        let g = match (&cal.residual_reference, &s.residual_rms) {
            (Some(r), Some(rms)) => Some(relative_residual(rms, r)),
            _ => None,
        };
        self.difficulty.push(cal.difficulty_of(&s.params, g));
        self.params.push(s.params.clone());
        let n_index = cal.indices.len();
        for (j, q) in self.quantities.iter_mut().enumerate() {
            if j < n_index {
                let (y, f) = (s.exact_indices[j], s.predicted_indices[j]);
                q.errors.push((y - f).abs());
                q.moments[0] += y;
                q.moments[1] += y * y;
                q.moments[2] += 1.0;
            } else {
                let c = j - n_index;
                let score =
                    pino_conformal::sup_score(&s.predicted[c], &s.exact[c], &self.scales[c])
                        .map_err(|e| pino_learn::Error::Dataset {
                            path: "evaluate".into(),
                            message: format!("sample {}: `{}`: {e}", s.id, q.scores.name),
                        })?;
                q.errors.push(score);
                for x in &s.exact[c] {
                    q.moments[0] += x;
                    q.moments[1] += x * x;
                    q.moments[2] += 1.0;
                }
            }
        }
        Ok(())
    }

    /// The coverage rows and the conditional rows.
    pub fn finish(self) -> Result<(Vec<CoverageRow>, Vec<ConditionalRow>)> {
        let calibration = self.calibration;
        if !calibration.has_intervals() || self.params.is_empty() {
            return Ok((Vec::new(), Vec::new()));
        }
        let algorithm = calibration.model.algorithm;
        let mut rows = Vec::new();
        let mut conditional = Vec::new();
        for q in &self.quantities {
            let std = q.std();
            for normaliser in Normaliser::ALL {
                let Some(set) = q.scores.scores.get(&normaliser) else {
                    continue;
                };
                let sigmas: Vec<f64> = self
                    .difficulty
                    .iter()
                    .map(|d| calibration.sigma(normaliser, q.scores, d))
                    .collect::<Result<_>>()?;
                for level in REPORTED_LEVELS {
                    let Ok(qv) = set.quantile(level) else {
                        continue;
                    };
                    let inside: Vec<bool> = q
                        .errors
                        .iter()
                        .zip(&sigmas)
                        .map(|(e, s)| *e <= qv * s)
                        .collect();
                    let n = inside.len() as f64;
                    let mean_width = 2.0 * qv * q.scale_mean * sigmas.iter().sum::<f64>() / n;
                    rows.push(CoverageRow {
                        algorithm,
                        kind: q.kind,
                        quantity: q.scores.name.clone(),
                        unit: q.scores.unit.clone(),
                        normaliser,
                        chosen: normaliser == calibration.normaliser,
                        level,
                        n_calibration: calibration.n,
                        n_test: inside.len(),
                        coverage: inside.iter().filter(|&&b| b).count() as f64 / n,
                        mean_width,
                        width_over_std: if std > 0.0 {
                            mean_width / std
                        } else {
                            f64::NAN
                        },
                    });
                    if normaliser == calibration.normaliser && level == DEFAULT_COVERAGE {
                        conditional.extend(conditional_rows(
                            algorithm,
                            q,
                            calibration,
                            &self.params,
                            &self.difficulty,
                            &sigmas,
                            &inside,
                        ));
                    }
                }
            }
        }
        Ok((rows, conditional))
    }
}

/// Coverage in terciles of sigma (of `g` under the plain normaliser, when there is one) and
/// in the bottom and top quartile of each sampled parameter.
fn conditional_rows(
    algorithm: i64,
    q: &Quantity<'_>,
    calibration: &Calibration,
    params: &[Vec<f64>],
    difficulty: &[Difficulty],
    sigmas: &[f64],
    inside: &[bool],
) -> Vec<ConditionalRow> {
    let mut out = Vec::new();
    let mut push = |group: String, bin: &'static str, members: Vec<usize>| {
        if members.is_empty() {
            return;
        }
        let hit = members.iter().filter(|&&k| inside[k]).count();
        out.push(ConditionalRow {
            algorithm,
            kind: q.kind,
            quantity: q.scores.name.clone(),
            group,
            bin,
            n: members.len(),
            coverage: hit as f64 / members.len() as f64,
        });
    };
    let n = params.len();
    let by = |key: &dyn Fn(usize) -> f64| -> Vec<usize> {
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
        order
    };
    let bins: Option<Vec<f64>> = if calibration.normaliser == Normaliser::None {
        difficulty.iter().map(|d| d.relative_residual).collect()
    } else {
        Some(sigmas.to_vec())
    };
    if let Some(d) = bins {
        let order = by(&|k| d[k]);
        for (b, bin) in ["low", "middle", "high"].into_iter().enumerate() {
            push(
                "difficulty".into(),
                bin,
                order[b * n / 3..(b + 1) * n / 3].to_vec(),
            );
        }
    }
    for (p, (name, _)) in calibration.design.ranges.iter().enumerate() {
        let order = by(&|k| params[k][p]);
        let quarter = n / 4;
        push(name.clone(), "bottom quartile", order[..quarter].to_vec());
        push(name.clone(), "top quartile", order[n - quarter..].to_vec());
    }
    out
}

/// The coverage of `calibration` on the prepared samples `items` (with their `stored` index
/// columns) through the model of `run`.
pub fn split_coverage(
    system: &mbd_system::System,
    run: super::scored::Run<'_>,
    inputs: &pino_outputs::indices_eval::IndexInputs,
    items: &pino_learn::data::Prepared,
    stored: &pino_outputs::indices_eval::StoredColumns,
    calibration: &Calibration,
) -> Result<(Vec<CoverageRow>, Vec<ConditionalRow>)> {
    let scorer = super::scored::Scorer::new(system, run, inputs)?;
    let mut acc = CoverageAccumulator::new(calibration);
    let idx: Vec<usize> = (0..items.len()).collect();
    if calibration.has_intervals() {
        scorer.for_each(items, &idx, stored, &mut |s| acc.add(s))?;
    }
    acc.finish()
}
