//! The PNG plots of `evaluate`: predicted beside exact series of chosen samples and
//! channels, and the training curves.

use crate::channel_errors::unit_of;
use crate::ModelResult;
use crate::Result;
use pino_learn::checkpoint::ModelMeta;
use pino_learn::data::{Dataset, Prepared};
use pino_learn::layout::Layout;
use pino_learn::train::read_history;
use pino_learn::Error as LearnError;
use pino_outputs::indices_eval::alg_label;
use pino_outputs::physical::{exact_physical, Physical};
use report::plot::{write_png, Figure, Panel, Series, BLACK, PALETTE, RED};
use std::path::Path;

pub(super) fn plot_sample(
    path: &Path,
    ds: &Dataset,
    items: &Prepared,
    i: usize,
    pred: &Physical,
    meta: &ModelMeta,
    channels: &[usize],
) -> Result<()> {
    let (s, _) = exact_physical(items, i, &meta.norm)?;
    let id = items.id(i);
    let split = ds.samples[i].split.as_str();
    let t = ds.t_points();
    let (o, d) = (meta.layout.n_outputs(), meta.layout.n_dofs());
    let mut panels = Vec::new();
    // One row per chosen DOF; columns: displacement, velocity, acceleration.
    for &c in channels {
        for (order, quantity) in ["displacement", "velocity", "acceleration"]
            .into_iter()
            .enumerate()
        {
            let name = &meta.layout.dofs[c];
            let (unit, scale) = unit_of(meta.layout.unit(name), order);
            let (exact, p, nch, rows, off) = match order {
                0 => (&s.u, &pred.u, o, t, 0),
                1 => (&s.v, &pred.v, d, t - 2, 1),
                _ => (&s.a, &pred.a, d, t - 2, 1),
            };
            let x: Vec<f64> = (0..rows).map(|r| ds.t[r + off]).collect();
            panels.push(Panel {
                title: format!("{name}: {quantity} ({unit})"),
                xlabel: "t (s)".into(),
                log_y: false,
                series: vec![
                    Series {
                        x: x.clone(),
                        y: (0..rows)
                            .map(|r| scale * exact[(r + off) * nch + c])
                            .collect(),
                        color: BLACK,
                    },
                    Series {
                        x,
                        y: (0..rows).map(|r| scale * p[r * nch + c]).collect(),
                        color: RED,
                    },
                ],
            });
        }
    }
    write_png(
        path,
        &Figure {
            title: format!(
                "{split} sample {id} predicted by algorithm {}",
                alg_label(meta)
            ),
            legend: vec![
                (BLACK, "black: exact (solver)".into()),
                (
                    RED,
                    format!("red: predicted (alg {})", meta.train.algorithm.id()),
                ),
            ],
            rows: channels.len(),
            cols: 3,
            panel: (420, 260),
            panels,
        },
    )?;
    Ok(())
}

pub(super) fn plot_training_curves(path: &Path, results: &[ModelResult]) -> Result<bool> {
    let titles = [
        "training loss",
        "validation rel. L2, solutions",
        "validation rel. L2, first derivatives",
        "validation rel. L2, second derivatives",
    ];
    let mut panels: Vec<Panel> = titles
        .iter()
        .map(|t| Panel {
            title: (*t).into(),
            xlabel: "epoch".into(),
            series: Vec::new(),
            log_y: true,
        })
        .collect();
    let mut legend = Vec::new();
    for r in results {
        let hist_path = r.dir.join(pino_data::artifacts::HISTORY_FILE);
        if !hist_path.is_file() {
            continue;
        }
        let h = read_history(&hist_path)?;
        let color = PALETTE[(r.meta.train.algorithm.id() as usize - 1) % PALETTE.len()];
        legend.push((color, alg_label(&r.meta)));
        let x: Vec<f64> = h.iter().map(|row| row.epoch as f64).collect();
        for (k, f) in [
            |r: &pino_learn::checkpoint::HistoryRow| r.loss_total,
            |r: &pino_learn::checkpoint::HistoryRow| r.val_solution,
            |r: &pino_learn::checkpoint::HistoryRow| r.val_first,
            |r: &pino_learn::checkpoint::HistoryRow| r.val_second,
        ]
        .into_iter()
        .enumerate()
        {
            panels[k].series.push(Series {
                x: x.clone(),
                y: h.iter().map(f).collect(),
                color,
            });
        }
    }
    let any = !legend.is_empty();
    if any {
        write_png(
            path,
            &Figure {
                title: "training history by algorithm".into(),
                legend,
                rows: 2,
                cols: 2,
                panel: (480, 300),
                panels,
            },
        )?;
    }
    Ok(any)
}

/// The rigid DOFs `names` (the stage's `plot_channels`) as positions in `layout`, or an error
/// naming the allowed columns.
pub fn plot_channels(
    names: &[String],
    layout: &Layout,
    system: &mbd_system::System,
) -> Result<Vec<usize>> {
    names
        .iter()
        .map(|name| {
            layout.dofs.iter().position(|d| d == name).ok_or_else(|| {
                LearnError::OutOfRange {
                    field: "plot_channels".into(),
                    value: name.clone(),
                    allowed: format!(
                        "rigid-DOF columns of `{}`: {}",
                        system.name,
                        layout.dofs.join(", ")
                    ),
                }
                .into()
            })
        })
        .collect()
}
