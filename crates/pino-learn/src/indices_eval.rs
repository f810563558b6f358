//! The engineering indices (`docs/indices.md`, crate `pino-indices`) of the surrogate against
//! the solver, for `evaluate`.
//!
//! Per scored sample and model: the indices of the prediction and of the exact solution,
//! through the same [`pino_indices::compute`] as the `indices` stage. The contact forces are
//! the model's own output channels `p_1..p_4` (predicted directly); accelerations of the
//! prediction are central differences of its displacements, defined on the interior points
//! `1..T-1` of the window, so both sides use those points (the exact side with the solver's
//! exact `_a`). The truth row (algorithm 0) takes the exact displacements through the same
//! central differences: the floor of every model.
//!
//! Written: `indices_errors.{parquet,csv,md}` (per index and algorithm: mean and worst absolute
//! error, mean and worst relative error (%), Pearson correlation), `indices_samples.parquet`
//! (per algorithm and sample: predicted and exact) and `indices_scatter_<index>.png`.

use crate::checkpoint::ModelMeta;
use crate::config::{DOFS, FORCE_OFFSET, OUT_CHANNELS};
use crate::data::{static_wheel_load, Prepared, Split};
use crate::eval::{exact_physical, to_physical, Physical};
use crate::{write_atomic, Error, Result};
use pino_data::{schema, write_parquet, Column, Table};
use pino_indices::{IndexConfig, IndexParams, Indices, Record, INDEX_COLUMNS};
use report::csv::write_csv;
use report::plot::{write_png, Figure, Panel, Series, BLACK, PALETTE, RED};
use std::path::Path;

/// The indices of one model's predictions (or of the truth row) on the scored samples.
#[derive(Debug, Clone)]
pub struct ModelIndices {
    /// Algorithm id (0: the truth row).
    pub algorithm: i64,
    /// Label for tables and plots.
    pub label: String,
    /// Scored sample ids.
    pub ids: Vec<i64>,
    /// Indices of the prediction, per sample.
    pub predicted: Vec<Indices>,
    /// Indices of the solver's solution, per sample.
    pub exact: Vec<Indices>,
}

/// The settings `evaluate` uses: the stage's defaults, with the model's gravity and no
/// start-up (the model's window already dropped it).
pub fn eval_config(meta: &ModelMeta) -> Result<IndexConfig> {
    IndexParams {
        window_start_fraction: 0.0,
        gravity: meta.train.gravity,
        ..IndexParams::default()
    }
    .validate()
    .map_err(|e| Error::OutOfRange {
        field: "indices".into(),
        value: e.to_string(),
        allowed: "valid index parameters".into(),
    })
}

/// Indices of one sample's physical series: outputs `u [T, 18]` (rows `1..T-1` used) and
/// accelerations `acc` (`[T-2, 10]` interior rows when `interior_acc`, else `[T, 10]`).
pub fn indices_of_physical(
    u: &[f64],
    acc: &[f64],
    interior_acc: bool,
    dt: f64,
    params: &[f64; 14],
    cfg: &IndexConfig,
) -> pino_indices::Result<Indices> {
    let t = u.len() / OUT_CHANNELS;
    let rows = 1..t.saturating_sub(1);
    let ucol = |c: usize| -> Vec<f64> { rows.clone().map(|r| u[r * OUT_CHANNELS + c]).collect() };
    let acol = |c: usize| -> Vec<f64> {
        if interior_acc {
            acc.chunks_exact(DOFS).map(|r| r[c]).collect()
        } else {
            rows.clone().map(|r| acc[r * DOFS + c]).collect()
        }
    };
    let p: [Vec<f64>; 4] = std::array::from_fn(|i| ucol(FORCE_OFFSET + i));
    let z_r: [Vec<f64>; 4] = std::array::from_fn(|i| ucol(DOFS + i));
    // Vehicle DOF order: z_c 0, beta_c 1, z_t1 2, beta_t1 3, z_t2 4.
    let (z_c, beta_c, z_t1, z_t2) = (acol(0), acol(1), acol(2), acol(4));
    let rec = Record {
        dt,
        p: std::array::from_fn(|i| p[i].as_slice()),
        z_c_a: &z_c,
        beta_c_a: &beta_c,
        z_t_a: [&z_t1, &z_t2],
        z_r: std::array::from_fn(|i| z_r[i].as_slice()),
    };
    let w = static_wheel_load(params, cfg.gravity);
    let l_c = vtcd::params::SampleParams::from_array(*params).l_c;
    pino_indices::compute(&rec, l_c, w, cfg)
}

