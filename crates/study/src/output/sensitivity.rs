//! The files of a sensitivity study: every evaluation in SALib's order
//! (`evaluations.parquet`: `row`, `position` within the row, `block` (`A`, `AB`, `B`), the
//! `factor` an `AB` evaluation takes from `B`, the excitation id, the parameters, every index
//! with its interval where calibrated, `extrapolated`, `solver_checked`), the solver's
//! evaluations beside the surrogate's (`solver.parquet`), the indices
//! (`sobol.{parquet,csv}`: one row per index, source and factor, with bootstrap intervals and
//! the factor's rank by total index), the convergence record (`convergence.parquet`), the
//! Markdown summary with the rankings side by side, the plots (`sobol.png`,
//! [`SCATTER_FILE`]) and the timings ([`SPEED_FILE`]).

use super::{
    finish, num, plots, push_answers, push_solver, quantities, report_err, solver_pairs,
    study_units, EXCITATION, SCATTER_FILE, SOLVER_CHECKED, SPEED_FILE,
};
use crate::sensitivity::{rankings, Evaluation, Sensitivity, RANKED};
use crate::source;
use crate::spec::Study;
use crate::Result;
use pino_data::units::{Units, DIMENSIONLESS};
use pino_data::{Column, Table};
use pino_predict::{DesignAnswer, Predictor};
use pino_studies::sobol::Block;
use std::path::Path;

/// Column of an evaluation's row of the design.
pub const ROW: &str = "row";
/// Column of its position within the row (SALib's order: `A`, each `AB`, `B`).
pub const POSITION: &str = "position";
/// Column of its matrix.
pub const BLOCK: &str = "block";
/// Column of the factor an `AB` evaluation takes from `B` (empty for `A` and `B`).
pub const FACTOR: &str = "factor";

/// The columns of `sobol.parquet` beside `index`, `source`, `n` and `factor`.
const ESTIMATES: [&str; 7] = ["S1", "S1_lo", "S1_hi", "ST", "ST_lo", "ST_hi", "rank"];

/// Pushes `row`, `position`, `block`, `factor` and the excitation id of `evaluations`.
fn push_design(
    t: &mut Table,
    s: &Sensitivity,
    evaluations: &[Evaluation],
) -> pino_data::Result<()> {
    let g = s.factors.len();
    t.push(
        ROW,
        Column::I64(evaluations.iter().map(|e| e.row as i64).collect()),
    )?;
    t.push(
        POSITION,
        Column::I64(
            evaluations
                .iter()
                .map(|e| e.block.position(g) as i64)
                .collect(),
        ),
    )?;
    t.push(
        BLOCK,
        Column::Str(
            evaluations
                .iter()
                .map(|e| e.block.label().to_owned())
                .collect(),
        ),
    )?;
    t.push(
        FACTOR,
        Column::OptStr(
            evaluations
                .iter()
                .map(|e| match e.block {
                    Block::AB(i) => Some(s.factors[i].clone()),
                    Block::A | Block::B => None,
                })
                .collect(),
        ),
    )?;
    t.push(
        EXCITATION,
        Column::I64(evaluations.iter().map(|e| e.excitation as i64).collect()),
    )
}

