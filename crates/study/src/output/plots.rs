//! The studies' PNG plots, drawn with `report::plot` (polylines only: a bar is its outline,
//! a point a small cross, a limit a vertical or horizontal line; a NaN breaks a polyline).
//!
//! - [`histograms`] (`monte_carlo`): per index, the surrogate's histogram over the designs,
//!   its limit in red.
//! - [`exceedance_curves`] (`monte_carlo`): per limited index, `P(index > x)` against `x`,
//!   surrogate over all designs and solver over the checked ones, the limit in red.
//! - [`sobol_bars`] (`sensitivity`): per index, each factor's total index as a bar with its
//!   bootstrap interval, surrogate and solver side by side, first-order indices as crosses.
//! - [`history`] (`optimise`): the objective of every candidate by start, the best feasible
//!   so far, and each constrained index against its limit.
//! - [`surrogate_vs_solver`] (every kind): per index, the surrogate's answer against the
//!   solver's on the same design and excitation, the equality line in black.
//!
//! Same results, same bytes.

use crate::source;
use report::plot::{write_png, Figure, Panel, Rgb, Series, BLACK, PALETTE, RED};
use std::path::Path;

/// The surrogate's colour.
const SURROGATE: Rgb = PALETTE[0];
/// Bins of a histogram.
const BINS: usize = 30;
/// The size of one panel (pixels).
const PANEL: (usize, usize) = (360, 240);

/// A named quantity: an index's name and unit.
#[derive(Debug, Clone, Copy)]
pub struct Quantity<'a> {
    /// Its name.
    pub name: &'a str,
    /// Its unit.
    pub unit: &'a str,
}

impl Quantity<'_> {
    fn label(&self) -> String {
        if self.unit.is_empty() || self.unit == pino_data::units::DIMENSIONLESS {
            self.name.to_owned()
        } else {
            format!("{} ({})", self.name, self.unit)
        }
    }
}

/// The finite range of `values`, widened when it is one point.
fn range<'a>(values: impl IntoIterator<Item = &'a f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if lo > hi {
        None
    } else if lo == hi {
        let d = if lo == 0.0 { 1.0 } else { 0.05 * lo.abs() };
        Some((lo - d, hi + d))
    } else {
        Some((lo, hi))
    }
}

/// A vertical line at `x` from `y0` to `y1`.
fn vertical(x: f64, y0: f64, y1: f64, color: Rgb) -> Series {
    Series {
        x: vec![x, x],
        y: vec![y0, y1],
        color,
    }
}

/// Crosses at the points `(x, y)`, half-widths `ax`, `ay`.
fn crosses(points: &[(f64, f64)], ax: f64, ay: f64, color: Rgb) -> Series {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for &(px, py) in points
        .iter()
        .filter(|(a, b)| a.is_finite() && b.is_finite())
    {
        for s in [1.0, -1.0] {
            x.extend([px - ax, px + ax, f64::NAN]);
            y.extend([py - s * ay, py + s * ay, f64::NAN]);
        }
    }
    Series { x, y, color }
}

/// Writes `panels` in a grid of at most `cols` columns under `title` and `legend`.
fn figure(
    path: &Path,
    title: String,
    legend: Vec<(Rgb, String)>,
    mut panels: Vec<Panel>,
    cols: usize,
    panel: (usize, usize),
) -> report::Result<()> {
    let cols = cols.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(cols).max(1);
    panels.resize_with(rows * cols, Panel::default);
    write_png(
        path,
        &Figure {
            title,
            legend,
            rows,
            cols,
            panel,
            panels,
        },
    )
}

/// The histogram of `values` over `BINS` bins of `[lo, hi]` as a step outline.
fn histogram(values: &[f64], lo: f64, hi: f64, color: Rgb) -> Series {
    let width = (hi - lo) / BINS as f64;
    let mut counts = [0usize; BINS];
    for &v in values.iter().filter(|v| v.is_finite()) {
        let k = (((v - lo) / width) as usize).min(BINS - 1);
        counts[k] += 1;
    }
    let (mut x, mut y) = (vec![lo], vec![0.0]);
    for (k, &c) in counts.iter().enumerate() {
        let (a, b) = (lo + k as f64 * width, lo + (k + 1) as f64 * width);
        x.extend([a, b]);
        y.extend([c as f64, c as f64]);
    }
    x.push(hi);
    y.push(0.0);
    Series { x, y, color }
}