fn index_err(items: &Prepared, i: usize, e: pino_indices::Error) -> Error {
    Error::Dataset {
        path: std::path::PathBuf::from("evaluate"),
        message: format!("sample {}: indices: {e}", items.id(i)),
    }
}

/// The indices of one model's predictions `preds` (physical, in `idx` order) and of the
/// exact solutions of samples `idx`.
pub fn model_indices(
    items: &Prepared,
    idx: &[usize],
    preds: &[Physical],
    meta: &ModelMeta,
) -> Result<ModelIndices> {
    let cfg = eval_config(meta)?;
    let dt = meta.grid.dt;
    let mut out = ModelIndices {
        algorithm: meta.train.algorithm.id(),
        label: format!(
            "{} {}, depth {}",
            meta.train.algorithm.id(),
            meta.train.algorithm.name(),
            meta.model.depth
        ),
        ids: Vec::with_capacity(idx.len()),
        predicted: Vec::with_capacity(idx.len()),
        exact: Vec::with_capacity(idx.len()),
    };
    for (k, &i) in idx.iter().enumerate() {
        let (ex, _) = exact_physical(items, i, &meta.norm)?;
        let params = items.params(i);
        let e = indices_of_physical(&ex.u, &ex.a, false, dt, params, &cfg)
            .map_err(|e| index_err(items, i, e))?;
        let p = indices_of_physical(&preds[k].u, &preds[k].a, true, dt, params, &cfg)
            .map_err(|e| index_err(items, i, e))?;
        out.ids.push(items.id(i));
        out.exact.push(e);
        out.predicted.push(p);
    }
    Ok(out)
}

/// The truth row: the exact displacements and forces through the model's central differences
/// (z-score of the exact outputs, then [`to_physical`]).
pub fn truth_indices(items: &Prepared, idx: &[usize], meta: &ModelMeta) -> Result<ModelIndices> {
    let mut preds = Vec::with_capacity(idx.len());
    for &i in idx {
        let s = items.series(i)?;
        preds.push(to_physical(&s.u, meta));
    }
    let mut m = model_indices(items, idx, &preds, meta)?;
    m.algorithm = 0;
    m.label = "truth: exact, central differences".into();
    Ok(m)
}

/// Error statistics of one index for one model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexError {
    /// Mean of `|pred - exact|` (index unit).
    pub mean_abs: f64,
    /// Largest `|pred - exact|`.
    pub worst_abs: f64,
    /// Sample of the largest absolute error.
    pub worst_abs_sample: i64,
    /// Mean of `|pred - exact| / |exact|` (%), over samples with `exact != 0`.
    pub mean_rel_pct: f64,
    /// Largest relative error (%).
    pub worst_rel_pct: f64,
    /// Pearson correlation of predicted and exact over the samples (NaN when either is
    /// constant).
    pub correlation: f64,
    /// Mean of the exact values (for scale).
    pub exact_mean: f64,
}

/// Statistics of `pred` against `exact` (same samples, ids `ids`).
pub fn index_error(pred: &[f64], exact: &[f64], ids: &[i64]) -> IndexError {
    let n = pred.len().max(1) as f64;
    let abs: Vec<f64> = pred.iter().zip(exact).map(|(p, e)| (p - e).abs()).collect();
    let (wa, wa_v) = abs
        .iter()
        .enumerate()
        .fold((0usize, f64::NEG_INFINITY), |b, (i, &v)| {
            if v > b.1 {
                (i, v)
            } else {
                b
            }
        });
    let rels: Vec<f64> = abs
        .iter()
        .zip(exact)
        .filter(|(_, e)| **e != 0.0)
        .map(|(a, e)| 100.0 * a / e.abs())
        .collect();
    let mp = pred.iter().sum::<f64>() / n;
    let me = exact.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (p, e) in pred.iter().zip(exact) {
        sxy += (p - mp) * (e - me);
        sxx += (p - mp) * (p - mp);
        syy += (e - me) * (e - me);
    }
    IndexError {
        mean_abs: abs.iter().sum::<f64>() / n,
        worst_abs: wa_v.max(0.0),
        worst_abs_sample: ids.get(wa).copied().unwrap_or(-1),
        mean_rel_pct: rels.iter().sum::<f64>() / rels.len().max(1) as f64,
        worst_rel_pct: rels.iter().copied().fold(0.0, f64::max),
        correlation: if sxx > 0.0 && syy > 0.0 {
            sxy / (sxx * syy).sqrt()
        } else {
            f64::NAN
        },
        exact_mean: me,
    }
}

