//! Design studies through a trained model (`docs/studies.md`): many designs, each under its
//! own excitation, answered by the surrogate with calibrated intervals where the model has a
//! calibration, and a sample of them answered by the exact solver beside it.
//!
//! A study is declared as one value of the `study` stage's matrix: a mapping with `name`,
//! `kind` (`monte_carlo`, `sensitivity`, `optimise`, `critical_speed`), `parameters` (distributions by name;
//! every sampled parameter not named is uniform over the model's training range) and
//! `solver_check` (how many designs also run through the solver). The estimators are
//! `pino-studies`'; this module draws the designs, evaluates them and writes the tables.
//!
//! Every random draw is keyed by (the study's seed, purpose, design id): parameter draws by
//! [`mbd_dataset::Purpose::StudyDesigns`], the excitation of design `i` is the profile the
//! `irregularity` stage would generate for sample `i` at the study's seed.
//!
//! - [`spec`]: a study's declaration, parsed and checked against the model.
//! - [`evaluate`]: designs answered by the surrogate and, for a sample, by the solver.
//! - [`monte_carlo`], [`sensitivity`], [`optimise`], [`critical_speed`]: the four kinds of
//!   study.
//! - [`output`]: their tables, Markdown summaries and plots.
//!
//! This crate is the wiring of a model into the studies; `pino-studies` holds the estimators
//! and stays free of any model (it does not depend on the learning engine).
#![warn(missing_docs)]

pub mod critical_speed;
pub mod evaluate;
pub mod monte_carlo;
pub mod optimise;
pub mod output;
pub mod sensitivity;
pub mod spec;

pub use evaluate::Progress;
pub use spec::{Study, StudyKind, StudyParams};

/// The `source` values of a study's tables: which side answered.
pub mod source {
    /// The surrogate on every design of the study.
    pub const SURROGATE: &str = "surrogate";
    /// The surrogate on the designs the solver also answered (Monte Carlo).
    pub const SURROGATE_CHECKED: &str = "surrogate_checked";
    /// The surrogate on the solver's rows of a sensitivity design.
    pub const SURROGATE_REDUCED: &str = "surrogate_reduced";
    /// The exact solver.
    pub const SOLVER: &str = "solver";
}

use candle_core::Device;
use mbd_system::System;
use pino_learn::layout::Layout;
use pino_learn::Error as LearnError;
use pino_outputs::indices_eval::IndexInputs;
pub use pino_outputs::{Error, Result};
use pino_predict::Predictor;
use pino_surrogate::Surrogate;
use std::path::{Path, PathBuf};

/// The sampled parameters of `system` with their sampling ranges (description order).
pub fn description_parameters(system: &System) -> Vec<(String, [f64; 2])> {
    system
        .sampled_names()
        .into_iter()
        .map(str::to_owned)
        .zip(system.ranges())
        .collect()
}

/// The model's sampled parameters with their training ranges (its parameter order).
pub fn model_parameters(predictor: &Predictor) -> Vec<(String, [f64; 2])> {
    let r = &predictor.meta.training_ranges;
    predictor
        .space
        .names()
        .iter()
        .map(|n| {
            let k = r.names.iter().position(|x| x == n);
            let range = k.map_or([f64::NEG_INFINITY, f64::INFINITY], |k| [r.min[k], r.max[k]]);
            (n.clone(), range)
        })
        .collect()
}

/// The index names a model of `system` computes.
pub fn index_names(system: &System) -> Result<Vec<String>> {
    let inputs = IndexInputs::of(system, &Layout::of(system))?;
    Ok(inputs.columns().iter().map(|c| c.name.clone()).collect())
}

/// A refusal of a declaration, named by its field (`study.<name>.<field>: ...`).
fn spec_error(e: spec::SpecError) -> crate::Error {
    LearnError::Format {
        path: format!("study.{}.{}", e.study, e.field).into(),
        message: format!("{} (docs/studies.md)", e.message),
    }
    .into()
}

/// Checks the study of `params` against `system` before anything runs.
pub fn check(system: &System, params: &StudyParams) -> Result<Study> {
    params.validate()?;
    Study::parse(
        &params.study,
        &description_parameters(system),
        &index_names(system)?,
    )
    .map_err(spec_error)
}

/// The surrogate a study reads: the `surrogate` stage's output (`surrogate`), or else the model
/// of `params.algorithm` among `models` (with its calibration from `calibration` when given)
/// alone.
pub fn load_surrogate(
    surrogate: Option<&Path>,
    models: &[PathBuf],
    calibration: Option<&Path>,
    params: &StudyParams,
    device: &Device,
) -> Result<Surrogate> {
    if let Some(dir) = surrogate {
        return Surrogate::load(dir, device);
    }
    let mut predictor = None;
    for dir in models {
        let p = Predictor::load(dir, device)?;
        if p.meta.train.algorithm.id() == params.algorithm {
            predictor = Some(p);
            break;
        }
    }
    let mut predictor = predictor.ok_or_else(|| LearnError::OutOfRange {
        field: "algorithm".into(),
        value: params.algorithm.to_string(),
        allowed: format!("an algorithm among the {} trained models", models.len()),
    })?;
    if let Some(c) = calibration {
        predictor.load_calibration(c)?;
    }
    Ok(Surrogate::of_model(predictor))
}

