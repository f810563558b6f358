//! The files of a study: every evaluation (`evaluations.parquet`: the design, its excitation
//! id, every index, its interval where calibrated, `extrapolated`, `solver_checked`), the
//! solver's answers beside the surrogate's (`solver.parquet`), the statistics
//! (`summary.{parquet,csv,md}`, one row per index and source) and the timings
//! ([`SPEED_FILE`]: the only file whose bytes differ between two runs). Column units are declared, as in every artifact.

use super::monte_carlo::MonteCarlo;
use super::spec::Study;
use crate::predict::Predictor;
use pino_data::units::{declare, DIMENSIONLESS, PER_ROW, UNIT_KEY};
use pino_data::{Column, Table};
use pino_learn::{Error, Result};
use pino_studies::stats::{Interval, QUANTILES};
use std::path::Path;

/// Column of a design's number in a study.
pub const DESIGN: &str = "design";
/// Column of its excitation id (the profile sample id at the study's seed).
pub const EXCITATION: &str = "excitation";
/// The timings of a study (the only file that differs between two runs of one study).
pub const SPEED_FILE: &str = "speed.csv";
/// Column flagging the designs the solver also answered.
pub const SOLVER_CHECKED: &str = "solver_checked";

fn quantile_name(p: f64) -> String {
    format!("q{:02}", (p * 100.0).round() as i64)
}

/// The summary's statistics, in column order: `mean`, `std`, the quantiles (`q05`, ...).
fn statistic_names() -> Vec<String> {
    ["mean".to_owned(), "std".to_owned()]
        .into_iter()
        .chain(QUANTILES.iter().map(|&p| quantile_name(p)))
        .collect()
}

fn report_err(e: report::Error) -> Error {
    Error::Format {
        path: "study".into(),
        message: e.to_string(),
    }
}

/// Writes a Monte Carlo study's files into `out`.
pub fn write_monte_carlo(
    out: &Path,
    predictor: &Predictor,
    study: &Study,
    mc: &MonteCarlo,
) -> Result<()> {
    let columns = predictor.index_inputs().columns();
    let mut units: Vec<(String, String)> = vec![
        (DESIGN.into(), DIMENSIONLESS.into()),
        (EXCITATION.into(), DIMENSIONLESS.into()),
        (SOLVER_CHECKED.into(), DIMENSIONLESS.into()),
        ("extrapolated".into(), DIMENSIONLESS.into()),
        ("source".into(), DIMENSIONLESS.into()),
        ("index".into(), DIMENSIONLESS.into()),
        ("n".into(), DIMENSIONLESS.into()),
        ("solver_failure".into(), DIMENSIONLESS.into()),
        ("limit".into(), PER_ROW.into()),
        ("p_exceed".into(), DIMENSIONLESS.into()),
    ];
    for c in columns {
        for suffix in ["_lo", "_hi", "_surrogate"] {
            units.push((format!("{}{suffix}", c.name), c.unit.clone()));
        }
    }
    for stat in statistic_names() {
        for suffix in ["", "_lo", "_hi"] {
            units.push((format!("{stat}{suffix}"), PER_ROW.into()));
        }
    }
    for s in [
        "p_exceed_lo",
        "p_exceed_hi",
        "p_surrogate_lo",
        "p_surrogate_hi",
    ] {
        units.push((s.into(), DIMENSIONLESS.into()));
    }
    declare(units.iter().map(|(n, u)| (n.as_str(), u.as_str())))?;

    // Every evaluation.
    let n = mc.designs.len();
    let mut t = Table::default();
    t.push(DESIGN, Column::I64((0..n as i64).collect()))?;
    t.push(
        EXCITATION,
        Column::I64(mc.excitation.iter().map(|&e| e as i64).collect()),
    )?;
    predictor.space.push_columns(&mut t, &mc.designs)?;
    for (j, c) in columns.iter().enumerate() {
        t.push(
            &c.name,
            Column::F64(mc.answers.iter().map(|a| a.indices.values[j]).collect()),
        )?;
    }
    let calibrated = mc.answers.iter().all(|a| a.calibrated.is_some()) && n > 0;
    if calibrated {
        for (j, c) in columns.iter().enumerate() {
            let side = |lo: bool| {
                mc.answers
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
    let outside = predictor.outside_training(&mc.designs);
    t.push(
        "extrapolated",
        Column::I64(outside.iter().map(|o| (!o.is_empty()) as i64).collect()),
    )?;
    let mut checked = vec![0i64; n];
    for &k in &mc.checked {
        checked[k] = 1;
    }
    t.push(SOLVER_CHECKED, Column::I64(checked))?;
    pino_data::write_parquet(&out.join("evaluations.parquet"), &t)?;

    // The solver beside the surrogate.
    let mut s = Table::default();
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
    predictor.space.push_columns(&mut s, &designs)?;
    for (j, c) in columns.iter().enumerate() {
        s.push(
            &c.name,
            Column::F64(mc.solved.iter().map(|x| x.indices[j]).collect()),
        )?;
        s.push(
            &format!("{}_surrogate", c.name),
            Column::F64(
                mc.checked
                    .iter()
                    .map(|&k| mc.answers[k].indices.values[j])
                    .collect(),
            ),
        )?;
    }
    s.push(
        "solver_failure",
        Column::Str(
            mc.solved
                .iter()
                .map(|x| x.failure.clone().unwrap_or_default())
                .collect(),
        ),
    )?;
    pino_data::write_parquet(&out.join("solver.parquet"), &s)?;

    // The statistics.
    let rows = &mc.summaries;
    let mut m = Table::default();
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
    report::csv::write_csv(&out.join("summary.csv"), &m).map_err(report_err)?;
    let checked = mc.checked.len();
    let per = |s: f64, k: usize| if k == 0 { f64::NAN } else { 1e3 * s / k as f64 };
    let (sur_ms, sol_ms) = (per(mc.surrogate_s, n), per(mc.solver_s, checked));
    let speed = format!(
        "side,designs,seconds,ms_per_design\nsurrogate,{n},{:.4},{sur_ms:.4}\nsolver,{checked},{:.4},{sol_ms:.4}\n",
        mc.surrogate_s, mc.solver_s
    );
    report::write_atomic(&out.join(SPEED_FILE), speed.as_bytes()).map_err(report_err)?;
    report::write_atomic(
        &out.join("summary.md"),
        summary_markdown(study, mc, calibrated).as_bytes(),
    )
    .map_err(report_err)?;
    Ok(())
}

fn num(x: f64) -> String {
    if x.is_nan() {
        "-".into()
    } else {
        format!("{x:.4}")
    }
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