/// Writes the index files (module doc) for `models` (the truth row first, then by algorithm)
/// scored on `split`.
pub fn write_indices(out: &Path, split: Split, models: &[ModelIndices]) -> Result<()> {
    // Errors table: one row per (algorithm, index).
    let (mut alg, mut name, mut unit) = (Vec::new(), Vec::new(), Vec::new());
    let mut stats: Vec<IndexError> = Vec::new();
    for m in models {
        for (k, c) in INDEX_COLUMNS.iter().enumerate() {
            let p: Vec<f64> = m.predicted.iter().map(|ix| ix.values()[k]).collect();
            let e: Vec<f64> = m.exact.iter().map(|ix| ix.values()[k]).collect();
            alg.push(m.algorithm);
            name.push(c.name.to_owned());
            unit.push(c.unit.to_owned());
            stats.push(index_error(&p, &e, &m.ids));
        }
    }
    let mut t = Table::default();
    t.push("algorithm", Column::I64(alg.clone()))?;
    t.push("index", Column::Str(name.clone()))?;
    t.push("unit", Column::Str(unit.clone()))?;
    t.push(
        "split",
        Column::Str(alg.iter().map(|_| split.label().to_owned()).collect()),
    )?;
    let f = |g: &dyn Fn(&IndexError) -> f64| Column::F64(stats.iter().map(g).collect());
    t.push("exact_mean", f(&|s| s.exact_mean))?;
    t.push("mean_abs_error", f(&|s| s.mean_abs))?;
    t.push("worst_abs_error", f(&|s| s.worst_abs))?;
    t.push(
        "worst_abs_sample_id",
        Column::I64(stats.iter().map(|s| s.worst_abs_sample).collect()),
    )?;
    t.push("mean_rel_error_pct", f(&|s| s.mean_rel_pct))?;
    t.push("worst_rel_error_pct", f(&|s| s.worst_rel_pct))?;
    t.push("correlation", f(&|s| s.correlation))?;
    write_parquet(&out.join("indices_errors.parquet"), &t)?;
    write_csv(&out.join("indices_errors.csv"), &t)?;

    let n = models.first().map_or(0, |m| m.ids.len());
    let mut md = format!(
        "# Engineering indices: surrogate against solver on the {} split ({n} samples)\n\n\
         Definitions: docs/indices.md. Contact forces are the model's predicted channels \
         `p_1..p_4`; accelerations are central differences of the predicted displacements, so \
         both sides are taken on the interior points of the window (the exact side with the \
         solver's `_a`). Algorithm 0 is the truth row: exact displacements through the same \
         central differences (the floor of every model).\n\n\
         | index | unit | exact mean |",
        split.label()
    );
    for m in models {
        md.push_str(&format!(
            " alg {}: mean abs / worst abs / mean rel % / r |",
            m.algorithm
        ));
    }
    md.push_str("\n|---|---|---|");
    md.push_str(&"---|".repeat(models.len()));
    md.push('\n');
    let cell = |v: f64| {
        if v.is_nan() {
            "-".to_owned()
        } else {
            format!("{v:.4}")
        }
    };
    for (k, c) in INDEX_COLUMNS.iter().enumerate() {
        md.push_str(&format!(
            "| `{}` | {} | {} |",
            c.name,
            c.unit,
            cell(stats.get(k).map_or(f64::NAN, |s| s.exact_mean))
        ));
        for m in 0..models.len() {
            let s = &stats[m * INDEX_COLUMNS.len() + k];
            md.push_str(&format!(
                " {} / {} / {:.2} / {:.3} |",
                cell(s.mean_abs),
                cell(s.worst_abs),
                s.mean_rel_pct,
                s.correlation
            ));
        }
        md.push('\n');
    }
    md.push_str("\nScatter plots: `indices_scatter_<index>.png` (predicted against exact, one panel per algorithm, black line: equality).\n");
    write_atomic(&out.join("indices_errors.md"), md.as_bytes())?;

    // Per-sample values.
    let mut s = Table::default();
    let rows: Vec<(usize, usize)> = models
        .iter()
        .enumerate()
        .flat_map(|(m, mi)| (0..mi.ids.len()).map(move |k| (m, k)))
        .collect();
    s.push(
        "algorithm",
        Column::I64(rows.iter().map(|&(m, _)| models[m].algorithm).collect()),
    )?;
    s.push(
        schema::SAMPLE_ID,
        Column::I64(rows.iter().map(|&(m, k)| models[m].ids[k]).collect()),
    )?;
    for (j, c) in INDEX_COLUMNS.iter().enumerate() {
        s.push(
            c.name,
            Column::F64(
                rows.iter()
                    .map(|&(m, k)| models[m].predicted[k].values()[j])
                    .collect(),
            ),
        )?;
        s.push(
            &format!("{}_exact", c.name),
            Column::F64(
                rows.iter()
                    .map(|&(m, k)| models[m].exact[k].values()[j])
                    .collect(),
            ),
        )?;
    }
    write_parquet(&out.join("indices_samples.parquet"), &s)?;

    for (j, c) in INDEX_COLUMNS.iter().enumerate() {
        scatter(
            &out.join(format!("indices_scatter_{}.png", c.name)),
            j,
            c,
            models,
        )?;
    }
    Ok(())
}

