//! The files `evaluate` writes for people: Table 4 (Parquet, CSV, Markdown, beside the
//! paper's figures), the prediction speed, the per-channel errors and the plots' legend.

use super::channel_errors::ChannelError;
use super::plots::plot_training_curves;
use super::{EvalOptions, Evaluation, ModelResult, TRUTH_NAME};
use crate::Result;
use atomic_file::write_atomic;
use pino_data::{write_parquet, Column, Table};
use pino_learn::config::Algorithm;
use pino_learn::layout::Layout;
use report::csv::write_csv;
use std::path::Path;

/// Writes what `evaluate` leaves for people: Table 4 (Parquet, CSV, Markdown), the speed
/// figures, the per-channel errors and the plots' legend.
pub(super) fn write_outputs(
    out: &Path,
    ev: &Evaluation,
    layout: &Layout,
    opts: &EvalOptions,
) -> Result<()> {
    let rows = table4_rows(ev, opts);
    let split = ev.scored_on.split().as_str();
    write_table4(out, split, &rows)?;
    write_speed(out, split, &ev.models)?;
    let md = table4_markdown(split, ev.scored_on.note(), &rows, layout);
    write_atomic(&out.join("table4.md"), md.as_bytes())?;
    write_channel_errors(out, &ev.models)?;
    write_plots_doc(out, &ev.models)
}

/// One row of Table 4: the truth (algorithm 0) or a model.
pub(super) struct Table4Row {
    algorithm: i64,
    name: String,
    depth: i64,
    t4: [f64; 3],
    forces: f64,
    peak: f64,
    paper: [f64; 3],
    samples: i64,
}

/// Table 4's rows: the truth first (when scored), then the models.
pub(super) fn table4_rows(ev: &Evaluation, opts: &EvalOptions) -> Vec<Table4Row> {
    let results = &ev.models;
    let mut rows: Vec<Table4Row> = Vec::new();
    if let Some(tr) = ev.truth {
        rows.push(Table4Row {
            algorithm: 0,
            name: TRUTH_NAME.into(),
            depth: 0,
            t4: [tr.table4[0], tr.table4[1], tr.table4[2]],
            forces: tr.table4[3],
            peak: 0.0,
            paper: [f64::NAN; 3],
            samples: tr.samples as i64,
        });
    }
    for r in results {
        let a = r.meta.train.algorithm;
        rows.push(Table4Row {
            algorithm: a.id(),
            name: a.name().to_owned(),
            depth: r.meta.model.depth as i64,
            t4: r.table4,
            forces: r.forces_pct,
            peak: r.peak_force_error_pct_w,
            paper: if opts.compare_with_paper {
                paper_table4(a)
            } else {
                [f64::NAN; 3]
            },
            samples: r.samples as i64,
        });
    }
    rows
}

/// The paper's Table 4 for `algorithm` on its vehicle-track model (solutions, first, second
/// derivatives; relative L2 %), printed beside ours when `compare_with_paper` is on.
pub(super) fn paper_table4(algorithm: Algorithm) -> [f64; 3] {
    match algorithm {
        Algorithm::Fno => [4.24, 13.58, 1404.42],
        Algorithm::Pino => [7.41, 23.06, 202.42],
        Algorithm::PinoMbdWeights => [8.29, 14.90, 20.79],
        Algorithm::PinoMbdDerivatives => [6.75, 6.12, 6.73],
        Algorithm::PinoMbdDerivativesDeep => [6.77, 4.90, 3.20],
    }
}

/// `table4.parquet` and `table4.csv`.
pub(super) fn write_table4(out: &Path, split: &str, rows: &[Table4Row]) -> Result<()> {
    let mut t = Table::default();
    let f = |g: &dyn Fn(&Table4Row) -> f64| Column::F64(rows.iter().map(g).collect());
    t.push(
        "algorithm",
        Column::I64(rows.iter().map(|r| r.algorithm).collect()),
    )?;
    t.push(
        "name",
        Column::Str(rows.iter().map(|r| r.name.clone()).collect()),
    )?;
    t.push("depth", Column::I64(rows.iter().map(|r| r.depth).collect()))?;
    t.push(
        "split",
        Column::Str(rows.iter().map(|_| split.to_owned()).collect()),
    )?;
    t.push("solutions_pct", f(&|r| r.t4[0]))?;
    t.push("first_derivatives_pct", f(&|r| r.t4[1]))?;
    t.push("second_derivatives_pct", f(&|r| r.t4[2]))?;
    t.push("contact_forces_pct", f(&|r| r.forces))?;
    t.push("peak_contact_force_error_pct_w", f(&|r| r.peak))?;
    t.push("paper_solutions_pct", f(&|r| r.paper[0]))?;
    t.push("paper_first_derivatives_pct", f(&|r| r.paper[1]))?;
    t.push("paper_second_derivatives_pct", f(&|r| r.paper[2]))?;
    t.push(
        "samples",
        Column::I64(rows.iter().map(|r| r.samples).collect()),
    )?;
    write_parquet(&out.join("table4.parquet"), &t)?;
    write_csv(&out.join("table4.csv"), &t)?;

    Ok(())
}