/// Writes a sensitivity study's files into `out`.
pub fn write_sensitivity(
    out: &Path,
    predictor: &Predictor,
    study: &Study,
    s: &Sensitivity,
) -> Result<()> {
    let mut extra = vec![
        (ROW, DIMENSIONLESS),
        (POSITION, DIMENSIONLESS),
        (BLOCK, DIMENSIONLESS),
        (FACTOR, DIMENSIONLESS),
    ];
    extra.extend(ESTIMATES.iter().map(|n| (*n, DIMENSIONLESS)));
    let units = study_units(predictor, &extra)?;
    let designs: Vec<Vec<f64>> = s.evaluations.iter().map(|e| e.design.clone()).collect();
    let checked = s.solved.len();

    // Every evaluation.
    let mut t = Table::default().with_units(units.clone());
    push_design(&mut t, s, &s.evaluations)?;
    let calibrated = push_answers(&mut t, predictor, &designs, &s.answers)?;
    t.push(
        SOLVER_CHECKED,
        Column::Bool((0..s.evaluations.len()).map(|k| k < checked).collect()),
    )?;
    pino_data::write_parquet(&out.join("evaluations.parquet"), &t)?;

    // The solver beside the surrogate.
    let mut v = Table::default().with_units(units.clone());
    push_design(&mut v, s, &s.evaluations[..checked])?;
    let answers: Vec<&DesignAnswer> = s.answers[..checked].iter().collect();
    push_solver(&mut v, predictor, &designs[..checked], &s.solved, &answers)?;
    pino_data::write_parquet(&out.join("solver.parquet"), &v)?;

    // The indices: one row per index, source and factor.
    let m = sobol_table(s, units.clone())?;
    pino_data::write_parquet(&out.join("sobol.parquet"), &m)?;
    report::csv::write_csv(&out.join(super::SOBOL_TABLE_FILE), &m).map_err(report_err)?;

    // The convergence record.
    let c = convergence_table(s, units)?;
    pino_data::write_parquet(&out.join("convergence.parquet"), &c)?;

    write_plots(out, predictor, study, s, &answers)?;
    finish(
        out,
        (s.evaluations.len(), s.surrogate_s),
        (checked, s.solver_s),
        &summary_markdown(study, s, calibrated),
    )
}

/// The Sobol estimates: one row per index, source and factor, with the factor's rank.
fn sobol_table(s: &Sensitivity, units: Units) -> Result<Table> {
    let mut m = Table::default().with_units(units);
    let (mut index, mut source, mut rows, mut factor) = (vec![], vec![], vec![], vec![]);
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); ESTIMATES.len()];
    for e in &s.sobol {
        let mut rank = vec![f64::NAN; s.factors.len()];
        for (place, &k) in e.order().iter().enumerate() {
            rank[k] = (place + 1) as f64;
        }
        for (k, name) in s.factors.iter().enumerate() {
            index.push(e.index.clone());
            source.push(e.source.to_owned());
            rows.push(e.rows as i64);
            factor.push(name.clone());
            let row = e.factors.get(k).map_or([f64::NAN; 6], |f| {
                [
                    f.first,
                    f.first_ci.lo,
                    f.first_ci.hi,
                    f.total,
                    f.total_ci.lo,
                    f.total_ci.hi,
                ]
            });
            for (col, x) in values.iter_mut().zip(row.into_iter().chain([rank[k]])) {
                col.push(x);
            }
        }
    }
    m.push("index", Column::Str(index))?;
    m.push("source", Column::Str(source))?;
    m.push("n", Column::I64(rows))?;
    m.push(FACTOR, Column::Str(factor))?;
    for (name, col) in ESTIMATES.iter().zip(values) {
        m.push(name, Column::F64(col))?;
    }
    Ok(m)
}

/// The convergence record: each index's first and total estimates at each row count.
fn convergence_table(s: &Sensitivity, units: Units) -> Result<Table> {
    let mut c = Table::default().with_units(units);
    let (mut index, mut rows, mut factor, mut first, mut total) =
        (vec![], vec![], vec![], vec![], vec![]);
    for (i, n, est) in &s.convergence {
        for (k, (f, t)) in est.iter().enumerate() {
            index.push(i.clone());
            rows.push(*n as i64);
            factor.push(s.factors[k].clone());
            first.push(*f);
            total.push(*t);
        }
    }
    c.push("index", Column::Str(index))?;
    c.push("n", Column::I64(rows))?;
    c.push(FACTOR, Column::Str(factor))?;
    c.push("S1", Column::F64(first))?;
    c.push("ST", Column::F64(total))?;
    Ok(c)
}

