//! The files of an optimisation: the search's history (`history.parquet`: one row per
//! candidate with its start, its number within the start, its design, the objective's
//! statistic, each constrained index's statistic (`<index>_judged`), the penalised score and
//! `feasible`), every surrogate evaluation (`evaluations.parquet`: candidate by excitation,
//! every index with its interval where calibrated, `extrapolated`, `solver_checked`), the
//! solver's evaluations beside the surrogate's (`solver.parquet`), the checked candidates
//! judged by each source (`optimum.{parquet,csv}`), the Markdown summary, the plots
//! (`history.png`, [`SCATTER_FILE`]) and the timings ([`SPEED_FILE`]).

use super::{
    finish, num, plots, push_answers, push_solver, study_units, EXCITATION, SCATTER_FILE,
    SOLVER_CHECKED, SPEED_FILE,
};
use crate::evaluate::Solved;
use crate::optimise::{describe, Candidate, Judged, Optimisation, Role};
use crate::source;
use crate::spec::{Optimise, Study};
use crate::Result;
use pino_data::units::{Units, DIMENSIONLESS};
use pino_data::{Column, Table};
use pino_indices::system::IndexInfo;
use pino_predict::{DesignAnswer, Predictor};
use std::path::Path;

/// Column of a candidate's position in the search's history.
pub const CANDIDATE: &str = "candidate";
/// Column of the start a candidate belongs to.
pub const START: &str = "start";
/// Column of a candidate's number within its start.
pub const EVALUATION: &str = "evaluation";
/// Column of the objective's statistic over the excitations.
pub const OBJECTIVE: &str = "objective";
/// Column of the score the optimiser minimised.
pub const PENALISED: &str = "penalised";
/// Column flagging a candidate that meets every limit.
pub const FEASIBLE: &str = "feasible";
/// Column of why a candidate was checked by the solver.
pub const ROLE: &str = "role";
/// Suffix of a constrained index's statistic over the excitations of the values its limit is
/// judged on (the calibrated interval's upper end for the surrogate where there is one).
pub const JUDGED_SUFFIX: &str = "_judged";

/// The objective's unit: the terms' common unit, else dimensionless (a weighted sum of
/// numbers in different units).
fn objective_unit(predictor: &Predictor, o: &Optimise) -> String {
    let columns = predictor.index_inputs().columns();
    let units: Vec<&str> = o
        .objective
        .iter()
        .filter_map(|(i, _)| columns.iter().find(|c| c.name == *i))
        .map(|c| c.unit.as_str())
        .collect();
    match units.split_first() {
        Some((first, rest)) if rest.iter().all(|u| u == first) => (*first).to_owned(),
        _ => DIMENSIONLESS.to_owned(),
    }
}

/// Pushes `objective`, each constraint's `<index>_judged` and `feasible` of `judged`.
fn push_judged(
    t: &mut Table,
    predictor: &Predictor,
    r: &Optimisation,
    judged: &[&Judged],
) -> pino_data::Result<()> {
    let columns = predictor.index_inputs().columns();
    t.push(
        OBJECTIVE,
        Column::F64(judged.iter().map(|j| j.objective).collect()),
    )?;
    for (k, &(j, _)) in r.constraints.iter().enumerate() {
        t.push(
            &format!("{}{JUDGED_SUFFIX}", columns[j].name),
            Column::F64(judged.iter().map(|x| x.constraints[k]).collect()),
        )?;
    }
    t.push(
        FEASIBLE,
        Column::Bool(judged.iter().map(|j| j.feasible).collect()),
    )
}

