//! The coverage tables `evaluate` writes (`coverage.{parquet,csv,md}`,
//! `coverage_conditional.{parquet,csv}`) from the rows of [`super::coverage`].

use super::coverage::{ConditionalRow, CoverageRow};
use super::{Calibration, Normaliser, DEFAULT_COVERAGE};
use crate::Result;
use atomic_file::write_atomic;
use pino_data::{write_parquet, Column, Table};
use report::csv::write_csv;
use std::path::Path;

/// Writes the coverage tables of every calibrated model into `out`.
pub fn write_coverage(
    out: &Path,
    calibrations: &[Calibration],
    rows: &[CoverageRow],
    conditional: &[ConditionalRow],
) -> Result<()> {
    let mut t = Table::default();
    let col_s = |f: &dyn Fn(&CoverageRow) -> String| Column::Str(rows.iter().map(f).collect());
    let col_f = |f: &dyn Fn(&CoverageRow) -> f64| Column::F64(rows.iter().map(f).collect());
    let col_i = |f: &dyn Fn(&CoverageRow) -> i64| Column::I64(rows.iter().map(f).collect());
    t.push("algorithm", col_i(&|r| r.algorithm))?;
    t.push("kind", col_s(&|r| r.kind.to_owned()))?;
    t.push("quantity", col_s(&|r| r.quantity.clone()))?;
    t.push("unit", col_s(&|r| r.unit.clone()))?;
    t.push("normaliser", col_s(&|r| r.normaliser.as_str().to_owned()))?;
    t.push(
        "chosen",
        Column::Bool(rows.iter().map(|r| r.chosen).collect()),
    )?;
    t.push("level", col_f(&|r| r.level))?;
    t.push("n_calibration", col_i(&|r| r.n_calibration as i64))?;
    t.push("n_test", col_i(&|r| r.n_test as i64))?;
    t.push("coverage", col_f(&|r| r.coverage))?;
    t.push("mean_width", col_f(&|r| r.mean_width))?;
    t.push("width_over_std", col_f(&|r| r.width_over_std))?;
    write_parquet(&out.join("coverage.parquet"), &t)?;
    write_csv(&out.join("coverage.csv"), &t)?;

    let mut c = Table::default();
    let cs =
        |f: &dyn Fn(&ConditionalRow) -> String| Column::Str(conditional.iter().map(f).collect());
    c.push(
        "algorithm",
        Column::I64(conditional.iter().map(|r| r.algorithm).collect()),
    )?;
    c.push("kind", cs(&|r| r.kind.to_owned()))?;
    c.push("quantity", cs(&|r| r.quantity.clone()))?;
    c.push(
        "level",
        Column::F64(vec![DEFAULT_COVERAGE; conditional.len()]),
    )?;
    c.push("group", cs(&|r| r.group.clone()))?;
    c.push("bin", cs(&|r| r.bin.to_owned()))?;
    c.push(
        "n",
        Column::I64(conditional.iter().map(|r| r.n as i64).collect()),
    )?;
    c.push(
        "coverage",
        Column::F64(conditional.iter().map(|r| r.coverage).collect()),
    )?;
    write_parquet(&out.join("coverage_conditional.parquet"), &c)?;
    write_csv(&out.join("coverage_conditional.csv"), &c)?;

    Ok(write_atomic(
        &out.join("coverage.md"),
        markdown(calibrations, rows, conditional).as_bytes(),
    )?)
}

