//! Evaluation on the validation split: the paper's Table 4, per-channel errors in physical
//! units, prediction speed, and PNG plots.
//!
//! Table 4 (`learning.md`): per algorithm, the mean over validation samples of the relative
//! L2 error (%) of the 14 z-scored solutions, of the 10 vehicle velocities and of the 10
//! vehicle accelerations, both from central differences of the prediction at interior points.
//! Per channel: `||pred - exact|| / ||exact||` in physical units (mean over samples, %), the
//! RMS error in an engineer's unit (mm, mrad, mm/s, mrad/s, m/s^2, rad/s^2) and the worst
//! sample; also the Hertz contact forces `p_1..p_4` (kN) implied by the predicted `z_w - z_r`
//! and the exact irregularity. Speed: simulated seconds (validation samples x window length) per wall second of
//! forward passes.

use crate::checkpoint::{load_model, ModelMeta};
use crate::config::{WindowConfig, DOFS, OUT_CHANNELS};
use crate::data::{load_dataset, make_batch, prepare, Dataset, Split};
use crate::loss::LossContext;
use crate::model::Fno;
use crate::plot::{write_png, Figure, Panel, Series, BLACK, PALETTE, RED};
use crate::spectral::Transform;
use crate::train::{evaluate_split, read_history};
use crate::{write_atomic, Error, Result};
use candle_core::{DType, Device};
use pino_data::{schema, write_parquet, Column, Table};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn d_plots() -> usize {
    2
}
fn d_batch() -> usize {
    8
}
fn d_device() -> crate::config::DeviceKind {
    crate::config::DeviceKind::Cpu
}

/// The `evaluate` stage's parameters as they appear in pipeline.yaml.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalParams {
    /// Validation samples plotted per model.
    #[serde(default = "d_plots")]
    pub plot_samples: usize,
    /// Samples per forward pass.
    #[serde(default = "d_batch")]
    pub batch_size: usize,
    /// "cpu" or "cuda".
    #[serde(default = "d_device")]
    pub device: crate::config::DeviceKind,
}

/// Evaluation settings.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    /// Validation samples plotted per model.
    pub plot_samples: usize,
    /// Samples per forward pass.
    pub batch_size: usize,
    /// Transform implementation.
    pub transform: Transform,
}

/// One channel's error.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelError {
    /// Column name (`z_c`, `z_c_v`, ...).
    pub channel: String,
    /// Unit of the RMS values.
    pub unit: &'static str,
    /// Mean relative L2 (%) in physical units.
    pub rel_l2_pct: f64,
    /// RMS error over all samples and times, in `unit`.
    pub rms_error: f64,
    /// RMS of the exact signal, in `unit`.
    pub rms_exact: f64,
    /// Sample with the largest relative error.
    pub worst_sample: i64,
    /// Its relative error (%).
    pub worst_rel_l2_pct: f64,
}

/// One model's results.
#[derive(Debug, Clone)]
pub struct ModelResult {
    /// Its directory.
    pub dir: PathBuf,
    /// Its metadata.
    pub meta: ModelMeta,
    /// Table 4 values (%): solutions, first, second derivatives.
    pub table4: [f64; 3],
    /// Per-channel errors.
    pub channels: Vec<ChannelError>,
    /// Simulated seconds per wall second of prediction.
    pub speed: f64,
    /// Wall seconds of the forward passes over the validation split.
    pub wall_s: f64,
    /// Validation samples.
    pub samples: usize,
}

/// Display unit and scale of a channel: displacements mm, angles mrad, their rates per s,
/// accelerations SI.
fn unit_of(channel: &str, order: usize) -> (&'static str, f64) {
    let angle = channel.starts_with("beta");
    match (order, angle) {
        (0, false) => ("mm", 1e3),
        (0, true) => ("mrad", 1e3),
        (1, false) => ("mm/s", 1e3),
        (1, true) => ("mrad/s", 1e3),
        (_, false) => ("m/s^2", 1.0),
        (_, true) => ("rad/s^2", 1.0),
    }
}