/// Writes an optimisation's files into `out`: the search's history, every surrogate
/// evaluation, the solver's runs beside them, the checked candidates judged by both, the
/// plots and the summary.
pub fn write_optimise(
    out: &Path,
    predictor: &Predictor,
    study: &Study,
    o: &Optimise,
    r: &Optimisation,
) -> Result<()> {
    let columns = predictor.index_inputs().columns();
    let objective_unit = objective_unit(predictor, o);
    let judged_units: Vec<(String, &str)> = r
        .constraints
        .iter()
        .map(|&(j, _)| {
            (
                format!("{}{JUDGED_SUFFIX}", columns[j].name),
                columns[j].unit.as_str(),
            )
        })
        .collect();
    let mut extra: Vec<(&str, &str)> = vec![
        (CANDIDATE, DIMENSIONLESS),
        (START, DIMENSIONLESS),
        (EVALUATION, DIMENSIONLESS),
        (OBJECTIVE, objective_unit.as_str()),
        (PENALISED, DIMENSIONLESS),
        (FEASIBLE, DIMENSIONLESS),
        (ROLE, DIMENSIONLESS),
    ];
    extra.extend(judged_units.iter().map(|(n, u)| (n.as_str(), *u)));
    let units = study_units(predictor, &extra)?;
    let m = r.excitation.len();

    let designs: Vec<Vec<f64>> = r.history.iter().map(|c| c.design.clone()).collect();
    write_history(out, &units, predictor, r, &designs)?;
    let calibrated = write_evaluations(out, &units, predictor, r, &designs)?;
    let beside: Vec<&DesignAnswer> = r
        .checked
        .iter()
        .flat_map(|c| r.answers[c.candidate].iter())
        .collect();
    let solved: Vec<_> = r.checked.iter().flat_map(|c| c.solved.clone()).collect();
    write_solver(out, &units, predictor, r, &designs, &solved, &beside)?;
    write_optimum(out, &units, predictor, r, &designs)?;
    write_plots(out, predictor, study, o, r, &solved, &beside)?;
    let solves = r.checked.len() * m;
    finish(
        out,
        (r.distinct * m, r.surrogate_s),
        (solves, r.solver_s),
        &summary_markdown(predictor, study, o, r, calibrated, &objective_unit),
    )
}

/// `history.parquet`: the search's candidates in order, with their designs and judgements.
fn write_history(
    out: &Path,
    units: &Units,
    predictor: &Predictor,
    r: &Optimisation,
    designs: &[Vec<f64>],
) -> Result<()> {
    let mut h = Table::default().with_units(units.clone());
    let rows = r.history.len();
    h.push(CANDIDATE, Column::I64((0..rows as i64).collect()))?;
    h.push(
        START,
        Column::I64(r.history.iter().map(|c| c.start as i64).collect()),
    )?;
    h.push(
        EVALUATION,
        Column::I64(r.history.iter().map(|c| c.evaluation as i64).collect()),
    )?;
    predictor.space.push_columns(&mut h, designs)?;
    let judged: Vec<&Judged> = r.history.iter().map(|c| &c.judged).collect();
    push_judged(&mut h, predictor, r, &judged)?;
    h.push(
        PENALISED,
        Column::F64(r.history.iter().map(|c| c.penalised).collect()),
    )?;
    pino_data::write_parquet(&out.join("history.parquet"), &h)?;
    Ok(())
}

/// `evaluations.parquet`: every surrogate evaluation, candidate by excitation; whether the
/// answers carry calibrated intervals.
fn write_evaluations(
    out: &Path,
    units: &Units,
    predictor: &Predictor,
    r: &Optimisation,
    designs: &[Vec<f64>],
) -> Result<bool> {
    let (rows, m) = (r.history.len(), r.excitation.len());
    let mut e = Table::default().with_units(units.clone());
    let candidate: Vec<i64> = (0..rows as i64)
        .flat_map(|c| std::iter::repeat_n(c, m))
        .collect();
    let checked: Vec<bool> = (0..rows)
        .map(|c| r.checked.iter().any(|x| x.candidate == c))
        .collect();
    e.push(CANDIDATE, Column::I64(candidate))?;
    e.push(
        EXCITATION,
        Column::I64(
            (0..rows)
                .flat_map(|_| r.excitation.iter().map(|&x| x as i64))
                .collect(),
        ),
    )?;
    let every: Vec<Vec<f64>> = designs
        .iter()
        .flat_map(|d| std::iter::repeat_n(d.clone(), m))
        .collect();
    let answers: Vec<DesignAnswer> = r.answers.iter().flatten().cloned().collect();
    let calibrated = push_answers(&mut e, predictor, &every, &answers)?;
    e.push(
        SOLVER_CHECKED,
        Column::Bool(
            checked
                .iter()
                .flat_map(|&c| std::iter::repeat_n(c, m))
                .collect(),
        ),
    )?;
    pino_data::write_parquet(&out.join("evaluations.parquet"), &e)?;
    Ok(calibrated)
}

