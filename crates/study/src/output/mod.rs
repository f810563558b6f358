//! The files of a study, one writer per kind ([`monte_carlo`], [`sensitivity`], [`optimise`],
//! [`critical_speed`]), sharing the
//! columns every study has: the designs and their excitation ids, the surrogate's index
//! values with their calibrated intervals and `extrapolated`, the solver's beside them, and
//! the timings ([`SPEED_FILE`]: the only file whose bytes differ between two runs of one
//! study). Every table carries the units of its columns (`study_units`), as in every
//! artifact.

pub mod critical_speed;
pub mod monte_carlo;
pub mod optimise;
pub mod plots;
pub mod sensitivity;

pub use critical_speed::write_critical_speed;
pub use monte_carlo::write_monte_carlo;
pub use optimise::write_optimise;
pub use sensitivity::write_sensitivity;

use super::evaluate::Solved;
use super::spec;
use crate::Result;
use pino_data::units::{Units, DIMENSIONLESS};
use pino_data::{Column, Table};
use pino_learn::Error as LearnError;
use pino_predict::{DesignAnswer, Predictor};
use pino_studies::stats::QUANTILES;
use std::path::Path;

/// Column of a design's number in a study.
pub const DESIGN: &str = "design";
/// Column of its excitation id (the profile sample id at the study's seed).
pub const EXCITATION: &str = "excitation";
/// The timings of a study (the only file that differs between two runs of one study).
pub const SPEED_FILE: &str = "speed.csv";

/// The report of a study, in Markdown (every kind).
pub const SUMMARY_MD_FILE: &str = "summary.md";
/// A Monte Carlo study's statistics per index and source, as CSV.
pub const MONTE_CARLO_TABLE_FILE: &str = "summary.csv";
/// A sensitivity study's Sobol indices per index and factor, as CSV.
pub const SOBOL_TABLE_FILE: &str = "sobol.csv";
/// An optimisation's optimum, runners-up and checked candidates, as CSV.
pub const OPTIMUM_TABLE_FILE: &str = "optimum.csv";
/// A critical-speed study's critical speed per grid point and side, as CSV.
pub const CRITICAL_SPEED_TABLE_FILE: &str = "critical_speed.csv";

/// The table a reader of a study of `kind` (the declaration's `kind`) opens first.
pub fn headline_table(kind: &str) -> Option<&'static str> {
    match kind {
        spec::MONTE_CARLO => Some(MONTE_CARLO_TABLE_FILE),
        spec::SENSITIVITY => Some(SOBOL_TABLE_FILE),
        spec::OPTIMISE => Some(OPTIMUM_TABLE_FILE),
        spec::CRITICAL_SPEED => Some(CRITICAL_SPEED_TABLE_FILE),
        _ => None,
    }
}

/// The plot of the surrogate against the solver on the checked evaluations (every kind).
pub const SCATTER_FILE: &str = "surrogate_vs_solver.png";
/// Column flagging the designs the solver also answered.
pub const SOLVER_CHECKED: &str = "solver_checked";
/// Column flagging designs outside the model's training ranges.
pub const EXTRAPOLATED: &str = "extrapolated";
/// Column of why the solver gave no answer (null when it did).
pub const SOLVER_FAILURE: &str = "solver_failure";
/// Suffix of the surrogate's value beside the solver's.
pub const SURROGATE_SUFFIX: &str = "_surrogate";

fn quantile_name(p: f64) -> String {
    format!("q{:02}", (p * 100.0).round() as i64)
}

/// The Monte Carlo summary's statistics, in column order: `mean`, `std`, the quantiles
/// (`q05`, ...).
fn statistic_names() -> Vec<String> {
    ["mean".to_owned(), "std".to_owned()]
        .into_iter()
        .chain(QUANTILES.iter().map(|&p| quantile_name(p)))
        .collect()
}

fn report_err(e: report::Error) -> crate::Error {
    LearnError::Format {
        path: "study".into(),
        message: e.to_string(),
    }
    .into()
}

/// A number in a Markdown table (`-` when missing).
fn num(x: f64) -> String {
    if x.is_nan() {
        "-".into()
    } else {
        format!("{x:.4}")
    }
}

/// The units of the columns a study's tables have: the model's system's, those every study
/// writes, and `extra` (`(name, unit)`).
fn study_units(predictor: &Predictor, extra: &[(&str, &str)]) -> Result<Units> {
    let mut units: Vec<(String, String)> = [
        DESIGN,
        EXCITATION,
        SOLVER_CHECKED,
        EXTRAPOLATED,
        SOLVER_FAILURE,
        "source",
        "index",
        "n",
    ]
    .iter()
    .map(|n| ((*n).to_owned(), DIMENSIONLESS.to_owned()))
    .collect();
    for c in predictor.index_inputs().columns() {
        for suffix in ["_lo", "_hi", SURROGATE_SUFFIX] {
            units.push((format!("{}{suffix}", c.name), c.unit.clone()));
        }
    }
    units.extend(
        extra
            .iter()
            .map(|(n, u)| ((*n).to_owned(), (*u).to_owned())),
    );
    Ok(predictor.units()?.with(units)?)
}

