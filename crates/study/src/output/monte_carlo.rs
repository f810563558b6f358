//! The files of a Monte Carlo study: every evaluation (`evaluations.parquet`: the design, its
//! excitation id, every index, its interval where calibrated, `extrapolated`,
//! `solver_checked`), the solver's answers beside the surrogate's (`solver.parquet`), the
//! statistics (`summary.{parquet,csv,md}`, one row per index and source), the plots
//! (`histograms.png`, `exceedance.png`, [`SCATTER_FILE`]) and the timings ([`SPEED_FILE`]).

use super::{
    finish, num, plots, push_answers, push_solver, quantities, report_err, solver_pairs,
    statistic_names, study_units, DESIGN, EXCITATION, SCATTER_FILE, SOLVER_CHECKED, SPEED_FILE,
};
use crate::monte_carlo::MonteCarlo;
use crate::spec::Study;
use crate::Result;
use pino_data::units::{Units, DIMENSIONLESS, PER_ROW, UNIT_KEY};
use pino_data::{Column, Table};
use pino_predict::{DesignAnswer, Predictor};
use pino_studies::stats::Interval;
use std::path::Path;

/// Writes a Monte Carlo study's files into `out`: every evaluation, the solver beside the
/// surrogate, the statistics, the plots and the summary.
pub fn write_monte_carlo(
    out: &Path,
    predictor: &Predictor,
    study: &Study,
    mc: &MonteCarlo,
) -> Result<()> {
    let mut extra: Vec<(String, &str)> = vec![
        ("limit".into(), PER_ROW),
        ("p_exceed".into(), DIMENSIONLESS),
    ];
    for stat in statistic_names() {
        for suffix in ["", "_lo", "_hi"] {
            extra.push((format!("{stat}{suffix}"), PER_ROW));
        }
    }
    for s in [
        "p_exceed_lo",
        "p_exceed_hi",
        "p_surrogate_lo",
        "p_surrogate_hi",
    ] {
        extra.push((s.into(), DIMENSIONLESS));
    }
    let extra: Vec<(&str, &str)> = extra.iter().map(|(n, u)| (n.as_str(), *u)).collect();
    let units = study_units(predictor, &extra)?;

    let n = mc.designs.len();
    let calibrated = write_evaluations(out, &units, predictor, mc)?;
    write_solver(out, &units, predictor, mc)?;
    write_summary_table(out, &units, predictor, mc)?;
    write_plots(out, predictor, study, mc)?;
    finish(
        out,
        (n, mc.surrogate_s),
        (mc.checked.len(), mc.solver_s),
        &summary_markdown(study, mc, calibrated),
    )
}

/// `evaluations.parquet`: every design with its answers; whether they carry calibrated
/// intervals.
fn write_evaluations(
    out: &Path,
    units: &Units,
    predictor: &Predictor,
    mc: &MonteCarlo,
) -> Result<bool> {
    let n = mc.designs.len();
    let mut t = Table::default().with_units(units.clone());
    t.push(DESIGN, Column::I64((0..n as i64).collect()))?;
    t.push(
        EXCITATION,
        Column::I64(mc.excitation.iter().map(|&e| e as i64).collect()),
    )?;
    let calibrated = push_answers(&mut t, predictor, &mc.designs, &mc.answers)?;
    let mut checked = vec![false; n];
    for &k in &mc.checked {
        checked[k] = true;
    }
    t.push(SOLVER_CHECKED, Column::Bool(checked))?;
    pino_data::write_parquet(&out.join("evaluations.parquet"), &t)?;
    Ok(calibrated)
}

/// `solver.parquet`: the checked designs through the solver, beside the surrogate.
fn write_solver(out: &Path, units: &Units, predictor: &Predictor, mc: &MonteCarlo) -> Result<()> {
    let mut s = Table::default().with_units(units.clone());
    s.push(
        DESIGN,
        Column::I64(mc.checked.iter().map(|&k| k as i64).collect()),
    )?;
    s.push(
        EXCITATION,
        Column::I64(
            mc.checked
                .iter()
                .map(|&k| mc.excitation[k] as i64)
                .collect(),
        ),
    )?;
    let designs: Vec<Vec<f64>> = mc.checked.iter().map(|&k| mc.designs[k].clone()).collect();
    let answers: Vec<&DesignAnswer> = mc.checked.iter().map(|&k| &mc.answers[k]).collect();
    push_solver(&mut s, predictor, &designs, &mc.solved, &answers)?;
    pino_data::write_parquet(&out.join("solver.parquet"), &s)?;
    Ok(())
}