/// `solver.parquet`: the solver beside the surrogate, checked candidate by excitation.
fn write_solver(
    out: &Path,
    units: &Units,
    predictor: &Predictor,
    r: &Optimisation,
    designs: &[Vec<f64>],
    solved: &[Solved],
    beside: &[&DesignAnswer],
) -> Result<()> {
    let m = r.excitation.len();
    let mut v = Table::default().with_units(units.clone());
    v.push(
        CANDIDATE,
        Column::I64(
            r.checked
                .iter()
                .flat_map(|c| std::iter::repeat_n(c.candidate as i64, m))
                .collect(),
        ),
    )?;
    v.push(
        ROLE,
        Column::Str(
            r.checked
                .iter()
                .flat_map(|c| std::iter::repeat_n(c.role.label().to_owned(), m))
                .collect(),
        ),
    )?;
    v.push(
        EXCITATION,
        Column::I64(
            r.checked
                .iter()
                .flat_map(|_| r.excitation.iter().map(|&x| x as i64))
                .collect(),
        ),
    )?;
    let solver_designs: Vec<Vec<f64>> = r
        .checked
        .iter()
        .flat_map(|c| std::iter::repeat_n(designs[c.candidate].clone(), m))
        .collect();
    push_solver(&mut v, predictor, &solver_designs, solved, beside)?;
    pino_data::write_parquet(&out.join("solver.parquet"), &v)?;
    Ok(())
}

/// `optimum.parquet` and its CSV: each checked candidate judged by the surrogate and by the
/// solver.
fn write_optimum(
    out: &Path,
    units: &Units,
    predictor: &Predictor,
    r: &Optimisation,
    designs: &[Vec<f64>],
) -> Result<()> {
    let mut t = Table::default().with_units(units.clone());
    let both = |f: &dyn Fn(usize) -> i64| -> Vec<i64> {
        (0..r.checked.len()).flat_map(|k| [f(k), f(k)]).collect()
    };
    t.push(
        CANDIDATE,
        Column::I64(both(&|k| r.checked[k].candidate as i64)),
    )?;
    t.push(
        ROLE,
        Column::Str(
            r.checked
                .iter()
                .flat_map(|c| [c.role.label().to_owned(), c.role.label().to_owned()])
                .collect(),
        ),
    )?;
    t.push(
        "source",
        Column::Str(
            r.checked
                .iter()
                .flat_map(|_| [source::SURROGATE.to_owned(), source::SOLVER.to_owned()])
                .collect(),
        ),
    )?;
    let twice: Vec<Vec<f64>> = r
        .checked
        .iter()
        .flat_map(|c| [designs[c.candidate].clone(), designs[c.candidate].clone()])
        .collect();
    predictor.space.push_columns(&mut t, &twice)?;
    let judged: Vec<&Judged> = r
        .checked
        .iter()
        .flat_map(|c| [&r.history[c.candidate].judged, &c.solver])
        .collect();
    push_judged(&mut t, predictor, r, &judged)?;
    pino_data::write_parquet(&out.join("optimum.parquet"), &t)?;
    report::csv::write_csv(&out.join(super::OPTIMUM_TABLE_FILE), &t).map_err(super::report_err)
}