/// Physical prediction of one sample: solutions `[T, 14]`, and interior velocities and
/// accelerations `[T-2, 10]`.
pub struct Physical {
    /// Solutions.
    pub u: Vec<f64>,
    /// Velocities (interior points).
    pub v: Vec<f64>,
    /// Accelerations (interior points).
    pub a: Vec<f64>,
}

/// De-normalises a z-scored prediction `[T, 14]` and differentiates it (central differences).
pub fn to_physical(u_n: &[f32], meta: &ModelMeta) -> Physical {
    let t = u_n.len() / OUT_CHANNELS;
    let dt = meta.grid.dt;
    let u = meta.norm.outputs.denormalise(u_n);
    let mut v = Vec::with_capacity((t - 2) * DOFS);
    let mut a = Vec::with_capacity((t - 2) * DOFS);
    for n in 1..t - 1 {
        for c in 0..DOFS {
            // Differences of z-scored values times std: the mean cancels exactly.
            let s = meta.norm.outputs.std[c];
            let (p, m, x) = (
                u_n[(n - 1) * OUT_CHANNELS + c] as f64,
                u_n[n * OUT_CHANNELS + c] as f64,
                u_n[(n + 1) * OUT_CHANNELS + c] as f64,
            );
            v.push(s * (x - p) / (2.0 * dt));
            a.push(s * (x - 2.0 * m + p) / (dt * dt));
        }
    }
    Physical { u, v, a }
}

/// Predicts the z-scored solutions `[T, 14]` of every sample in `idx`, returning them with the
/// wall time of the forward passes.
pub fn predict_samples(
    model: &Fno,
    items: &[crate::data::Prepared],
    idx: &[usize],
    t_points: usize,
    batch_size: usize,
    device: &Device,
) -> Result<(Vec<Vec<f32>>, f64)> {
    let mut out = Vec::with_capacity(idx.len());
    let mut wall = 0.0;
    for chunk in idx.chunks(batch_size.max(1)) {
        let batch = make_batch(items, chunk, t_points, device)?;
        let t0 = Instant::now();
        let u = model.forward(&batch.x)?.detach().to_dtype(DType::F32)?;
        let flat: Vec<f32> = u.flatten_all()?.to_vec1()?;
        wall += t0.elapsed().as_secs_f64();
        out.extend(flat.chunks(t_points * OUT_CHANNELS).map(<[f32]>::to_vec));
    }
    Ok((out, wall))
}