/// One histogram per index of the surrogate's `values` (index-major), the limit in red.
pub fn histograms(
    path: &Path,
    study: &str,
    quantities: &[Quantity<'_>],
    values: &[Vec<f64>],
    limits: &[Option<f64>],
) -> report::Result<()> {
    let mut panels = Vec::new();
    for ((q, v), limit) in quantities.iter().zip(values).zip(limits) {
        let Some((lo, hi)) = range(v.iter().chain(limit.iter())) else {
            continue;
        };
        let h = histogram(v, lo, hi, SURROGATE);
        let top = h.y.iter().copied().fold(0.0, f64::max);
        let mut series = vec![h];
        if let Some(l) = limit {
            series.push(vertical(*l, 0.0, top, RED));
        }
        panels.push(Panel {
            title: format!("{} designs", v.len()),
            xlabel: q.label(),
            series,
            log_y: false,
        });
    }
    figure(
        path,
        format!("study {study}: the surrogate's answers"),
        vec![(SURROGATE, source::SURROGATE.into()), (RED, "limit".into())],
        panels,
        3,
        PANEL,
    )
}

/// `P(X > x)` of `values` as a step curve (the empirical survival function).
fn survival(values: &[f64], color: Rgb) -> Series {
    let mut v: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let n = v.len() as f64;
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for (k, &a) in v.iter().enumerate() {
        x.extend([a, a]);
        y.extend([(n - k as f64) / n, (n - k as f64 - 1.0) / n]);
    }
    Series { x, y, color }
}

/// Per limited index, the surrogate's exceedance curve over all designs and the solver's
/// over the checked ones (`solver`, index-major), the limit in red.
pub fn exceedance_curves(
    path: &Path,
    study: &str,
    quantities: &[Quantity<'_>],
    surrogate: &[Vec<f64>],
    solver: &[Vec<f64>],
    limits: &[Option<f64>],
) -> report::Result<()> {
    let mut panels = Vec::new();
    for (j, q) in quantities.iter().enumerate() {
        let Some(l) = limits[j] else { continue };
        panels.push(Panel {
            title: format!("P({} > x)", q.name),
            xlabel: format!("x: {}", q.label()),
            series: vec![
                survival(&surrogate[j], SURROGATE),
                survival(&solver[j], BLACK),
                vertical(l, 0.0, 1.0, RED),
            ],
            log_y: false,
        });
    }
    if panels.is_empty() {
        return Ok(());
    }
    figure(
        path,
        format!("study {study}: exceedance curves"),
        vec![
            (SURROGATE, "surrogate, all designs".into()),
            (BLACK, "solver, checked designs".into()),
            (RED, "limit".into()),
        ],
        panels,
        3,
        PANEL,
    )
}

/// One source's Sobol estimates of one index: per factor (first, total, total's interval).
pub type SobolBars = Vec<(f64, f64, [f64; 2])>;

/// Per index, the factors' total indices as bars with their intervals (the surrogate's left,
/// the solver's right of each factor's place) and first-order indices as crosses. `bars`
/// holds per index `(surrogate, solver)`, the solver's empty when it did not run.
pub fn sobol_bars(
    path: &Path,
    study: &str,
    factors: &[String],
    indices: &[&str],
    bars: &[(SobolBars, SobolBars)],
) -> report::Result<()> {
    let key: Vec<String> = factors
        .iter()
        .enumerate()
        .map(|(k, f)| format!("{} {f}", k + 1))
        .collect();
    let mut panels = Vec::new();
    for (name, (surrogate, solver)) in indices.iter().zip(bars) {
        let mut series = Vec::new();
        for (offset, color, estimates) in [(-0.2, SURROGATE, surrogate), (0.2, BLACK, solver)] {
            let (mut x, mut y) = (Vec::new(), Vec::new());
            let mut firsts = Vec::new();
            for (k, &(first, total, [lo, hi])) in estimates.iter().enumerate() {
                let c = (k + 1) as f64 + offset;
                // The bar's outline, then its interval as a whisker.
                x.extend([c - 0.15, c - 0.15, c + 0.15, c + 0.15, f64::NAN]);
                y.extend([0.0, total, total, 0.0, f64::NAN]);
                x.extend([c, c, f64::NAN]);
                y.extend([lo, hi, f64::NAN]);
                firsts.push((c, first));
            }
            series.push(Series { x, y, color });
            series.push(crosses(&firsts, 0.08, 0.02, color));
        }
        panels.push(Panel {
            title: format!("{name}: total (bars, interval) and first-order (x) indices"),
            xlabel: format!("factor: {}", key.join(", ")),
            series,
            log_y: false,
        });
    }
    let width = (8 * 6 * factors.len() + 200).max(PANEL.0);
    figure(
        path,
        format!("study {study}: Sobol indices"),
        vec![
            (SURROGATE, "surrogate, all rows".into()),
            (BLACK, "solver, its rows".into()),
        ],
        panels,
        1,
        (width, PANEL.1),
    )
}

/// One candidate of an optimisation's history, for [`history`].
#[derive(Debug, Clone)]
pub struct Step {
    /// Its start.
    pub start: usize,
    /// The objective's statistic.
    pub objective: f64,
    /// Each constrained index's judged statistic.
    pub constraints: Vec<f64>,
    /// Whether it meets every limit.
    pub feasible: bool,
}

/// The search for `objective` (its description, the figure's title): the objective of every
/// candidate (x: its position in the history) coloured by start, the best feasible objective so far in black; a panel per constraint with its limit
/// in red. `maximise` turns "best" into the largest.
pub fn history(
    path: &Path,
    study: &str,
    objective: &str,
    constraints: &[(Quantity<'_>, f64)],
    steps: &[Step],
    maximise: bool,
) -> report::Result<()> {
    let starts = steps.iter().map(|s| s.start + 1).max().unwrap_or(0);
    let points = |f: &dyn Fn(&Step) -> f64, start: usize| -> Vec<(f64, f64)> {
        steps
            .iter()
            .enumerate()
            .filter(|(_, s)| s.start == start)
            .map(|(k, s)| (k as f64, f(s)))
            .collect()
    };
    let ax = 0.004 * steps.len() as f64;
    let ay = |r: Option<(f64, f64)>| r.map_or(0.0, |(lo, hi)| 0.012 * (hi - lo));
    let objective_range = range(steps.iter().map(|s| &s.objective));
    let mut series: Vec<Series> = (0..starts)
        .map(|s| {
            crosses(
                &points(&|x| x.objective, s),
                ax,
                ay(objective_range),
                PALETTE[(s + 1) % PALETTE.len()],
            )
        })
        .collect();
    let mut best = f64::NAN;
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for (k, s) in steps.iter().enumerate() {
        if s.feasible && s.objective.is_finite() {
            let improves = best.is_nan()
                || (maximise && s.objective > best)
                || (!maximise && s.objective < best);
            if improves {
                best = s.objective;
            }
        }
        x.push(k as f64);
        y.push(best);
    }
    series.push(Series { x, y, color: BLACK });
    let mut panels = vec![Panel {
        title: "objective".into(),
        xlabel: "candidate".into(),
        series,
        log_y: false,
    }];
    for (c, (q, limit)) in constraints.iter().enumerate() {
        let r = range(steps.iter().map(|s| &s.constraints[c]).chain([limit]));
        let mut series: Vec<Series> = (0..starts)
            .map(|s| {
                crosses(
                    &points(&|x| x.constraints[c], s),
                    ax,
                    ay(r),
                    PALETTE[(s + 1) % PALETTE.len()],
                )
            })
            .collect();
        series.push(Series {
            x: vec![0.0, steps.len().saturating_sub(1) as f64],
            y: vec![*limit, *limit],
            color: RED,
        });
        panels.push(Panel {
            title: format!("{} (judged) and its limit", q.name),
            xlabel: "candidate".into(),
            series,
            log_y: false,
        });
    }
    let mut legend: Vec<(Rgb, String)> = (0..starts)
        .map(|s| (PALETTE[(s + 1) % PALETTE.len()], format!("start {s}")))
        .collect();
    legend.push((BLACK, "best feasible so far".into()));
    legend.push((RED, "limit".into()));
    figure(
        path,
        format!("study {study}: {objective}"),
        legend,
        panels,
        2,
        PANEL,
    )
}

/// Per index, the surrogate's answers (y) against the solver's (x) on the same designs and
/// excitations (`pairs`: per index, `(surrogate, solver)` point lists), the equality line
/// in black. Nothing is written when the solver checked nothing.
pub fn surrogate_vs_solver(
    path: &Path,
    study: &str,
    quantities: &[Quantity<'_>],
    pairs: &[(Vec<f64>, Vec<f64>)],
) -> report::Result<()> {
    if pairs.iter().all(|(s, _)| s.is_empty()) {
        return Ok(());
    }
    let mut panels = Vec::new();
    for (q, (surrogate, solver)) in quantities.iter().zip(pairs) {
        let Some((lo, hi)) = range(surrogate.iter().chain(solver)) else {
            continue;
        };
        let points: Vec<(f64, f64)> = solver
            .iter()
            .copied()
            .zip(surrogate.iter().copied())
            .collect();
        let arm = 0.012 * (hi - lo);
        panels.push(Panel {
            title: format!("{}: surrogate (y) vs solver (x)", q.name),
            xlabel: format!("solver {}", q.label()),
            series: vec![
                Series {
                    x: vec![lo, hi],
                    y: vec![lo, hi],
                    color: BLACK,
                },
                crosses(&points, arm, arm, SURROGATE),
            ],
            log_y: false,
        });
    }
    figure(
        path,
        format!("study {study}: surrogate against solver, same designs and excitations"),
        vec![
            (SURROGATE, source::SURROGATE.into()),
            (BLACK, "equality".into()),
        ],
        panels,
        3,
        PANEL,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Decodes a PNG into (width, height, RGB bytes).
    fn pixels(path: &Path) -> (usize, usize, Vec<u8>) {
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        (info.width as usize, info.height as usize, buf)
    }

    fn count(px: &[u8], color: Rgb) -> usize {
        px.chunks(3).filter(|p| *p == color).count()
    }

    #[test]
    fn a_histogram_shows_its_limit_and_the_same_data_gives_the_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let q = [
            Quantity {
                name: "q",
                unit: "1",
            },
            Quantity {
                name: "r",
                unit: "kN",
            },
        ];
        let values = vec![
            (0..500)
                .map(|i| (i as f64 / 500.0).powi(2))
                .collect::<Vec<_>>(),
            (0..500).map(|i| 100.0 + i as f64).collect(),
        ];
        let with = dir.path().join("with.png");
        histograms(&with, "s", &q, &values, &[Some(0.6), None]).unwrap();
        let without = dir.path().join("without.png");
        histograms(&without, "s", &q, &values, &[None, None]).unwrap();
        let (_, _, a) = pixels(&with);
        let (_, _, b) = pixels(&without);
        // The limit line is the only red besides the legend's.
        assert!(
            count(&a, RED) > count(&b, RED) + 50,
            "{} vs {}",
            count(&a, RED),
            count(&b, RED)
        );
        assert!(count(&a, SURROGATE) > 500);
        let again = dir.path().join("again.png");
        histograms(&again, "s", &q, &values, &[Some(0.6), None]).unwrap();
        assert_eq!(
            std::fs::read(&with).unwrap(),
            std::fs::read(&again).unwrap()
        );
    }

    #[test]
    fn the_survival_curve_steps_down_from_one_to_zero() {
        let s = survival(&[3.0, 1.0, f64::NAN, 2.0], BLACK);
        assert_eq!(s.x, [1.0, 1.0, 2.0, 2.0, 3.0, 3.0]);
        let third = 1.0 / 3.0;
        let expected = [1.0, 2.0 * third, 2.0 * third, third, third, 0.0];
        assert!(s.y.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-15));
    }

    #[test]
    fn a_histogram_counts_every_finite_value_once() {
        let v: Vec<f64> = (0..=90)
            .map(|i| i as f64 / 90.0)
            .chain([f64::NAN])
            .collect();
        let h = histogram(&v, 0.0, 1.0, SURROGATE);
        // Bin heights: every other y after the first point (each bin is two points).
        let total: f64 = h.y[1..h.y.len() - 1].iter().step_by(2).sum();
        assert_eq!(total, 91.0);
    }

    #[test]
    fn every_kind_of_plot_is_drawn_and_an_unchecked_study_has_no_scatter() {
        let dir = tempfile::tempdir().unwrap();
        let q = [Quantity {
            name: "q",
            unit: "m",
        }];
        let solver = [(vec![1.0, 2.0, 3.0], vec![1.1, 1.9, 3.2])];
        let scatter = dir.path().join("scatter.png");
        surrogate_vs_solver(&scatter, "s", &q, &solver).unwrap();
        assert!(count(&pixels(&scatter).2, SURROGATE) > 20);
        let none = dir.path().join("none.png");
        surrogate_vs_solver(&none, "s", &q, &[(vec![], vec![])]).unwrap();
        assert!(!none.exists());

        let bars = dir.path().join("bars.png");
        let est: SobolBars = vec![(0.5, 0.6, [0.55, 0.65]), (0.1, 0.2, [0.1, 0.3])];
        sobol_bars(
            &bars,
            "s",
            &["a".into(), "b".into()],
            &["q"],
            &[(est.clone(), est)],
        )
        .unwrap();
        let (_, _, px) = pixels(&bars);
        assert!(count(&px, SURROGATE) > 50 && count(&px, BLACK) > 50);

        let steps: Vec<Step> = (0..40)
            .map(|k| Step {
                start: k % 2,
                objective: 1.0 / (1.0 + k as f64),
                constraints: vec![k as f64 / 40.0],
                feasible: k < 30,
            })
            .collect();
        let h = dir.path().join("history.png");
        history(&h, "s", "q", &[(q[0], 0.75)], &steps, false).unwrap();
        assert!(count(&pixels(&h).2, RED) > 50);
    }
}