/// `history.png` (the search with each limit) and the surrogate against the solver.
fn write_plots(
    out: &Path,
    predictor: &Predictor,
    study: &Study,
    o: &Optimise,
    r: &Optimisation,
    solved: &[Solved],
    beside: &[&DesignAnswer],
) -> Result<()> {
    let q = super::quantities(predictor);
    let steps: Vec<plots::Step> = r
        .history
        .iter()
        .map(|c| plots::Step {
            start: c.start,
            objective: c.judged.objective,
            constraints: c.judged.constraints.clone(),
            feasible: c.judged.feasible,
        })
        .collect();
    let limited: Vec<(plots::Quantity<'_>, f64)> =
        r.constraints.iter().map(|&(j, l)| (q[j], l)).collect();
    plots::history(
        &out.join("history.png"),
        &study.name,
        &describe(o),
        &limited,
        &steps,
        o.maximise,
    )
    .map_err(super::report_err)?;
    let pairs = super::solver_pairs(q.len(), beside, solved);
    plots::surrogate_vs_solver(&out.join(SCATTER_FILE), &study.name, &q, &pairs)
        .map_err(super::report_err)
}

/// The Markdown summary: the problem, the optimum (or the least-violating design), the
/// checked candidates judged by the surrogate and by the solver.
fn summary_markdown(
    predictor: &Predictor,
    study: &Study,
    o: &Optimise,
    r: &Optimisation,
    calibrated: bool,
    unit: &str,
) -> String {
    let columns = predictor.index_inputs().columns();
    let names = predictor.space.names();
    let best = &r.history[r.best];
    let mut md = format!(
        "# Study `{}`: optimisation\n\n\
         Goal: {} (`{OBJECTIVE}`, {unit}), subject to {}.\n\n\
         {} candidates ({} distinct designs) from {} starts, each under the same {} excitations; \
         the solver ran {} of them under the same excitations (the time of each side: `{SPEED_FILE}`).\n{}\n",
        study.name,
        describe(o),
        if r.constraints.is_empty() {
            "no limit".to_owned()
        } else {
            r.constraints
                .iter()
                .map(|&(j, l)| format!("{} <= {l}", columns[j].name))
                .collect::<Vec<_>>()
                .join(", ")
        },
        r.history.len(),
        r.distinct,
        o.starts,
        r.excitation.len(),
        r.checked.len(),
        if calibrated {
            "\nEach limit is judged on the upper end of the calibrated interval (the surrogate's side).\n"
        } else {
            "\nThe model has no calibration: its answers carry no error bar, and the limits are judged on point values.\n"
        }
    );
    if r.feasible {
        md.push_str(&format!(
            "\n**Optimum**: candidate {}, objective {} {unit}.\n",
            r.best,
            num(best.judged.objective)
        ));
    } else {
        md.push_str(&format!(
            "\n**Infeasible**: no candidate meets every limit; the least-violating design is candidate {} (objective {} {unit}).\n",
            r.best,
            num(best.judged.objective)
        ));
    }
    md.push_str(&design_section(names, r, best));
    md.push_str(&checked_section(columns, r));
    md
}

/// The optimum's design: each varying parameter's value and box, flagged at a bound.
fn design_section(names: &[String], r: &Optimisation, best: &Candidate) -> String {
    let mut md = String::new();
    let varying: Vec<usize> = (0..names.len())
        .filter(|&k| r.bounds[k][0] < r.bounds[k][1])
        .collect();
    md.push_str("\n## The design\n\n");
    let rows: Vec<Vec<String>> = varying
        .iter()
        .map(|&k| {
            let [lo, hi] = r.bounds[k];
            let at = best.design[k];
            let edge = (at - lo).abs() <= 1e-6 * (hi - lo) || (hi - at).abs() <= 1e-6 * (hi - lo);
            vec![
                names[k].clone(),
                num(at),
                format!("[{}, {}]", num(lo), num(hi)),
                if edge { "at a bound" } else { "" }.to_owned(),
            ]
        })
        .collect();
    md.push_str(&report::markdown::table(
        &["parameter", "value", "box", ""],
        &rows,
    ));
    md
}

/// The checked candidates, surrogate beside solver, and the solver's verdict on the optimum.
fn checked_section(columns: &[IndexInfo], r: &Optimisation) -> String {
    let mut md = String::new();
    md.push_str("\n## Surrogate and solver on the checked candidates\n\n");
    let mut header = vec![
        "candidate".to_owned(),
        "role".to_owned(),
        format!("{OBJECTIVE} surrogate"),
        format!("{OBJECTIVE} solver"),
    ];
    for &(j, l) in &r.constraints {
        header.push(format!("{} surrogate (<= {l})", columns[j].name));
        header.push(format!("{} solver", columns[j].name));
    }
    header.push("feasible surrogate / solver".into());
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let yes = |b: bool| if b { "yes" } else { "no" };
    let rows: Vec<Vec<String>> = r
        .checked
        .iter()
        .map(|c| {
            let s = &r.history[c.candidate].judged;
            let mut row = vec![
                c.candidate.to_string(),
                c.role.label().to_owned(),
                num(s.objective),
                num(c.solver.objective),
            ];
            for k in 0..r.constraints.len() {
                row.push(num(s.constraints[k]));
                row.push(num(c.solver.constraints[k]));
            }
            row.push(format!("{} / {}", yes(s.feasible), yes(c.solver.feasible)));
            row
        })
        .collect();
    md.push_str(&report::markdown::table(&header, &rows));
    if let Some(c) = r.checked.iter().find(|c| c.role == Role::Optimum) {
        let s = &r.history[c.candidate].judged;
        let verdict = match (s.feasible, c.solver.feasible) {
            (true, true) => "the solver confirms the optimum meets every limit",
            (true, false) => {
                "the solver finds the optimum violates a limit: the surrogate's error (beyond its \
                 interval where calibrated) misleads the search here"
            }
            (false, true) => {
                "the solver finds the least-violating design feasible: the surrogate (its \
                 interval's upper end where calibrated) is conservative here"
            }
            (false, false) => "the solver agrees that the design violates a limit",
        };
        let failures = c.solved.iter().filter(|x| x.failure.is_some()).count();
        md.push_str(&format!(
            "\nOn the optimum {verdict}{}; objective {} (surrogate) vs {} (solver).\n",
            if failures > 0 {
                format!(" ({failures} of its solves failed: `solver.parquet` says why)")
            } else {
                String::new()
            },
            num(s.objective),
            num(c.solver.objective)
        ));
    }
    md
}
