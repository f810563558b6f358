//! How a study's designs are answered: by the surrogate in batches, each design under its own
//! excitation (generated at the study's seed for its excitation id), with calibrated
//! intervals where the model has a calibration; and a chosen few by the exact solver with the
//! same excitations, timed.

use super::spec::StudyParams;
use crate::predict::{DesignAnswer, GeneratedProfiles, Predictor, ProfileSource};
use crate::solve::{exact, exact_indices};
use crate::surrogate::Surrogate;
use crate::Result;
use mbd_engine::RunConfig;
use pino_indices::IndexConfig;
use rayon::prelude::*;

/// What a study evaluates with: the surrogate, its run controls, the index settings and the
/// profile generators at the study's seed.
pub struct Evaluator<'a> {
    /// The surrogate (its members with their calibrations when they have one).
    pub surrogate: &'a Surrogate,
    /// Its primary member: the system, design space and run controls.
    pub predictor: &'a Predictor,
    /// The model's run controls.
    pub run: RunConfig,
    /// The index settings of a prediction.
    pub cfg: IndexConfig,
    /// The study's shared settings.
    pub params: &'a StudyParams,
    profiles: GeneratedProfiles,
}

/// One design through the solver.
#[derive(Debug, Clone, PartialEq)]
pub struct Solved {
    /// The index values (NaN when the solver refused or failed).
    pub indices: Vec<f64>,
    /// Why it has none.
    pub failure: Option<String>,
}

impl<'a> Evaluator<'a> {
    /// The evaluator of `surrogate` for a study with `params`.
    pub fn new(surrogate: &'a Surrogate, params: &'a StudyParams) -> Result<Self> {
        let predictor = surrogate.primary();
        Ok(Self {
            run: predictor.run_config(None)?,
            cfg: predictor.index_config()?,
            profiles: predictor.profile_generators(params.seed)?,
            surrogate,
            predictor,
            params,
        })
    }

    /// Whether answers carry calibrated intervals.
    pub fn calibrated(&self) -> bool {
        self.surrogate.has_intervals()
    }

    /// The surrogate's answers for `designs`, design `k` under excitation `excitation[k]`.
    pub fn surrogate(&self, designs: &[Vec<f64>], excitation: &[u64]) -> Result<Vec<DesignAnswer>> {
        let of = |k: usize| self.profiles.of(excitation[k]);
        self.surrogate.answers_with(
            designs,
            &ProfileSource::PerDesign(&of),
            &self.run,
            &self.cfg,
            self.params.batch_size,
            self.params.coverage,
        )
    }

    /// The solver's indices of `designs` under `excitation` (side by side on all cores).
    pub fn solver(&self, designs: &[Vec<f64>], excitation: &[u64]) -> Result<Vec<Solved>> {
        designs
            .par_iter()
            .zip(excitation)
            .map(|(d, &e)| {
                let profiles = self.profiles.of(e)?;
                let result = exact(self.predictor, &self.run, d, &profiles, None)
                    .and_then(|x| exact_indices(self.predictor, d, x, &self.cfg));
                let n = self.predictor.index_inputs().columns().len();
                Ok(match result {
                    Ok(ix) => Solved {
                        indices: ix.values,
                        failure: None,
                    },
                    Err(e) => Solved {
                        indices: vec![f64::NAN; n],
                        failure: Some(e.to_string()),
                    },
                })
            })
            .collect()
    }
}

/// `k` designs spread evenly over `n` (`floor(j n / k)`, `j < k`).
pub fn spread(n: usize, k: usize) -> Vec<usize> {
    (0..k.min(n)).map(|j| j * n / k.min(n).max(1)).collect()
}