/// `table4.md`: the table, a warning when scored on validation, the metric's definition and
/// where the speed figures are.
/// Table 4's note when the dataset has no test split.
pub(super) const FALLBACK_VALIDATION_WARNING: &str =
    "> **WARNING: this dataset has no `test` split, so \
     Table 4 is scored on the `validation` split**, the samples on which training reported \
     progress and settings were chosen: these figures are optimistic. Generate a test split \
     (`sample-params` `n_test`) for an honest table.";

/// Table 4's note when the validation split was asked for (`split: validation`).
pub(super) const ASKED_VALIDATION_NOTE: &str =
    "> Scored on the `validation` split, as asked (`split: \
     validation`): figures to choose settings by; the test split is kept for the final report.";

pub(super) fn table4_markdown(
    split: &str,
    note: Option<&str>,
    rows: &[Table4Row],
    layout: &Layout,
) -> String {
    let n = rows.first().map_or(0, |r| r.samples);
    let mut md = format!("# Table 4: relative L2 error (%) on the {split} split ({n} samples)\n\n");
    if let Some(note) = note {
        md.push_str(note);
        md.push_str("\n\n");
    }
    let cell = |v: f64| {
        if v.is_nan() {
            "-".to_owned()
        } else {
            format!("{v:.2}")
        }
    };
    let dash_if_zero = |v: i64| {
        if v == 0 {
            "-".to_owned()
        } else {
            v.to_string()
        }
    };
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                dash_if_zero(r.algorithm),
                r.name.clone(),
                dash_if_zero(r.depth),
                cell(r.t4[0]),
                cell(r.t4[1]),
                cell(r.t4[2]),
                cell(r.forces),
                cell(r.peak),
                cell(r.paper[0]),
                cell(r.paper[1]),
                cell(r.paper[2]),
            ]
        })
        .collect();
    md.push_str(&report::markdown::table(
        &[
            "Algorithm",
            "Name",
            "Depth",
            "Solutions",
            "First derivatives",
            "Second derivatives",
            "Contact forces",
            "Peak force error (% of W)",
            "Paper: solutions",
            "Paper: first",
            "Paper: second",
        ],
        &cells,
    ));
    let forces = &layout.outputs[layout.forces()];
    md.push_str(&format!(
        "\nMetric: per sample, relative L2 of z-scored values, then the mean over the samples. \
         *Solutions*: the {} displacement channels ({}), as in the paper; the forces ({}), also \
         predicted, are scored in their own column. *First / second derivatives*: central \
         differences of the predicted rigid DOFs ({}) against the solver's exact `_v` / `_a` \
         (interior points). *Peak force error*: per sample and force `|max_t f_pred - max_t \
         f_exact|`, mean over samples and forces, in % of the sample's static contact force \
         (the mean static force of the elements on the moving points: the wheel load W of the \
         vehicle-track model). *{TRUTH_NAME}*: the exact \
         solutions fed through the same metric: 0 on solutions and forces, and the floor any \
         model has on the derivatives at this output rate.\n",
        layout.solutions,
        layout.outputs[..layout.solutions].join(", "),
        if forces.is_empty() {
            "none".to_owned()
        } else {
            forces.join(", ")
        },
        layout.dofs.join(", "),
    ));
    md.push_str(
        "\nPrediction speed (simulated seconds per wall second of forward passes) is in \
         `speed.csv`, the one file of this artifact that depends on the machine.\n",
    );
    md
}