/// Pushes the parameters of `designs`, the surrogate's index values, their calibrated
/// `_lo`/`_hi` (when every answer has them) and `extrapolated`; returns whether the answers
/// are calibrated.
fn push_answers(
    t: &mut Table,
    predictor: &Predictor,
    designs: &[Vec<f64>],
    answers: &[DesignAnswer],
) -> Result<bool> {
    let columns = predictor.index_inputs().columns();
    predictor.space.push_columns(t, designs)?;
    for (j, c) in columns.iter().enumerate() {
        t.push(
            &c.name,
            Column::F64(answers.iter().map(|a| a.indices.values[j]).collect()),
        )?;
    }
    let calibrated = !answers.is_empty() && answers.iter().all(|a| a.calibrated.is_some());
    if calibrated {
        for (j, c) in columns.iter().enumerate() {
            let side = |lo: bool| {
                answers
                    .iter()
                    .map(|a| {
                        let i = a.calibrated.as_ref().map(|c| c.indices[j]);
                        i.map_or(f64::NAN, |i| if lo { i.lo } else { i.hi })
                    })
                    .collect()
            };
            t.push(&format!("{}_lo", c.name), Column::F64(side(true)))?;
            t.push(&format!("{}_hi", c.name), Column::F64(side(false)))?;
        }
    }
    let outside = predictor.outside_training(designs)?;
    t.push(
        EXTRAPOLATED,
        Column::Bool(outside.iter().map(|o| !o.is_empty()).collect()),
    )?;
    Ok(calibrated)
}

/// Pushes the parameters of `designs`, the solver's index values with the surrogate's
/// beside each (`<index>_surrogate`, from `answers`) and `solver_failure`.
fn push_solver(
    t: &mut Table,
    predictor: &Predictor,
    designs: &[Vec<f64>],
    solved: &[Solved],
    answers: &[&DesignAnswer],
) -> Result<()> {
    predictor.space.push_columns(t, designs)?;
    for (j, c) in predictor.index_inputs().columns().iter().enumerate() {
        t.push(
            &c.name,
            Column::F64(solved.iter().map(|x| x.indices[j]).collect()),
        )?;
        t.push(
            &format!("{}{SURROGATE_SUFFIX}", c.name),
            Column::F64(answers.iter().map(|a| a.indices.values[j]).collect()),
        )?;
    }
    t.push(
        SOLVER_FAILURE,
        Column::OptStr(solved.iter().map(|x| x.failure.clone()).collect()),
    )?;
    Ok(())
}

/// The model's indices as named quantities, for the plots.
fn quantities(predictor: &Predictor) -> Vec<plots::Quantity<'_>> {
    predictor
        .index_inputs()
        .columns()
        .iter()
        .map(|c| plots::Quantity {
            name: &c.name,
            unit: &c.unit,
        })
        .collect()
}

/// Per index, the surrogate's and the solver's values on the same evaluations: `beside[k]`
/// the surrogate's answer the solver's `solved[k]` checks.
fn solver_pairs(
    indices: usize,
    beside: &[&DesignAnswer],
    solved: &[Solved],
) -> Vec<(Vec<f64>, Vec<f64>)> {
    (0..indices)
        .map(|j| {
            (
                beside.iter().map(|a| a.indices.values[j]).collect(),
                solved.iter().map(|s| s.indices[j]).collect(),
            )
        })
        .collect()
}

/// Writes a study's last files: [`SPEED_FILE`] with each side's evaluations and wall time,
/// and [`SUMMARY_MD_FILE`].
fn finish(out: &Path, surrogate: (usize, f64), solver: (usize, f64), summary: &str) -> Result<()> {
    write_speed(out, surrogate, solver)?;
    Ok(atomic_file::write_atomic(
        &out.join(SUMMARY_MD_FILE),
        summary.as_bytes(),
    )?)
}

/// Writes [`SPEED_FILE`]: each side's evaluations, wall time and time per evaluation.
fn write_speed(out: &Path, surrogate: (usize, f64), solver: (usize, f64)) -> Result<()> {
    let per = |(k, s): (usize, f64)| if k == 0 { f64::NAN } else { 1e3 * s / k as f64 };
    let speed = format!(
        "side,designs,seconds,ms_per_design\nsurrogate,{},{:.4},{:.4}\nsolver,{},{:.4},{:.4}\n",
        surrogate.0,
        surrogate.1,
        per(surrogate),
        solver.0,
        solver.1,
        per(solver)
    );
    Ok(atomic_file::write_atomic(
        &out.join(SPEED_FILE),
        speed.as_bytes(),
    )?)
}