/// Runs the study of `params` through `surrogate` and writes its files into `out`; returns the
/// one-line summary.
pub fn run(surrogate: &Surrogate, params: &StudyParams, out: &Path) -> Result<String> {
    run_with(surrogate, params, out, None)
}

/// [`run`] counting its designs in `progress`; once that is cancelled it stops at its next
/// slice of designs or solve with [`crate::Error::Cancelled`].
pub fn run_with(
    surrogate: &Surrogate,
    params: &StudyParams,
    out: &Path,
    progress: Option<&Progress>,
) -> Result<String> {
    params.validate()?;
    let predictor = surrogate.primary();
    let parameters = model_parameters(predictor);
    let names: Vec<String> = predictor
        .index_inputs()
        .columns()
        .iter()
        .map(|c| c.name.clone())
        .collect();
    let study = Study::parse(&params.study, &parameters, &names).map_err(spec_error)?;
    let ev = evaluate::Evaluator::new(surrogate, params)?;
    let ev = match progress {
        Some(p) => ev.with_progress(p),
        None => ev,
    };
    match &study.kind {
        StudyKind::MonteCarlo { n, limits } => {
            let mc = monte_carlo::run(&ev, &study, *n, limits, &parameters)?;
            output::write_monte_carlo(out, predictor, &study, &mc)?;
            let firsts: Vec<String> = mc
                .summaries
                .iter()
                .filter(|s| s.source == source::SURROGATE)
                .filter_map(|s| {
                    s.exceedance
                        .map(|e| format!("P({} > {}) = {:.4}", s.index, e.limit, e.probability))
                })
                .collect();
            Ok(format!(
                "`{}`: {n} designs in {:.1} s ({} through the solver in {:.1} s){}{}",
                study.name,
                mc.surrogate_s,
                mc.checked.len(),
                mc.solver_s,
                if firsts.is_empty() { "" } else { "; " },
                firsts.join(", ")
            ))
        }
        StudyKind::Sensitivity { n } => {
            let s = sensitivity::run(&ev, &study, *n, &parameters)?;
            output::write_sensitivity(out, predictor, &study, &s)?;
            let ranked = sensitivity::rankings(&s);
            let differ: Vec<&str> = ranked
                .iter()
                .filter(|r| !r.same)
                .map(|r| r.index.as_str())
                .collect();
            Ok(format!(
                "`{}`: {} evaluations ({n} rows, {} factors) in {:.1} s ({} through the solver in {:.1} s){}",
                study.name,
                s.evaluations.len(),
                s.factors.len(),
                s.surrogate_s,
                s.solved.len(),
                s.solver_s,
                if ranked.is_empty() {
                    String::new()
                } else if differ.is_empty() {
                    "; surrogate and solver rank the top factors alike".to_owned()
                } else {
                    format!("; the rankings differ for {} (summary.md says why)", differ.join(", "))
                }
            ))
        }
        StudyKind::CriticalSpeed(c) => {
            let r = critical_speed::run(&ev, &study, c, &parameters)?;
            output::write_critical_speed(out, predictor, &study, &r)?;
            let states = |s: &critical_speed::Sweeps| {
                let c = s.critical(&r.speeds);
                let within = c
                    .iter()
                    .filter(|x| matches!(x, critical_speed::Crossing::At(_)))
                    .count();
                let below = c
                    .iter()
                    .filter(|x| matches!(x, critical_speed::Crossing::Below))
                    .count();
                (within, below, c.len())
            };
            let (within, below, cells) = states(&r.surrogate);
            Ok(format!(
                "`{}`: {} grid points x {} speeds x {} tracks in {:.1} s ({} grid points through the solver in {:.1} s); critical speed within the sweep at {within} of {cells} points, below it at {below}",
                study.name,
                r.points.len(),
                r.speeds.len(),
                c.excitations,
                r.surrogate_s,
                r.solver.cells.len(),
                r.solver_s,
            ))
        }
        StudyKind::Optimise(o) => {
            let r = optimise::run(&ev, &study, o, &parameters)?;
            output::write_optimise(out, predictor, &study, o, &r)?;
            let best = &r.history[r.best];
            let solver = r.checked.iter().find(|c| c.role == optimise::Role::Optimum);
            Ok(format!(
                "`{}`: {} candidates in {:.1} s ({} through the solver in {:.1} s); {}: objective {:.4} (solver {}){}",
                study.name,
                r.history.len(),
                r.surrogate_s,
                r.checked.len(),
                r.solver_s,
                if r.feasible { "optimum" } else { "infeasible, least-violating design" },
                best.judged.objective,
                solver.map_or("-".to_owned(), |c| format!("{:.4}", c.solver.objective)),
                match solver {
                    Some(c) if r.feasible && !c.solver.feasible => "; the solver finds it violates a limit (summary.md)",
                    _ => "",
                }
            ))
        }
    }
}