/// One PNG per index: a panel per model, predicted (y) against exact (x), each sample a small
/// cross, the equality line in black.
fn scatter(
    path: &Path,
    j: usize,
    c: &pino_indices::IndexColumn,
    models: &[ModelIndices],
) -> Result<()> {
    let all = models
        .iter()
        .flat_map(|m| m.predicted.iter().chain(&m.exact))
        .map(|ix| ix.values()[j])
        .filter(|v| v.is_finite());
    let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    let (lo, hi) = if lo < hi {
        (lo, hi)
    } else {
        (lo - 1.0, lo + 1.0)
    };
    let arm = 0.012 * (hi - lo);
    let mut panels = Vec::new();
    for mi in models {
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for (p, e) in mi.predicted.iter().zip(&mi.exact) {
            let (px, py) = (e.values()[j], p.values()[j]);
            // A cross: two strokes, each ended by a NaN that breaks the polyline.
            for (dx, dy) in [(arm, arm), (arm, -arm)] {
                x.extend([px - dx, px + dx, f64::NAN]);
                y.extend([py - dy, py + dy, f64::NAN]);
            }
        }
        let color = if mi.algorithm == 0 {
            RED
        } else {
            PALETTE[(mi.algorithm as usize - 1) % PALETTE.len()]
        };
        panels.push(Panel {
            title: if mi.algorithm == 0 {
                mi.label.clone()
            } else {
                format!("alg {}", mi.label)
            },
            xlabel: format!("exact {} ({}) {:.3} - {:.3}", c.name, c.unit, lo, hi),
            series: vec![
                Series {
                    x: vec![lo, hi],
                    y: vec![lo, hi],
                    color: BLACK,
                },
                Series { x, y, color },
            ],
            log_y: false,
        });
    }
    let cols = models.len().clamp(1, 3);
    let rows = models.len().div_ceil(cols).max(1);
    while panels.len() < rows * cols {
        panels.push(Panel::default());
    }
    write_png(
        path,
        &Figure {
            title: format!(
                "{} ({}): {}; predicted (y) against exact (x)",
                c.name, c.unit, c.definition
            ),
            legend: vec![
                (BLACK, "black: predicted = exact".into()),
                (
                    PALETTE[0],
                    "crosses: one scored sample each (colour by algorithm)".into(),
                ),
            ],
            rows,
            cols,
            panel: (360, 300),
            panels,
        },
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::TrainParams;
    use crate::data::{load_dataset, load_split};
    use crate::synthetic::{write_dataset, SyntheticSpec};
    use crate::train::model_meta;

    #[test]
    fn forces_offset_by_5_kn_move_the_peak_force_by_5_kn_and_files_are_written() {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 3,
            n_validation: 1,
            n_test: 2,
            duration: 0.3,
            ..Default::default()
        };
        let files = write_dataset(&spec, dir.path()).unwrap();
        let (m, t, w) = TrainParams::with_algorithm(4).configs().unwrap();
        let sims = std::slice::from_ref(&files.simulation);
        let ds = load_dataset(&files.params, sims, None, &w).unwrap();
        let meta = model_meta(&ds, m, t, w).unwrap();
        let (_, items) = load_split(&files.params, sims, &w, Split::Test, &meta.norm).unwrap();
        let idx: Vec<usize> = (0..items.len()).collect();
        let truth = truth_indices(&items, &idx, &meta).unwrap();
        // The truth row's forces and rail are exact: those indices agree to f32 storage.
        for (p, e) in truth.predicted.iter().zip(&truth.exact) {
            let (pv, ev) = (p.values(), e.values());
            assert!((pv[0] - ev[0]).abs() < 1e-3 * ev[0], "{} {}", pv[0], ev[0]);
            assert!((pv[13] - ev[13]).abs() <= 1e-3 * ev[13].abs().max(1e-6));
            assert_eq!(p.window_s, e.window_s);
        }
        // A prediction: the truth with every contact force raised by 5 kN.
        let preds: Vec<Physical> = idx
            .iter()
            .map(|&i| {
                let mut ph = to_physical(&items.series(i).unwrap().u, &meta);
                for row in ph.u.chunks_exact_mut(OUT_CHANNELS) {
                    for f in &mut row[FORCE_OFFSET..] {
                        *f += 5e3;
                    }
                }
                ph
            })
            .collect();
        let m5 = model_indices(&items, &idx, &preds, &meta).unwrap();
        for (k, (p, t)) in m5.predicted.iter().zip(&truth.predicted).enumerate() {
            assert!((p.peak_wheel_rail_force_kn - t.peak_wheel_rail_force_kn - 5.0).abs() < 1e-9);
            let w = static_wheel_load(items.params(idx[k]), meta.train.gravity);
            let d = t.wheel_load_reduction_rate - p.wheel_load_reduction_rate;
            assert!((d - 5e3 / w).abs() < 1e-12, "{d}");
            assert_eq!(p.sperling_wz, t.sperling_wz);
        }
        let out = dir.path().join("out");
        std::fs::create_dir_all(&out).unwrap();
        write_indices(&out, Split::Test, &[truth, m5]).unwrap();
        let table = pino_data::read_parquet(&out.join("indices_errors.parquet"), None).unwrap();
        assert_eq!(table.num_rows(), 2 * INDEX_COLUMNS.len());
        let mean_abs = table.f64("mean_abs_error").unwrap();
        let peak_row = INDEX_COLUMNS.len(); // algorithm 4, first index
        assert!(
            mean_abs[peak_row] > 4.99 && mean_abs[peak_row] < 5.01,
            "{}",
            mean_abs[peak_row]
        );
        for c in INDEX_COLUMNS {
            assert!(out
                .join(format!("indices_scatter_{}.png", c.name))
                .is_file());
        }
        assert!(
            out.join("indices_errors.md").is_file()
                && out.join("indices_samples.parquet").is_file()
        );
    }

    #[test]
    fn error_statistics_of_known_offsets() {
        let exact = [1.0, 2.0, 4.0];
        let pred = [1.5, 2.0, 3.0];
        let s = index_error(&pred, &exact, &[10, 11, 12]);
        assert!((s.mean_abs - 0.5).abs() < 1e-15);
        assert_eq!((s.worst_abs, s.worst_abs_sample), (1.0, 12));
        assert!((s.mean_rel_pct - 100.0 * (0.5 + 0.0 + 0.25) / 3.0).abs() < 1e-12);
        assert_eq!(s.worst_rel_pct, 50.0);
        let same = index_error(&exact, &exact, &[1, 2, 3]);
        assert!((same.correlation - 1.0).abs() < 1e-15 && same.mean_abs == 0.0);
        let flipped = index_error(&[4.0, 3.0, 1.0], &exact, &[1, 2, 3]);
        assert!(flipped.correlation < -0.9);
        assert!(index_error(&[1.0; 3], &exact, &[1, 2, 3])
            .correlation
            .is_nan());
    }
}