fn markdown(
    calibrations: &[Calibration],
    rows: &[CoverageRow],
    conditional: &[ConditionalRow],
) -> String {
    let mut md = String::from(
        "# Calibrated intervals on the test split\n\n\
         Split conformal intervals (docs/uncertainty.md) of each model, calibrated on the \
         calibration split and checked here on the test split: `coverage` is the fraction of \
         test samples whose solver value lies inside the interval (a channel: whose whole curve \
         lies inside the band), `width` the mean interval width in the quantity's unit, \
         `width/std` the width over the quantity's spread over the test split (near 4 or more: \
         the interval says little). The guarantee is marginal over the dataset's design \
         distribution; with 100 test samples the coverage itself has a binomial standard \
         error of about 3 points.\n\n",
    );
    for cal in calibrations {
        let alg = cal.model.algorithm;
        md.push_str(&format!("## Algorithm {alg}\n\n"));
        if let Some(why) = &cal.no_intervals {
            md.push_str(&format!("No intervals: {why}.\n\n"));
            continue;
        }
        md.push_str(&format!(
            "{} calibration samples, normaliser `{}` (scales and heads fitted on {} validation samples).\n\n\
             | quantity | kind | unit | coverage 0.8 / 0.9 / 0.95 | width at 0.9 | width/std at 0.9 | coverage 0.9 by difficulty (low / mid / high) |\n\
             |---|---|---|---|---|---|---|\n",
            cal.n,
            cal.normaliser.as_str(),
            cal.n_fit
        ));
        md.push_str(&quantity_rows(alg, rows, conditional));
        md.push_str(&normaliser_rows(cal, rows));
        md.push('\n');
    }
    md.push_str("Per parameter quartile and per difficulty bin: `coverage_conditional.csv`; every normaliser and level: `coverage.csv`.\n");
    md
}

/// The rows of `alg`'s chosen normaliser: per quantity, its coverage at each level, its width
/// and its coverage by difficulty.
fn quantity_rows(alg: i64, rows: &[CoverageRow], conditional: &[ConditionalRow]) -> String {
    let mut md = String::new();
    let own: Vec<&CoverageRow> = rows
        .iter()
        .filter(|r| r.algorithm == alg && r.chosen)
        .collect();
    let mut names: Vec<(&str, &str, &str)> = Vec::new();
    for r in &own {
        if !names
            .iter()
            .any(|(n, k, _)| *n == r.quantity && *k == r.kind)
        {
            names.push((&r.quantity, r.kind, &r.unit));
        }
    }
    for (name, kind, unit) in names {
        let at = |level: f64| {
            own.iter()
                .find(|r| r.quantity == name && r.kind == kind && r.level == level)
        };
        let cov: Vec<String> = [0.8, 0.9, 0.95]
            .iter()
            .map(|&l| at(l).map_or("-".into(), |r| format!("{:.2}", r.coverage)))
            .collect();
        let bins: Vec<String> = ["low", "middle", "high"]
            .iter()
            .map(|b| {
                conditional
                    .iter()
                    .find(|c| {
                        c.algorithm == alg
                            && c.quantity == name
                            && c.kind == kind
                            && c.group == "difficulty"
                            && c.bin == *b
                    })
                    .map_or("-".into(), |c| format!("{:.2}", c.coverage))
            })
            .collect();
        let (w, ws) = at(0.9).map_or(("-".into(), "-".into()), |r| {
            (
                format!("{:.4}", r.mean_width),
                format!("{:.2}", r.width_over_std),
            )
        });
        md.push_str(&format!(
            "| `{name}` | {kind} | {unit} | {} | {w} | {ws} | {} |\n",
            cov.join(" / "),
            bins.join(" / ")
        ));
    }
    md
}

/// Every normaliser of `cal`'s model compared: mean coverage and width over each kind at 0.9.
fn normaliser_rows(cal: &Calibration, rows: &[CoverageRow]) -> String {
    let alg = cal.model.algorithm;
    let mut md = String::new();
    md.push_str("\nNormalisers compared (mean over the quantities of each kind at 0.9):\n\n| normaliser | kind | mean coverage | mean width/std |\n|---|---|---|---|\n");
    for normaliser in Normaliser::ALL {
        for kind in ["index", "channel"] {
            let sel: Vec<&CoverageRow> = rows
                .iter()
                .filter(|r| {
                    r.algorithm == alg
                        && r.normaliser == normaliser
                        && r.kind == kind
                        && r.level == 0.9
                })
                .collect();
            if sel.is_empty() {
                continue;
            }
            let n = sel.len() as f64;
            md.push_str(&format!(
                "| `{}`{} | {kind} | {:.3} | {:.3} |\n",
                normaliser.as_str(),
                if normaliser == cal.normaliser {
                    " (used)"
                } else {
                    ""
                },
                sel.iter().map(|r| r.coverage).sum::<f64>() / n,
                sel.iter()
                    .map(|r| r.width_over_std)
                    .filter(|v| v.is_finite())
                    .sum::<f64>()
                    / n
            ));
        }
    }
    md
}