fn channel_errors(
    ds: &Dataset,
    val: &[usize],
    preds: &[Physical],
    hertz_g: f64,
) -> Vec<ChannelError> {
    let t = ds.t_points();
    let names = schema::solution_channels();
    let mut out = Vec::new();
    // (order, name, channel count, exact accessor, predicted accessor, first row)
    for order in 0..3 {
        let nch = if order == 0 { OUT_CHANNELS } else { DOFS };
        for c in 0..nch {
            let base = names[c];
            let channel = match order {
                0 => base.to_owned(),
                1 => schema::velocity(base),
                _ => schema::acceleration(base),
            };
            let (unit, scale) = unit_of(base, order);
            let mut rels = Vec::with_capacity(val.len());
            let (mut se, mut sx, mut n) = (0.0, 0.0, 0usize);
            for (k, &i) in val.iter().enumerate() {
                let s = &ds.samples[i];
                let (exact, pred, rows, off): (&[f64], &[f64], usize, usize) = match order {
                    0 => (&s.u, &preds[k].u, t, 0),
                    1 => (&s.v, &preds[k].v, t - 2, 1),
                    _ => (&s.a, &preds[k].a, t - 2, 1),
                };
                let (mut e2, mut x2) = (0.0, 0.0);
                for r in 0..rows {
                    let x = exact[(r + off) * nch + c];
                    let p = pred[r * nch + c];
                    e2 += (p - x) * (p - x);
                    x2 += x * x;
                }
                rels.push(if x2 > 0.0 { (e2 / x2).sqrt() } else { f64::NAN });
                se += e2;
                sx += x2;
                n += rows;
            }
            let (worst, worst_rel) = rels.iter().enumerate().filter(|(_, r)| r.is_finite()).fold(
                (0usize, f64::NEG_INFINITY),
                |(bi, bv), (i, &r)| if r > bv { (i, r) } else { (bi, bv) },
            );
            let finite: Vec<f64> = rels.iter().copied().filter(|r| r.is_finite()).collect();
            out.push(ChannelError {
                channel,
                unit,
                rel_l2_pct: 100.0 * finite.iter().sum::<f64>() / finite.len().max(1) as f64,
                rms_error: scale * (se / n.max(1) as f64).sqrt(),
                rms_exact: scale * (sx / n.max(1) as f64).sqrt(),
                worst_sample: val.get(worst).map(|&i| ds.samples[i].id).unwrap_or(-1),
                worst_rel_l2_pct: 100.0 * worst_rel,
            });
        }
    }
    // Contact forces (kN): Hertz of the predicted against the exact `z_w - z_r - eta`.
    for i in 0..4 {
        let force = |u: &[f64], eta: &[f64], r: usize| {
            let delta =
                u[r * OUT_CHANNELS + 6 + i] - u[r * OUT_CHANNELS + DOFS + i] - eta[r * 4 + i];
            vtcd::contact::contact_force(delta, hertz_g) * 1e-3
        };
        let mut rels = Vec::with_capacity(val.len());
        let (mut se, mut sx) = (0.0, 0.0);
        for (k, &s) in val.iter().enumerate() {
            let smp = &ds.samples[s];
            let (mut e2, mut x2) = (0.0, 0.0);
            for r in 0..t {
                let (x, p) = (force(&smp.u, &smp.eta, r), force(&preds[k].u, &smp.eta, r));
                e2 += (p - x) * (p - x);
                x2 += x * x;
            }
            rels.push((e2 / x2.max(1e-300)).sqrt());
            se += e2;
            sx += x2;
        }
        let (worst, worst_rel) =
            rels.iter()
                .enumerate()
                .fold((0usize, f64::NEG_INFINITY), |(bi, bv), (i, &r)| {
                    if r > bv {
                        (i, r)
                    } else {
                        (bi, bv)
                    }
                });
        let n = (val.len() * t).max(1) as f64;
        out.push(ChannelError {
            channel: schema::CONTACT_FORCES[i].to_owned(),
            unit: "kN",
            rel_l2_pct: 100.0 * rels.iter().sum::<f64>() / rels.len().max(1) as f64,
            rms_error: (se / n).sqrt(),
            rms_exact: (sx / n).sqrt(),
            worst_sample: val.get(worst).map(|&i| ds.samples[i].id).unwrap_or(-1),
            worst_rel_l2_pct: 100.0 * worst_rel,
        });
    }
    out
}

/// "5 PINO-MBD (direct derivatives), depth 5": the depth tells algorithms 4 and 5 apart.
fn alg_label(meta: &ModelMeta) -> String {
    let alg = meta.train.algorithm;
    format!("{} {}, depth {}", alg.id(), alg.name(), meta.model.depth)
}