/// `summary.parquet` and its CSV: each index's statistics with their bootstrap intervals and
/// its exceedance of the limit, by source.
fn write_summary_table(
    out: &Path,
    units: &Units,
    predictor: &Predictor,
    mc: &MonteCarlo,
) -> Result<()> {
    let columns = predictor.index_inputs().columns();
    let rows = &mc.summaries;
    let mut m = Table::default().with_units(units.clone());
    let unit_of = |name: &str| {
        columns
            .iter()
            .find(|c| c.name == name)
            .map_or(String::new(), |c| c.unit.clone())
    };
    m.push(
        "index",
        Column::Str(rows.iter().map(|r| r.index.clone()).collect()),
    )?;
    m.push(
        UNIT_KEY,
        Column::Str(rows.iter().map(|r| unit_of(&r.index)).collect()),
    )?;
    m.push(
        "source",
        Column::Str(rows.iter().map(|r| r.source.to_owned()).collect()),
    )?;
    m.push(
        "n",
        Column::I64(rows.iter().map(|r| r.summary.n as i64).collect()),
    )?;
    let f = |m: &mut Table, name: &str, v: Vec<f64>| m.push(name, Column::F64(v));
    // Each statistic with its bootstrap interval: mean, std, then the quantiles.
    let stats = |s: &pino_studies::stats::Summary| -> Vec<(f64, Interval)> {
        [(s.mean, s.mean_ci), (s.std, s.std_ci)]
            .into_iter()
            .chain(
                s.quantiles
                    .iter()
                    .copied()
                    .zip(s.quantile_ci.iter().copied()),
            )
            .collect()
    };
    let names = statistic_names();
    let per_row: Vec<Vec<(f64, Interval)>> = rows.iter().map(|r| stats(&r.summary)).collect();
    for (k, name) in names.iter().enumerate() {
        f(&mut m, name, per_row.iter().map(|s| s[k].0).collect())?;
        f(
            &mut m,
            &format!("{name}_lo"),
            per_row.iter().map(|s| s[k].1.lo).collect(),
        )?;
        f(
            &mut m,
            &format!("{name}_hi"),
            per_row.iter().map(|s| s[k].1.hi).collect(),
        )?;
    }
    let ex = |g: &dyn Fn(&pino_studies::stats::Exceedance) -> f64| -> Vec<f64> {
        rows.iter()
            .map(|r| r.exceedance.as_ref().map_or(f64::NAN, g))
            .collect()
    };
    f(&mut m, "limit", ex(&|e| e.limit))?;
    f(&mut m, "p_exceed", ex(&|e| e.probability))?;
    f(&mut m, "p_exceed_lo", ex(&|e| e.sampling.lo))?;
    f(&mut m, "p_exceed_hi", ex(&|e| e.sampling.hi))?;
    f(
        &mut m,
        "p_surrogate_lo",
        ex(&|e| e.surrogate.map_or(f64::NAN, |s| s.lo)),
    )?;
    f(
        &mut m,
        "p_surrogate_hi",
        ex(&|e| e.surrogate.map_or(f64::NAN, |s| s.hi)),
    )?;
    pino_data::write_parquet(&out.join("summary.parquet"), &m)?;
    report::csv::write_csv(&out.join(super::MONTE_CARLO_TABLE_FILE), &m).map_err(report_err)
}

/// The histograms with the limits, the exceedance curves (surrogate and solver) and the
/// surrogate against the solver.
fn write_plots(out: &Path, predictor: &Predictor, study: &Study, mc: &MonteCarlo) -> Result<()> {
    let q = quantities(predictor);
    let values: Vec<Vec<f64>> = (0..q.len())
        .map(|j| mc.answers.iter().map(|a| a.indices.values[j]).collect())
        .collect();
    plots::histograms(
        &out.join("histograms.png"),
        &study.name,
        &q,
        &values,
        &mc.limits,
    )
    .map_err(report_err)?;
    let beside: Vec<&DesignAnswer> = mc.checked.iter().map(|&i| &mc.answers[i]).collect();
    let pairs = solver_pairs(q.len(), &beside, &mc.solved);
    let solver: Vec<Vec<f64>> = pairs.iter().map(|(_, v)| v.clone()).collect();
    plots::exceedance_curves(
        &out.join("exceedance.png"),
        &study.name,
        &q,
        &values,
        &solver,
        &mc.limits,
    )
    .map_err(report_err)?;
    plots::surrogate_vs_solver(&out.join(SCATTER_FILE), &study.name, &q, &pairs).map_err(report_err)
}

/// The Markdown summary: what ran, the statistics, the exceedances side by side.
fn summary_markdown(study: &Study, mc: &MonteCarlo, calibrated: bool) -> String {
    let n = mc.designs.len();
    let mut md = format!(
        "# Study `{}`: Monte Carlo, {n} designs\n\n{} designs also through the solver, with the same excitations (the time of each side: `{SPEED_FILE}`).\n{}\n\n",
        study.name,
        mc.checked.len(),
        if calibrated {
            "Surrogate bounds: the fraction of designs whose whole calibrated interval is over the limit, and the fraction whose interval reaches it."
        } else {
            "The model has no calibration: its answers carry no error bar and no surrogate bounds are given."
        }
    );
    let header = [
        "index",
        "source",
        "n",
        "mean",
        "std",
        "q05",
        "q50",
        "q95",
        "q99",
        "limit",
        "P(exceed)",
        "interval",
        "surrogate bounds",
    ];
    let rows: Vec<Vec<String>> = mc
        .summaries
        .iter()
        .map(|r| {
            let s = &r.summary;
            let e = r.exceedance.as_ref();
            vec![
                r.index.clone(),
                r.source.to_owned(),
                s.n.to_string(),
                format!(
                    "{} [{}, {}]",
                    num(s.mean),
                    num(s.mean_ci.lo),
                    num(s.mean_ci.hi)
                ),
                num(s.std),
                num(s.quantiles[0]),
                num(s.quantiles[1]),
                num(s.quantiles[2]),
                num(s.quantiles[3]),
                e.map_or("-".into(), |e| num(e.limit)),
                e.map_or("-".into(), |e| num(e.probability)),
                e.map_or("-".into(), |e| {
                    format!("[{}, {}]", num(e.sampling.lo), num(e.sampling.hi))
                }),
                e.and_then(|e| e.surrogate)
                    .map_or("-".into(), |b| format!("[{}, {}]", num(b.lo), num(b.hi))),
            ]
        })
        .collect();
    md.push_str(&report::markdown::table(&header, &rows));
    md
}