/// `speed.csv`: the wall-clock figures, in their own file so that every other artifact is a
/// pure function of the inputs (byte-identical on a rerun).
pub(super) fn write_speed(out: &Path, split: &str, results: &[ModelResult]) -> Result<()> {
    let mut speed = Table::default();
    speed.push(
        "algorithm",
        Column::I64(
            results
                .iter()
                .map(|r| r.meta.train.algorithm.id())
                .collect(),
        ),
    )?;
    speed.push(
        &format!("{split}_samples"),
        Column::I64(results.iter().map(|r| r.samples as i64).collect()),
    )?;
    speed.push(
        "simulated_s_per_sample",
        Column::F64(
            results
                .iter()
                .map(|r| r.meta.grid.t_points as f64 * r.meta.grid.dt)
                .collect(),
        ),
    )?;
    speed.push(
        "wall_s",
        Column::F64(results.iter().map(|r| r.wall_s).collect()),
    )?;
    speed.push(
        "simulated_s_per_wall_s",
        Column::F64(results.iter().map(|r| r.speed).collect()),
    )?;
    write_csv(&out.join("speed.csv"), &speed)?;
    Ok(())
}

/// `channel_errors.parquet` and `.csv`: every model's relative L2 error per channel.
pub(super) fn write_channel_errors(out: &Path, results: &[ModelResult]) -> Result<()> {
    let mut c = Table::default();
    let rows: Vec<(i64, &ChannelError)> = results
        .iter()
        .flat_map(|r| {
            r.channels
                .iter()
                .map(move |ch| (r.meta.train.algorithm.id(), ch))
        })
        .collect();
    c.push(
        "algorithm",
        Column::I64(rows.iter().map(|(a, _)| *a).collect()),
    )?;
    c.push(
        "channel",
        Column::Str(rows.iter().map(|(_, e)| e.channel.clone()).collect()),
    )?;
    c.push(
        "unit",
        Column::Str(rows.iter().map(|(_, e)| e.unit.to_owned()).collect()),
    )?;
    c.push(
        "rel_l2_pct",
        Column::F64(rows.iter().map(|(_, e)| e.rel_l2_pct).collect()),
    )?;
    c.push(
        "rms_error",
        Column::F64(rows.iter().map(|(_, e)| e.rms_error).collect()),
    )?;
    c.push(
        "rms_exact",
        Column::F64(rows.iter().map(|(_, e)| e.rms_exact).collect()),
    )?;
    c.push(
        "worst_sample_id",
        Column::I64(rows.iter().map(|(_, e)| e.worst_sample).collect()),
    )?;
    c.push(
        "worst_rel_l2_pct",
        Column::F64(rows.iter().map(|(_, e)| e.worst_rel_l2_pct).collect()),
    )?;
    c.push(
        "peak_error_pct_w",
        Column::F64(
            rows.iter()
                .map(|(_, e)| e.peak_error_pct_w.unwrap_or(f64::NAN))
                .collect(),
        ),
    )?;
    write_parquet(&out.join("channel_errors.parquet"), &c)?;
    write_csv(&out.join("channel_errors.csv"), &c)?;

    Ok(())
}

/// `training_curves.png` (when there is history) and `plots.md`, the legend of the plots.
pub(super) fn write_plots_doc(out: &Path, results: &[ModelResult]) -> Result<()> {
    let curves = plot_training_curves(&out.join("training_curves.png"), results)?;
    let mut doc = String::from(
        "# Plots\n\n\
         Each figure has a title and a colour legend at the top; each panel has a title with \
         quantity and unit, numbered ticks on both axes with light grid lines through them, and \
         an x-axis label.\n\n\
         `pred_alg{A}_sample{ID}.png`: scored (test, else validation) sample ID predicted by \
         algorithm A. One row per plotted channel (the stage's `plot_channels`); columns \
         displacement (mm or mrad), velocity (per s), acceleration (per s^2) against time. Black: \
         exact (solver), red: prediction (velocities and accelerations by central differences).\n\n",
    );
    if curves {
        doc.push_str(
            "`training_curves.png`: on a logarithmic axis against epoch, the training loss (top left) and the \
             validation relative L2 of solutions (top right), first derivatives (bottom left) and \
             second derivatives (bottom right). Colours by algorithm: 1 blue, 2 orange, 3 green, \
             4 purple, 5 red.\n",
        );
    }
    write_atomic(&out.join("plots.md"), doc.as_bytes())?;
    Ok(())
}