fn plot_sample(
    path: &Path,
    ds: &Dataset,
    i: usize,
    pred: &Physical,
    meta: &ModelMeta,
) -> Result<()> {
    let s = &ds.samples[i];
    let t = ds.t_points();
    let mut panels = Vec::new();
    // Rows: car body z_c (channel 0), front wheel z_w1 (channel 6); columns: displacement
    // (mm), velocity (mm/s), acceleration (m/s^2).
    for (c, body) in [(0usize, "car body"), (6, "wheel 1")] {
        for (order, quantity) in ["displacement", "velocity", "acceleration"]
            .into_iter()
            .enumerate()
        {
            let name = schema::VEHICLE_DOFS[c];
            let (unit, scale) = unit_of(name, order);
            let (exact, p, nch, rows, off) = match order {
                0 => (&s.u, &pred.u, OUT_CHANNELS, t, 0),
                1 => (&s.v, &pred.v, DOFS, t - 2, 1),
                _ => (&s.a, &pred.a, DOFS, t - 2, 1),
            };
            let x: Vec<f64> = (0..rows).map(|r| ds.t[r + off]).collect();
            let xlabel = format!(
                "t (s) {:.2} - {:.2}",
                x.first().copied().unwrap_or(0.0),
                x.last().copied().unwrap_or(0.0)
            );
            panels.push(Panel {
                title: format!("{body} {name}: {quantity} ({unit})"),
                xlabel,
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
                "validation sample {} predicted by algorithm {}",
                s.id,
                alg_label(meta)
            ),
            legend: vec![
                (BLACK, "black: exact (solver)".into()),
                (
                    RED,
                    format!("red: predicted (alg {})", meta.train.algorithm.id()),
                ),
            ],
            rows: 2,
            cols: 3,
            panel: (420, 260),
            panels,
        },
    )
}

fn plot_training_curves(path: &Path, results: &[ModelResult]) -> Result<bool> {
    let titles = [
        "training loss (log10)",
        "validation rel. L2, solutions (log10)",
        "validation rel. L2, first derivatives (log10)",
        "validation rel. L2, second derivatives (log10)",
    ];
    let mut panels: Vec<Panel> = titles
        .iter()
        .map(|t| Panel {
            title: (*t).into(),
            xlabel: String::new(),
            series: Vec::new(),
        })
        .collect();
    let mut legend = Vec::new();
    let mut epochs = (f64::INFINITY, f64::NEG_INFINITY);
    for r in results {
        let hist_path = r.dir.join("history.parquet");
        if !hist_path.is_file() {
            continue;
        }
        let h = read_history(&hist_path)?;
        let color = PALETTE[(r.meta.train.algorithm.id() as usize - 1) % PALETTE.len()];
        legend.push((color, alg_label(&r.meta)));
        let x: Vec<f64> = h.iter().map(|row| row.epoch as f64).collect();
        for &e in x.first().into_iter().chain(x.last()) {
            epochs = (epochs.0.min(e), epochs.1.max(e));
        }
        let lg = |v: f64| if v > 0.0 { v.log10() } else { f64::NAN };
        for (k, f) in [
            |r: &crate::checkpoint::HistoryRow| r.loss_total,
            |r: &crate::checkpoint::HistoryRow| r.val_solution,
            |r: &crate::checkpoint::HistoryRow| r.val_first,
            |r: &crate::checkpoint::HistoryRow| r.val_second,
        ]
        .into_iter()
        .enumerate()
        {
            panels[k].series.push(Series {
                x: x.clone(),
                y: h.iter().map(|row| lg(f(row))).collect(),
                color,
            });
        }
    }
    let any = !legend.is_empty();
    if any {
        for p in &mut panels {
            p.xlabel = format!("epoch {} - {}", epochs.0, epochs.1);
        }
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

/// Writes a table as CSV (header, then rows; strings quoted when they hold a comma).
pub fn write_csv(path: &Path, t: &Table) -> Result<()> {
    let mut s = t.names().collect::<Vec<_>>().join(",");
    s.push('\n');
    for r in 0..t.num_rows() {
        let cells: Vec<String> = t
            .columns()
            .iter()
            .map(|(_, c)| match c {
                Column::F64(v) => format!("{}", v[r]),
                Column::I64(v) => v[r].to_string(),
                Column::Str(v) if v[r].contains(',') => format!("\"{}\"", v[r]),
                Column::Str(v) => v[r].clone(),
            })
            .collect();
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    write_atomic(path, s.as_bytes())
}

/// Evaluates every model directory on the validation split and writes, into `out`:
/// `table4.{parquet,csv,md}`, `channel_errors.{parquet,csv}`, `pred_alg{A}_sample{ID}.png`,
/// `training_curves.png`, `plots.md` and `speed.csv` (the only machine-dependent file).
pub fn evaluate(
    params_file: &Path,
    simulation_files: &[PathBuf],
    model_dirs: &[PathBuf],
    out: &Path,
    opts: &EvalOptions,
    device: &Device,
    progress: &mut dyn FnMut(usize, &str),
) -> Result<Vec<ModelResult>> {
    let mut results = Vec::new();
    let mut cache: Vec<(WindowConfig, Dataset)> = Vec::new();
    for (m, dir) in model_dirs.iter().enumerate() {
        let (model, meta) = load_model(dir, opts.transform, device)?;
        if !cache.iter().any(|(w, _)| *w == meta.window) {
            let ds = load_dataset(params_file, simulation_files, None, &meta.window)?;
            cache.push((meta.window, ds));
        }
        let ds = &cache
            .iter()
            .find(|(w, _)| *w == meta.window)
            .expect("cached")
            .1;
        if ds.t_points() != meta.grid.t_points || (ds.dt - meta.grid.dt).abs() > 1e-9 * meta.grid.dt
        {
            return Err(Error::Dataset {
                path: simulation_files.first().cloned().unwrap_or_default(),
                message: format!(
                    "model {} was trained on {} points at dt {} s, the dataset window has {} points at dt {} s",
                    dir.display(),
                    meta.grid.t_points,
                    meta.grid.dt,
                    ds.t_points(),
                    ds.dt
                ),
            });
        }
        let val = ds.split_indices(Split::Validation);
        if val.is_empty() {
            return Err(Error::Dataset {
                path: params_file.to_owned(),
                message: "no sample of split `validation`".into(),
            });
        }
        let items = prepare(ds, &meta.norm);
        let ctx = LossContext {
            config: meta.train,
            norm: meta.norm.clone(),
            dt: meta.grid.dt,
            f_ref: meta.f_ref,
        };
        let per = evaluate_split(
            &model,
            &ctx,
            &items,
            &val,
            ds.t_points(),
            opts.batch_size,
            device,
        )?;
        let mean = |v: &[f64]| 100.0 * v.iter().sum::<f64>() / v.len() as f64;
        let table4 = [mean(&per[0]), mean(&per[1]), mean(&per[2])];
        let (preds, wall) =
            predict_samples(&model, &items, &val, ds.t_points(), opts.batch_size, device)?;
        let phys: Vec<Physical> = preds.iter().map(|p| to_physical(p, &meta)).collect();
        let channels = channel_errors(
            ds,
            &val,
            &phys,
            vtcd::contact::hertz_constant(meta.train.wheel_radius),
        );
        let alg = meta.train.algorithm.id();
        for (k, &i) in val.iter().take(opts.plot_samples).enumerate() {
            let id = ds.samples[i].id;
            plot_sample(
                &out.join(format!("pred_alg{alg}_sample{id}.png")),
                ds,
                i,
                &phys[k],
                &meta,
            )?;
        }
        let simulated = val.len() as f64 * ds.t_points() as f64 * ds.dt;
        results.push(ModelResult {
            dir: dir.clone(),
            meta,
            table4,
            channels,
            speed: simulated / wall.max(1e-12),
            wall_s: wall,
            samples: val.len(),
        });
        progress(
            m + 1,
            &format!(
                "algorithm {alg}: {:.2}% / {:.2}% / {:.2}%",
                table4[0], table4[1], table4[2]
            ),
        );
    }
    results.sort_by_key(|r| r.meta.train.algorithm.id());
    write_outputs(out, &results)?;
    Ok(results)
}

fn write_outputs(out: &Path, results: &[ModelResult]) -> Result<()> {
    let mut t = Table::default();
    let f = |g: &dyn Fn(&ModelResult) -> f64| Column::F64(results.iter().map(g).collect());
    t.push(
        "algorithm",
        Column::I64(
            results
                .iter()
                .map(|r| r.meta.train.algorithm.id())
                .collect(),
        ),
    )?;
    t.push(
        "name",
        Column::Str(
            results
                .iter()
                .map(|r| r.meta.train.algorithm.name().to_owned())
                .collect(),
        ),
    )?;
    t.push(
        "depth",
        Column::I64(results.iter().map(|r| r.meta.model.depth as i64).collect()),
    )?;
    t.push("solutions_pct", f(&|r| r.table4[0]))?;
    t.push("first_derivatives_pct", f(&|r| r.table4[1]))?;
    t.push("second_derivatives_pct", f(&|r| r.table4[2]))?;
    t.push(
        "paper_solutions_pct",
        f(&|r| r.meta.train.algorithm.paper_table4()[0]),
    )?;
    t.push(
        "paper_first_derivatives_pct",
        f(&|r| r.meta.train.algorithm.paper_table4()[1]),
    )?;
    t.push(
        "paper_second_derivatives_pct",
        f(&|r| r.meta.train.algorithm.paper_table4()[2]),
    )?;
    t.push(
        "validation_samples",
        Column::I64(results.iter().map(|r| r.samples as i64).collect()),
    )?;
    write_parquet(&out.join("table4.parquet"), &t)?;
    write_csv(&out.join("table4.csv"), &t)?;

    let mut md = String::from(
        "# Table 4: relative L2 error (%) on the validation split\n\n\
         | Algorithm | Name | Depth | Solutions | First derivatives | Second derivatives | Paper: solutions | Paper: first | Paper: second |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        let a = r.meta.train.algorithm;
        let p = a.paper_table4();
        md.push_str(&format!(
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |\n",
            a.id(),
            a.name(),
            r.meta.model.depth,
            r.table4[0],
            r.table4[1],
            r.table4[2],
            p[0],
            p[1],
            p[2]
        ));
    }
    // Wall-clock figures live in their own file so that every other artifact is a pure
    // function of the inputs (byte-identical on a rerun).
    let mut speed = String::from(
        "algorithm,validation_samples,simulated_s_per_sample,wall_s,simulated_s_per_wall_s\n",
    );
    for r in results {
        speed.push_str(&format!(
            "{},{},{},{},{}\n",
            r.meta.train.algorithm.id(),
            r.samples,
            r.meta.grid.t_points as f64 * r.meta.grid.dt,
            r.wall_s,
            r.speed
        ));
    }
    write_atomic(&out.join("speed.csv"), speed.as_bytes())?;
    md.push_str(
        "\nPrediction speed (simulated seconds per wall second of forward passes) is in \
         `speed.csv`, the one file of this artifact that depends on the machine.\n",
    );
    write_atomic(&out.join("table4.md"), md.as_bytes())?;

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
    write_parquet(&out.join("channel_errors.parquet"), &c)?;
    write_csv(&out.join("channel_errors.csv"), &c)?;

    let curves = plot_training_curves(&out.join("training_curves.png"), results)?;
    let mut doc = String::from(
        "# Plots\n\n\
         Each figure has a title and a colour legend at the top; each panel has a title with \
         quantity and unit, an x-axis label with the time or epoch range, and its y range (min, \
         max) printed inside the frame.\n\n\
         `pred_alg{A}_sample{ID}.png`: validation sample ID predicted by algorithm A. Top row car \
         body `z_c`, bottom row front wheel `z_w1`; columns displacement (mm), velocity (mm/s), \
         acceleration (m/s^2) against time. Black: exact (solver), red: prediction (velocities and \
         accelerations by central differences).\n\n",
    );
    if curves {
        doc.push_str(
            "`training_curves.png`: log10 against epoch of the training loss (top left) and of the \
             validation relative L2 of solutions (top right), first derivatives (bottom left) and \
             second derivatives (bottom right). Colours by algorithm: 1 blue, 2 orange, 3 green, \
             4 purple, 5 red.\n",
        );
    }
    write_atomic(&out.join("plots.md"), doc.as_bytes())?;
    Ok(())
}