/// The Sobol bars of every index (surrogate and solver) and the surrogate against the solver
/// on the checked rows.
fn write_plots(
    out: &Path,
    predictor: &Predictor,
    study: &Study,
    s: &Sensitivity,
    answers: &[&DesignAnswer],
) -> Result<()> {
    let q = quantities(predictor);
    let estimates = |index: &str, source: &str| -> plots::SobolBars {
        s.of(index, source).map_or_else(Vec::new, |e| {
            e.factors
                .iter()
                .map(|f| (f.first, f.total, [f.total_ci.lo, f.total_ci.hi]))
                .collect()
        })
    };
    let names: Vec<&str> = q.iter().map(|x| x.name).collect();
    let bars: Vec<_> = names
        .iter()
        .map(|i| {
            (
                estimates(i, source::SURROGATE),
                estimates(i, source::SOLVER),
            )
        })
        .collect();
    plots::sobol_bars(
        &out.join("sobol.png"),
        &study.name,
        &s.factors,
        &names,
        &bars,
    )
    .map_err(report_err)?;
    let pairs = solver_pairs(q.len(), answers, &s.solved);
    plots::surrogate_vs_solver(&out.join(SCATTER_FILE), &study.name, &q, &pairs)
        .map_err(report_err)?;
    Ok(())
}

/// The Markdown summary: what ran, each index's indices by source, the rankings.
fn summary_markdown(study: &Study, s: &Sensitivity, calibrated: bool) -> String {
    let g = s.factors.len();
    let mut md = format!(
        "# Study `{}`: Sobol sensitivity, N = {} rows, {g} factors\n\n\
         {} evaluations through the surrogate ({} factors + 2 per row); the solver ran the first {} rows ({} evaluations) with the same excitations (the time of each side: `{SPEED_FILE}`). \
         First-order (Saltelli 2010) and total (Jansen 1999) indices with bootstrap intervals; `surrogate_reduced` is the surrogate on the solver's rows.\n{}\n",
        study.name,
        s.n,
        s.evaluations.len(),
        g,
        s.solver_rows,
        s.solved.len(),
        if calibrated {
            ""
        } else {
            "\nThe model has no calibration: its answers carry no error bar.\n"
        }
    );
    let ci = |x: f64, lo: f64, hi: f64| format!("{} [{}, {}]", num(x), num(lo), num(hi));
    let mut header = vec!["factor".to_owned()];
    let sources: Vec<&str> = [source::SURROGATE, source::SURROGATE_REDUCED, source::SOLVER]
        .into_iter()
        .filter(|src| s.sobol.iter().any(|e| e.source == *src))
        .collect();
    for src in &sources {
        header.push(format!("S1 {src}"));
        header.push(format!("ST {src}"));
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let mut indices: Vec<&str> = s.sobol.iter().map(|e| e.index.as_str()).collect();
    indices.dedup();
    for index in indices {
        md.push_str(&format!("\n## `{index}`\n\n"));
        let table: Vec<Vec<String>> = s
            .factors
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let mut row = vec![f.clone()];
                for src in &sources {
                    match s.of(index, src).and_then(|e| e.factors.get(k)) {
                        Some(e) => {
                            row.push(ci(e.first, e.first_ci.lo, e.first_ci.hi));
                            row.push(ci(e.total, e.total_ci.lo, e.total_ci.hi));
                        }
                        None => row.extend(["-".to_owned(), "-".to_owned()]),
                    }
                }
                row
            })
            .collect();
        md.push_str(&report::markdown::table(&header, &table));
    }
    let ranked = rankings(s);
    if !ranked.is_empty() {
        md.push_str(&format!(
            "\n## The {RANKED} most influential factors (by total index)\n\n"
        ));
        let rows: Vec<Vec<String>> = ranked
            .iter()
            .map(|r| {
                vec![
                    r.index.clone(),
                    r.surrogate.join(", "),
                    r.surrogate_reduced.join(", "),
                    r.solver.join(", "),
                    if r.same { "same" } else { "differs" }.to_owned(),
                    r.why.clone().unwrap_or_default(),
                ]
            })
            .collect();
        md.push_str(&report::markdown::table(
            &[
                "index",
                "surrogate",
                "surrogate, solver's rows",
                "solver",
                "ranking (surrogate vs solver)",
                "why",
            ],
            &rows,
        ));
    }
    md
}
