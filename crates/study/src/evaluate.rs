//! How a study's designs are answered: by the surrogate in batches, each design under its own
//! excitation (generated at the study's seed for its excitation id), with calibrated
//! intervals where the model has a calibration; and a chosen few by the exact solver with the
//! same excitations, timed. With a [`Progress`] the designs are answered in slices, each
//! counted as it ends, and a cancelled study stops at the next slice (or solve).

use super::spec::StudyParams;
use crate::Result;
use mbd_engine::RunConfig;
use pino_indices::IndexConfig;
use pino_predict::solve::{exact, exact_indices};
use pino_predict::{DesignAnswer, GeneratedProfiles, Predictor, ProfileSource};
use pino_surrogate::Surrogate;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// What a running study reports and obeys: the designs answered by the surrogate and by the
/// solver, of those asked for so far, and a request to stop. Shared with whoever watches the
/// study (the explorer's Studies page).
#[derive(Debug, Default)]
pub struct Progress {
    surrogate_done: AtomicUsize,
    surrogate_total: AtomicUsize,
    solver_done: AtomicUsize,
    solver_total: AtomicUsize,
    cancel: AtomicBool,
}

impl Progress {
    /// Asks the study to stop: it ends with [`crate::Error::Cancelled`] at its next slice of
    /// designs, and a solve in flight stops at its next step.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::SeqCst);
    }

    /// Whether the study was asked to stop.
    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::SeqCst)
    }

    /// Designs answered by the surrogate, and asked for so far.
    pub fn surrogate(&self) -> (usize, usize) {
        (
            self.surrogate_done.load(Ordering::SeqCst),
            self.surrogate_total.load(Ordering::SeqCst),
        )
    }

    /// Designs answered by the solver, and asked for so far.
    pub fn solver(&self) -> (usize, usize) {
        (
            self.solver_done.load(Ordering::SeqCst),
            self.solver_total.load(Ordering::SeqCst),
        )
    }

    fn go_on(&self) -> Result<()> {
        if self.cancelled() {
            return Err(crate::Error::Cancelled);
        }
        Ok(())
    }
}

/// Batches of a slice of the surrogate's designs, per thread of the pool: small enough that
/// the progress moves and a cancel is heard within a second or two, large enough to keep
/// every thread busy.
const SLICE_BATCHES_PER_THREAD: usize = 4;

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
    progress: Option<&'a Progress>,
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
            progress: None,
        })
    }

    /// This evaluator counting its designs in `progress` and stopping when it is cancelled.
    pub fn with_progress(mut self, progress: &'a Progress) -> Self {
        self.progress = Some(progress);
        self
    }

    /// Whether answers carry calibrated intervals.
    pub fn calibrated(&self) -> bool {
        self.surrogate.has_intervals()
    }

    /// The surrogate's answers for `designs`, design `k` under excitation `excitation[k]`.
    /// With a [`Progress`], in slices of whole batches (the same batches, so the same
    /// answers, as one call), each counted as it ends.
    pub fn surrogate(&self, designs: &[Vec<f64>], excitation: &[u64]) -> Result<Vec<DesignAnswer>> {
        let Some(progress) = self.progress else {
            return self.surrogate_slice(designs, excitation, 0);
        };
        progress
            .surrogate_total
            .fetch_add(designs.len(), Ordering::SeqCst);
        let slice = self.params.batch_size.max(1)
            * SLICE_BATCHES_PER_THREAD
            * rayon::current_num_threads().max(1);
        let mut answers = Vec::with_capacity(designs.len());
        for start in (0..designs.len()).step_by(slice) {
            progress.go_on()?;
            let end = (start + slice).min(designs.len());
            answers.extend(self.surrogate_slice(
                &designs[start..end],
                &excitation[start..end],
                start,
            )?);
            progress
                .surrogate_done
                .fetch_add(end - start, Ordering::SeqCst);
        }
        Ok(answers)
    }

    /// The surrogate's answers of the designs `first..` of a study (`designs`, under
    /// `excitation`).
    fn surrogate_slice(
        &self,
        designs: &[Vec<f64>],
        excitation: &[u64],
        first: usize,
    ) -> Result<Vec<DesignAnswer>> {
        let of = |k: usize| self.profiles.of(excitation[k]);
        self.surrogate
            .answers(
                designs,
                &ProfileSource::PerDesign(&of),
                &self.run,
                &self.cfg,
                self.params.batch_size,
                self.params.coverage,
            )
            .map_err(|e| shifted(e, first))
    }

    /// The solver's indices of `designs` under `excitation` (side by side on all cores).
    pub fn solver(&self, designs: &[Vec<f64>], excitation: &[u64]) -> Result<Vec<Solved>> {
        let cancel = self.progress.map(|p| &p.cancel);
        if let Some(p) = self.progress {
            p.go_on()?;
            p.solver_total.fetch_add(designs.len(), Ordering::SeqCst);
        }
        let solved = designs
            .par_iter()
            .zip(excitation)
            .map(|(d, &e)| {
                let profiles = self.profiles.of(e)?;
                let result = exact(self.predictor, &self.run, d, &profiles, cancel)
                    .and_then(|x| exact_indices(self.predictor, d, x, &self.cfg));
                let n = self.predictor.index_inputs().columns().len();
                if let Some(p) = self.progress {
                    p.solver_done.fetch_add(1, Ordering::SeqCst);
                }
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
            .collect::<Result<Vec<_>>>()?;
        if let Some(p) = self.progress {
            p.go_on()?;
        }
        Ok(solved)
    }
}

/// An error of design `k` of a slice (`sets[k]...`) named as design `first + k` of the study.
fn shifted(e: crate::Error, first: usize) -> crate::Error {
    let crate::Error::Learn(pino_learn::Error::OutOfRange {
        field,
        value,
        allowed,
    }) = e
    else {
        return e;
    };
    let renamed = field
        .strip_prefix("sets[")
        .and_then(|rest| rest.split_once(']'))
        .and_then(|(k, tail)| Some(format!("sets[{}]{tail}", k.parse::<usize>().ok()? + first)));
    pino_learn::Error::OutOfRange {
        field: renamed.unwrap_or(field),
        value,
        allowed,
    }
    .into()
}

/// `k` designs spread evenly over `n` (`floor(j n / k)`, `j < k`).
pub fn spread(n: usize, k: usize) -> Vec<usize> {
    (0..k.min(n)).map(|j| j * n / k.min(n).max(1)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slice_names_its_designs_as_the_study_does_and_a_cancel_stops_it() {
        let e = shifted(
            pino_learn::Error::OutOfRange {
                field: "sets[3].v_kmh".into(),
                value: "5000".into(),
                allowed: "at most 573".into(),
            }
            .into(),
            64,
        );
        assert!(
            e.to_string().contains("sets[67].v_kmh"),
            "design 3 of the slice from 64 is the study's 67: {e}"
        );
        let other = shifted(crate::Error::Cancelled, 64);
        assert!(matches!(other, crate::Error::Cancelled));
        let p = Progress::default();
        assert!(p.go_on().is_ok());
        assert_eq!((p.surrogate(), p.solver()), ((0, 0), (0, 0)));
        p.cancel();
        assert!(p.cancelled() && matches!(p.go_on(), Err(crate::Error::Cancelled)));
    }
}
