//! A small line-plot rasterizer writing PNG (no system fonts, no image stack).
//!
//! A figure is a header (title and a colour legend, wrapped to the width) above a grid of
//! panels. Each panel has a title, a frame, numbered ticks on both axes with light grid lines
//! through them, a grey zero line when the y range crosses zero, the series as 2 px polylines
//! (non-finite points break a line), and an x-axis label under the tick labels. Text is the
//! built-in 5x7 bitmap font (printable ASCII), so the images explain themselves.
//!
//! Ticks ([`linear_ticks`]) are "nice numbers": the smallest step `s = m 10^k`, `m` in
//! {1, 2, 5}, that puts at most `max` ticks on `[floor(lo/s) s, ceil(hi/s) s]`; the axis spans
//! exactly that interval, so it covers the data and both ends are labelled. Tick values are
//! computed as `n / 10^-k` from integers (correctly rounded) and printed with `max(0, -k)`
//! decimals, in `1e-5` form below a step of 1e-4 or from 1e6 up: no float noise. On a log
//! axis ([`log_ticks`]) the ticks are the 1-2-5 values of each decade, or whole decades when
//! those are too many, or linear nice values when the range is less than a decade.

use crate::font::{self, glyph};
use crate::{Error, Result};
use std::path::Path;

/// An RGB colour.
pub type Rgb = [u8; 3];
/// Black (exact solution).
pub const BLACK: Rgb = [0, 0, 0];
/// Red (prediction).
pub const RED: Rgb = [220, 40, 40];
/// Colour of titles, axis labels and numbers; distinct from every series colour so that
/// tests can tell text from curves.
pub const TEXT: Rgb = [50, 50, 50];
/// A palette for one line per algorithm (1..5): blue, orange, green, purple, red.
pub const PALETTE: [Rgb; 5] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [148, 103, 189],
    [214, 39, 40],
];
/// Frame and tick marks.
const FRAME: Rgb = [120, 120, 120];
/// Grid lines through the ticks.
const GRID: Rgb = [232, 232, 232];
/// The y = 0 line.
const ZERO: Rgb = [190, 190, 190];

/// One polyline.
#[derive(Debug, Clone)]
pub struct Series {
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates (non-finite values, and values <= 0 on a log axis, break the line).
    pub y: Vec<f64>,
    /// Colour.
    pub color: Rgb,
}

/// One panel: its curves and the text around them.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    /// Printed above the frame (quantity and unit).
    pub title: String,
    /// Printed centred under the x tick labels.
    pub xlabel: String,
    /// Curves.
    pub series: Vec<Series>,
    /// Logarithmic y axis.
    pub log_y: bool,
}

/// A grid of panels, row-major, under a header with the title and the (wrapped) legend.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Figure title (header, left).
    pub title: String,
    /// Legend entries, each drawn as a short line and its label in that colour.
    pub legend: Vec<(Rgb, String)>,
    /// Panel rows.
    pub rows: usize,
    /// Panel columns.
    pub cols: usize,
    /// Panel size in pixels (width, height); at least [`MIN_PANEL`].
    pub panel: (usize, usize),
    /// Panels (at most `rows * cols`; missing ones stay blank).
    pub panels: Vec<Panel>,
}

/// The smallest panel (width, height) in pixels that leaves room for three ticks per axis.
pub const MIN_PANEL: (usize, usize) = (160, 120);

/// Ticks of one axis in axis coordinates (log10 of the value on a log axis). The axis runs
/// from `lo` to `hi`, the first and last ticks.
#[derive(Debug, Clone, PartialEq)]
pub struct Ticks {
    /// Start of the axis (the first tick).
    pub lo: f64,
    /// End of the axis (the last tick).
    pub hi: f64,
    /// Tick positions, increasing.
    pub at: Vec<f64>,
    /// Their labels.
    pub labels: Vec<String>,
}

/// `n 10^k`, correctly rounded for |k| <= 22 (powers of ten are exact there).
fn decimal(n: i64, k: i32) -> f64 {
    if k >= 0 {
        n as f64 * 10f64.powi(k)
    } else {
        n as f64 / 10f64.powi(-k)
    }
}

/// The text of `n 10^k`: fixed with `max(0, -k)` decimals, or `2.5e-5` form when `sci`.
fn decimal_label(n: i64, k: i32, sci: bool) -> String {
    let v = decimal(n, k);
    if !sci {
        format!("{v:.*}", (-k).max(0) as usize)
    } else if n == 0 {
        "0".into()
    } else {
        // Significant digits of n, trailing zeros dropped: 250 -> 2.5e...
        let digits = n.unsigned_abs().to_string();
        let d = digits.trim_end_matches('0').len().max(1) - 1;
        format!("{v:.d$e}")
    }
}

/// A non-empty finite interval around `[lo, hi]`: equal ends are widened by 10 % of their
/// magnitude (by 1 around 0), non-finite ones give `[0, 1]`.
fn widen(lo: f64, hi: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    let (lo, hi) = (lo.min(hi), lo.max(hi));
    if hi - lo > 1e-12 * lo.abs().max(hi.abs()) {
        return (lo, hi);
    }
    let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
    (lo - d, hi + d)
}

/// `q` rounded to the nearest integer when it is one to 1e-9 (a quotient such as 0.3 / 0.1).
fn snap(q: f64) -> f64 {
    let r = q.round();
    if (q - r).abs() <= 1e-9 * r.abs().max(1.0) {
        r
    } else {
        q
    }
}

/// Nice ticks of a linear axis covering `[lo, hi]`, at most `max` of them (at least 3 are
/// allowed for, so that a range around zero always fits).
pub fn linear_ticks(lo: f64, hi: f64, max: usize) -> Ticks {
    let (lo, hi) = widen(lo, hi);
    let max = max.max(3) as f64;
    // The first candidate step is at most the span over max - 1 intervals; 20 x 10^k0 is at
    // least twice that, enough for max >= 3 with a partial interval at each end.
    let k0 = ((hi - lo) / (max - 1.0)).log10().floor() as i32;
    for k in k0..k0 + 3 {
        for m in [1i64, 2, 5] {
            let step = decimal(m, k);
            let (i0, i1) = (snap(lo / step).floor(), snap(hi / step).ceil());
            if i1 - i0 + 1.0 > max {
                continue;
            }
            let ns: Vec<i64> = (i0 as i64..=i1 as i64).map(|i| i * m).collect();
            let big = ns.iter().any(|&n| decimal(n, k).abs() >= 1e6);
            let sci = k < -4 || big;
            let at: Vec<f64> = ns.iter().map(|&n| decimal(n, k)).collect();
            return Ticks {
                lo: at[0],
                hi: at[at.len() - 1],
                labels: ns.iter().map(|&n| decimal_label(n, k, sci)).collect(),
                at,
            };
        }
    }
    // Not reached for finite input (see above); two labelled ends otherwise.
    Ticks {
        lo,
        hi,
        at: vec![lo, hi],
        labels: vec![format!("{lo}"), format!("{hi}")],
    }
}

/// Ticks of a logarithmic axis covering `[lo, hi]` (both > 0), at most `max` of them;
/// positions are log10 of the values, labels the values. Less than a decade: linear nice
/// values (0.6, 0.8, 1.0, ...), placed logarithmically, as long as they stay positive; more:
/// the 1-2-5 values of each decade, or whole decades when those are too many.
pub fn log_ticks(lo: f64, hi: f64, max: usize) -> Ticks {
    let (a, b) = widen(lo.log10(), hi.log10());
    let max = max.max(3);
    if b - a < 1.0 {
        let t = linear_ticks(10f64.powf(a), 10f64.powf(b), max);
        if t.lo > 0.0 {
            return Ticks {
                lo: t.lo.log10(),
                hi: t.hi.log10(),
                at: t.at.iter().map(|v| v.log10()).collect(),
                labels: t.labels,
            };
        }
    }
    // 1-2-5 values of every decade, the axis from the last at or below lo to the first at or
    // above hi.
    let cands: Vec<(i64, i32)> = (a.floor() as i32..=b.ceil() as i32)
        .flat_map(|e| [(1, e), (2, e), (5, e)])
        .collect();
    let pos = |&(m, e): &(i64, i32)| (m as f64).log10() + e as f64;
    let first = cands.iter().rposition(|c| pos(c) <= a + 1e-12).unwrap_or(0);
    let last = cands
        .iter()
        .position(|c| pos(c) >= b - 1e-12)
        .unwrap_or(cands.len() - 1);
    let label = |&(m, e): &(i64, i32)| decimal_label(m, e, !(-4..6).contains(&e));
    let from = |cs: &[(i64, i32)]| Ticks {
        lo: pos(&cs[0]),
        hi: pos(&cs[cs.len() - 1]),
        at: cs.iter().map(pos).collect(),
        labels: cs.iter().map(label).collect(),
    };
    if last - first < max {
        return from(&cands[first..=last]);
    }
    // Whole decades, every one or every 2, 5, 10, ... of them.
    let t = linear_ticks(a, b, max);
    let decades: Vec<(i64, i32)> = if t.at.len() >= 2 && t.at[1] - t.at[0] >= 1.0 {
        t.at.iter().map(|&e| (1, e.round() as i32)).collect()
    } else {
        (a.floor() as i32..=b.ceil() as i32)
            .map(|e| (1, e))
            .collect()
    };
    from(&decades)
}

/// Horizontal glyph pitch: 5 columns plus one of spacing.
const ADVANCE: i64 = font::WIDTH + 1;
/// Text line pitch: 7 rows plus room between lines.
const LINE: i64 = 12;
/// Tick mark length, outside the frame.
const TICK: i64 = 4;
/// Smallest vertical distance between y ticks.
const Y_PITCH: i64 = 28;
/// Smallest horizontal gap between x tick labels.
const X_GAP: i64 = 3 * ADVANCE;
/// Panel margins: above the frame (its title), right of it, below it (tick marks, tick
/// labels, x-axis label).
const TOP: i64 = LINE + 6;
const RIGHT: i64 = 14;
const BOTTOM: i64 = TICK + 3 + font::HEIGHT + 5 + font::HEIGHT + 5;

/// Top-left corners of the legend entries (wrapped to the figure width) and the header
/// height: the title line plus the legend lines.
fn legend_layout(fig: &Figure, width: usize) -> (Vec<(i64, i64)>, usize) {
    let (mut x, mut y) = (8, 4 + LINE);
    let mut at = Vec::new();
    for (_, name) in &fig.legend {
        let w = 20 + text_width(name);
        if x > 8 && x + w > width as i64 - 8 {
            (x, y) = (8, y + LINE);
        }
        at.push((x, y));
        x += w + 3 * ADVANCE;
    }
    let lines = if fig.legend.is_empty() {
        0
    } else {
        (y - 4) / LINE
    };
    (at, (1 + lines as usize) * LINE as usize + 6)
}

/// A rectangle by its corners (x0, y0, x1, y1), in pixels.
type Rect = (i64, i64, i64, i64);

/// Where a panel's axes went: its frame and ticks (read by the tests, which check every tick
/// label at its place).
#[derive(Debug, Clone)]
#[cfg_attr(not(test), allow(dead_code))]
struct Axes {
    frame: Rect,
    x: Ticks,
    y: Ticks,
}

struct Canvas {
    w: usize,
    h: usize,
    px: Vec<u8>,
    /// The axes of each panel with data.
    axes: Vec<Axes>,
}

impl Canvas {
    fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let i = 3 * (y as usize * self.w + x as usize);
            self.px[i..i + 3].copy_from_slice(&c);
        }
    }

    /// Bresenham line, drawn twice (offset by one pixel vertically) for 2 px weight.
    fn line(&mut self, (x0, y0): (i64, i64), (x1, y1): (i64, i64), c: Rgb, thick: bool) {
        let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
        let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
        let (mut x, mut y, mut err) = (x0, y0, dx + dy);
        loop {
            self.set(x, y, c);
            if thick {
                self.set(x, y + 1, c);
            }
            if x == x1 && y == y1 {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += sx;
            }
            if e2 <= dx {
                err += dx;
                y += sy;
            }
        }
    }

    /// A 1 px rectangle.
    fn frame(&mut self, (x0, y0, x1, y1): Rect) {
        let (a, b, c, d) = ((x0, y0), (x1, y0), (x1, y1), (x0, y1));
        for (p, q) in [(a, b), (b, c), (c, d), (d, a)] {
            self.line(p, q, FRAME, false);
        }
    }

    /// Text in the 5x7 font with its top-left corner at (x, y). Characters without a glyph
    /// are drawn as `?` so that a gap never hides a typo.
    fn text(&mut self, x: i64, y: i64, s: &str, c: Rgb) {
        for (k, ch) in s.chars().enumerate() {
            let g = glyph(ch).or_else(|| glyph('?')).unwrap_or_default();
            for (row, bits) in g.iter().enumerate() {
                for col in 0..font::WIDTH {
                    if bits & (0x10 >> col) != 0 {
                        self.set(x + ADVANCE * k as i64 + col, y + row as i64, c);
                    }
                }
            }
        }
    }
}

fn text_width(s: &str) -> i64 {
    (ADVANCE * s.chars().count() as i64 - 1).max(0)
}

/// Range of the finite values (positive ones on a log axis) of one coordinate.
fn range<'a>(values: impl Iterator<Item = &'a f64>, log: bool) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && (!log || **v > 0.0))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    (lo <= hi).then_some((lo, hi))
}

/// Renders a figure to RGB pixels.
fn render(fig: &Figure) -> Result<Canvas> {
    let layout = |message: String| Error::Layout {
        title: fig.title.clone(),
        message,
    };
    if fig.panels.len() > fig.rows * fig.cols {
        return Err(layout(format!(
            "{} panels do not fit a {} x {} grid",
            fig.panels.len(),
            fig.rows,
            fig.cols
        )));
    }
    let (pw, ph) = fig.panel;
    if pw < MIN_PANEL.0 || ph < MIN_PANEL.1 {
        return Err(layout(format!(
            "panel size {pw} x {ph} px is below the minimum {} x {}",
            MIN_PANEL.0, MIN_PANEL.1
        )));
    }
    let (at, header) = legend_layout(fig, pw * fig.cols);
    let (w, h) = (pw * fig.cols, header + ph * fig.rows);
    let mut cv = Canvas {
        w,
        h,
        px: vec![255; w * h * 3],
        axes: Vec::new(),
    };
    cv.text(8, 4, &fig.title, TEXT);
    for ((c, name), &(x, y)) in fig.legend.iter().zip(&at) {
        cv.line((x, y + 3), (x + 16, y + 3), *c, true);
        cv.text(x + 20, y, name, *c);
    }
    for (p, panel) in fig.panels.iter().enumerate() {
        let (ox, oy) = (
            (p % fig.cols * pw) as i64,
            (header + p / fig.cols * ph) as i64,
        );
        draw_panel(&mut cv, panel, (ox, oy), (pw, ph));
    }
    Ok(cv)
}

/// Draws one panel (title, ticks and grid, series, frame, x label) with its top-left corner at
/// `(ox, oy)` and the size `(pw, ph)` px, and records its axes.
fn draw_panel(cv: &mut Canvas, panel: &Panel, (ox, oy): (i64, i64), (pw, ph): (usize, usize)) {
    cv.text(ox + 8, oy + 4, &panel.title, TEXT);
    let (y0, y1) = (oy + TOP, oy + ph as i64 - BOTTOM);
    let xr = range(panel.series.iter().flat_map(|s| &s.x), false);
    let yr = range(panel.series.iter().flat_map(|s| &s.y), panel.log_y);
    let (Some((xmin, xmax)), Some((ymin, ymax))) = (xr, yr) else {
        // Nothing to draw: the frame alone.
        cv.frame((ox + 8, y0, ox + pw as i64 - RIGHT, y1));
        return;
    };
    let max_y = ((y1 - y0) / Y_PITCH).max(3) as usize;
    let yt = if panel.log_y {
        log_ticks(ymin, ymax, max_y)
    } else {
        linear_ticks(ymin, ymax, max_y)
    };
    let label_w = yt.labels.iter().map(|l| text_width(l)).max().unwrap_or(0);
    let (x0, x1) = (ox + 6 + label_w + 3 + TICK, ox + pw as i64 - RIGHT);
    // As many x ticks as their labels leave room for.
    let mut max_x = ((x1 - x0) / 40).max(3) as usize;
    let xt = loop {
        let t = linear_ticks(xmin, xmax, max_x);
        let widest = t.labels.iter().map(|l| text_width(l)).max().unwrap_or(0);
        if max_x <= 3 || t.at.len() as i64 * (widest + X_GAP) <= x1 - x0 {
            break t;
        }
        max_x -= 1;
    };
    let fx = |x: f64| x0 + ((x - xt.lo) / (xt.hi - xt.lo) * (x1 - x0) as f64).round() as i64;
    let fy = |y: f64| y1 - ((y - yt.lo) / (yt.hi - yt.lo) * (y1 - y0) as f64).round() as i64;
    for (&x, l) in xt.at.iter().zip(&xt.labels) {
        let px = fx(x);
        cv.line((px, y0), (px, y1), GRID, false);
        cv.line((px, y1), (px, y1 + TICK), FRAME, false);
        cv.text(px - text_width(l) / 2, y1 + TICK + 3, l, TEXT);
    }
    for (&y, l) in yt.at.iter().zip(&yt.labels) {
        let py = fy(y);
        cv.line((x0, py), (x1, py), GRID, false);
        cv.line((x0 - TICK, py), (x0, py), FRAME, false);
        cv.text(x0 - TICK - 3 - text_width(l), py - 3, l, TEXT);
    }
    if !panel.log_y && yt.lo < 0.0 && yt.hi > 0.0 {
        cv.line((x0, fy(0.0)), (x1, fy(0.0)), ZERO, false);
    }
    for s in &panel.series {
        let mut last: Option<(i64, i64)> = None;
        for (&x, &y) in s.x.iter().zip(&s.y) {
            let y = if panel.log_y { y.log10() } else { y };
            if !(x.is_finite() && y.is_finite()) {
                last = None;
                continue;
            }
            let q = (fx(x), fy(y));
            if let Some(prev) = last {
                cv.line(prev, q, s.color, true);
            }
            last = Some(q);
        }
    }
    cv.frame((x0, y0, x1, y1));
    let xl = (x0 + x1 - text_width(&panel.xlabel)) / 2;
    cv.text(xl, y1 + TICK + 3 + font::HEIGHT + 5, &panel.xlabel, TEXT);
    cv.axes.push(Axes {
        frame: (x0, y0, x1, y1),
        x: xt,
        y: yt,
    });
}

/// Renders and writes a PNG atomically (same figure, same bytes).
pub fn write_png(path: &Path, fig: &Figure) -> Result<()> {
    let cv = render(fig)?;
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, cv.w as u32, cv.h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let fmt = |source| Error::Png {
            path: path.to_owned(),
            source,
        };
        let mut w = enc.write_header().map_err(fmt)?;
        w.write_image_data(&cv.px).map_err(fmt)?;
    }
    Ok(atomic_file::write_atomic(path, &bytes)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(t: &Ticks) -> Vec<&str> {
        t.labels.iter().map(String::as_str).collect()
    }

    #[test]
    fn a_time_axis_gets_half_second_ticks() {
        let t = linear_ticks(0.001, 1.999, 6);
        assert_eq!(t.at, [0.0, 0.5, 1.0, 1.5, 2.0]);
        assert_eq!(labels(&t), ["0.0", "0.5", "1.0", "1.5", "2.0"]);
        assert_eq!((t.lo, t.hi), (0.0, 2.0));
        let epochs = linear_ticks(1.0, 40.0, 8);
        assert_eq!(labels(&epochs), ["0", "10", "20", "30", "40"]);
    }

    #[test]
    fn labels_carry_no_float_noise() {
        // 0.1 * 3 is 0.30000000000000004 in binary; the tick is 3 / 10.
        let t = linear_ticks(0.1, 0.7, 7);
        assert_eq!(
            labels(&t),
            ["0.1", "0.2", "0.3", "0.4", "0.5", "0.6", "0.7"]
        );
        assert_eq!(t.at[2], 0.3);
        let t = linear_ticks(-1.0, 1.0, 5);
        assert_eq!(labels(&t), ["-1.0", "-0.5", "0.0", "0.5", "1.0"]);
        let t = linear_ticks(2e-6, 9e-6, 5);
        assert_eq!(labels(&t), ["2e-6", "4e-6", "6e-6", "8e-6", "1e-5"]);
        let t = linear_ticks(1.5e6, 3e6, 4);
        assert_eq!(labels(&t), ["1.5e6", "2e6", "2.5e6", "3e6"]);
        let t = linear_ticks(-0.07, 0.02, 10);
        assert_eq!(
            labels(&t),
            [
                "-0.07", "-0.06", "-0.05", "-0.04", "-0.03", "-0.02", "-0.01", "0.00", "0.01",
                "0.02"
            ]
        );
        // A flat series still gets an axis around its value; a zero one around zero.
        assert_eq!(
            labels(&linear_ticks(3.0, 3.0, 5)),
            ["2.6", "2.8", "3.0", "3.2", "3.4"]
        );
        assert_eq!(
            labels(&linear_ticks(0.0, 0.0, 5)),
            ["-1.0", "-0.5", "0.0", "0.5", "1.0"]
        );
        assert_eq!(
            labels(&linear_ticks(f64::NAN, 1.0, 3)),
            ["0.0", "0.5", "1.0"]
        );
    }

    /// Deterministic pseudo-random numbers in [0, 1) (64-bit LCG, top 53 bits).
    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn ticks_are_the_smallest_1_2_5_step_covering_the_data() {
        let mut s = 7u64;
        for case in 0..3000 {
            let scale = 10f64.powf(12.0 * lcg(&mut s) - 8.0);
            let lo = scale * (2.0 * lcg(&mut s) - 1.0);
            let hi = lo + scale * (lcg(&mut s) + 1e-3);
            let max = 3 + case % 9;
            let t = linear_ticks(lo, hi, max);
            let n = t.at.len();
            assert!((2..=max).contains(&n), "{lo} {hi} {max}: {n} ticks");
            let step = t.at[1] - t.at[0];
            let tol = 1e-9 * step;
            assert!(t.lo <= lo + tol && t.hi >= hi - tol, "{lo} {hi}: {t:?}");
            assert_eq!((t.lo, t.hi), (t.at[0], t.at[n - 1]));
            // Equal steps of 1, 2 or 5 x 10^k.
            assert!(t
                .at
                .windows(2)
                .all(|w| ((w[1] - w[0]) - step).abs() <= 1e-6 * step));
            let k = (step.log10() + 1e-9).floor();
            let m = (step / 10f64.powf(k)).round();
            assert!([1.0, 2.0, 5.0].contains(&m), "step {step}");
            assert!(
                (m * 10f64.powf(k) - step).abs() <= 1e-6 * step,
                "step {step}"
            );
            // The next smaller nice step would need more than `max` ticks.
            let smaller = match m as i64 {
                1 => 5.0 * 10f64.powf(k - 1.0),
                2 => 10f64.powf(k),
                _ => 2.0 * 10f64.powf(k),
            };
            let count = (hi / smaller - 1e-9).ceil() - (lo / smaller + 1e-9).floor() + 1.0;
            assert!(
                count > max as f64,
                "{lo} {hi} {max}: step {smaller} fits too"
            );
            // Labels read back to their ticks, are distinct and short.
            for (v, l) in t.at.iter().zip(&t.labels) {
                let back: f64 = l.parse().unwrap();
                assert!((back - v).abs() <= tol, "{l} for {v}");
                assert!(l.len() <= 12, "{l}");
                assert!(!(l.starts_with('-') && back == 0.0), "{l}");
            }
            let mut u = t.labels.clone();
            u.dedup();
            assert_eq!(u.len(), n, "{:?}", t.labels);
        }
    }

    #[test]
    fn log_ticks_are_decades_or_1_2_5_values() {
        let t = log_ticks(0.003, 2.0, 8);
        assert_eq!(labels(&t), ["0.001", "0.01", "0.1", "1", "10"]);
        assert_eq!(t.at, [-3.0, -2.0, -1.0, 0.0, 1.0]);
        let t = log_ticks(0.02, 0.3, 8);
        assert_eq!(labels(&t), ["0.02", "0.05", "0.1", "0.2", "0.5"]);
        assert!((t.at[1] - 0.05f64.log10()).abs() < 1e-15);
        // Less than a decade: linear nice values, placed logarithmically.
        let t = log_ticks(0.011, 0.019, 8);
        assert_eq!(
            labels(&t),
            ["0.010", "0.012", "0.014", "0.016", "0.018", "0.020"]
        );
        assert!((t.hi - 0.02f64.log10()).abs() < 1e-15);
        let t = log_ticks(0.63, 1.95, 8);
        assert_eq!(
            labels(&t),
            ["0.6", "0.8", "1.0", "1.2", "1.4", "1.6", "1.8", "2.0"]
        );
        // ... unless they would reach 0: 1-2-5 values then.
        let t = log_ticks(0.15, 1.2, 8);
        assert_eq!(labels(&t), ["0.1", "0.2", "0.5", "1", "2"]);
        // Many decades: every fifth.
        let t = log_ticks(1e-7, 0.1, 4);
        assert_eq!(labels(&t), ["1e-10", "1e-5", "1"]);
        // Covering, increasing.
        for (lo, hi) in [
            (0.003, 2.0),
            (0.02, 0.3),
            (0.011, 0.019),
            (0.15, 1.2),
            (1e-7, 0.1),
            (5.0, 5.0),
        ] {
            let t = log_ticks(lo, hi, 8);
            assert!(
                t.lo <= lo.log10() + 1e-12 && t.hi >= hi.log10() - 1e-12,
                "{lo} {hi}"
            );
            assert!(t.at.windows(2).all(|w| w[0] < w[1]));
        }
    }

    fn sine_figure() -> Figure {
        let x: Vec<f64> = (0..100).map(|i| i as f64 / 50.0).collect();
        let y: Vec<f64> = x.iter().map(|v| (5.0 * v).sin()).collect();
        Figure {
            title: "sample 160, alg 5: PINO-MBD (direct derivatives)".into(),
            legend: vec![
                (BLACK, "exact (solver)".into()),
                (RED, "predicted (alg 5)".into()),
            ],
            rows: 1,
            cols: 2,
            panel: (240, 140),
            panels: vec![
                Panel {
                    title: "car body z_c: displacement (mm)".into(),
                    xlabel: "t (s)".into(),
                    series: vec![Series { x, y, color: RED }],
                    log_y: false,
                },
                Panel::default(),
            ],
        }
    }

    fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
        let mut r = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let mut px = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut px).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        px.truncate(info.buffer_size());
        (info.width, info.height, px)
    }

    #[test]
    fn a_rendered_png_decodes_to_the_figure_and_is_not_blank() {
        let dir = tempfile::tempdir().unwrap();
        let fig = sine_figure();
        let p = dir.path().join("a.png");
        write_png(&p, &fig).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let (w, h, px) = decode(&bytes);
        let header = legend_layout(&fig, 480).1;
        assert_eq!((w as usize, h as usize), (480, header + 140));
        assert_eq!(px, render(&fig).unwrap().px);
        let red = px.chunks(3).filter(|c| *c == RED).count();
        let ink = px.chunks(3).filter(|c| *c != [255, 255, 255]).count();
        // A ~190 px wide curve drawn 2 px thick covers at least 2 * 150 pixels; text, frame
        // and grid add more.
        assert!(red >= 300, "{red}");
        assert!(ink >= red + 1000, "{ink}");
        // Same figure, same bytes.
        write_png(&dir.path().join("b.png"), &fig).unwrap();
        assert_eq!(bytes, std::fs::read(dir.path().join("b.png")).unwrap());
    }

    /// Pixels of colour `c` in the half-open box.
    fn count(cv: &Canvas, (x0, y0, x1, y1): Rect, c: Rgb) -> usize {
        (y0.max(0)..y1.min(cv.h as i64))
            .flat_map(|y| (x0.max(0)..x1.min(cv.w as i64)).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let i = 3 * (y as usize * cv.w + x as usize);
                cv.px[i..i + 3] == c
            })
            .count()
    }

    fn ink(s: &str) -> usize {
        s.chars()
            .map(|c| {
                glyph(c)
                    .unwrap()
                    .iter()
                    .map(|b| b.count_ones() as usize)
                    .sum::<usize>()
            })
            .sum()
    }

    #[test]
    fn every_tick_label_is_drawn_at_its_tick() {
        let mut fig = sine_figure();
        fig.panel = (420, 260);
        let cv = render(&fig).unwrap();
        assert_eq!(cv.axes.len(), 1, "the empty panel has no axes");
        let Axes {
            frame: (x0, y0, x1, y1),
            x: xt,
            y: yt,
        } = cv.axes[0].clone();
        assert_eq!(labels(&xt), ["0.0", "0.5", "1.0", "1.5", "2.0"]);
        assert_eq!(labels(&yt), ["-1.0", "-0.5", "0.0", "0.5", "1.0"]);
        // Each label's box holds exactly the pixels of its glyphs: drawn, and not overlapped.
        for (&x, l) in xt.at.iter().zip(&xt.labels) {
            let px = x0 + ((x - xt.lo) / (xt.hi - xt.lo) * (x1 - x0) as f64).round() as i64;
            let left = px - text_width(l) / 2;
            let top = y1 + TICK + 3;
            let b = (
                left - 2,
                top - 1,
                left + text_width(l) + 2,
                top + font::HEIGHT + 1,
            );
            assert_eq!(count(&cv, b, TEXT), ink(l), "x label {l}");
        }
        for (&y, l) in yt.at.iter().zip(&yt.labels) {
            let py = y1 - ((y - yt.lo) / (yt.hi - yt.lo) * (y1 - y0) as f64).round() as i64;
            let right = x0 - TICK - 3;
            let b = (right - text_width(l) - 2, py - 4, right + 2, py + 5);
            assert_eq!(count(&cv, b, TEXT), ink(l), "y label {l}");
        }
    }

    #[test]
    fn titles_labels_and_legend_are_drawn() {
        let fig = sine_figure();
        let cv = render(&fig).unwrap();
        let header = legend_layout(&fig, cv.w).1 as i64;
        assert_eq!(header, 2 * LINE + 6);
        let w = cv.w as i64;
        let fig_title = count(&cv, (0, 0, w, LINE), TEXT);
        let legend_black = count(&cv, (0, LINE, w, header), BLACK);
        let legend_red = count(&cv, (0, LINE, w, header), RED);
        let title = count(&cv, (0, header, 240, header + LINE), TEXT);
        let xlabel = count(&cv, (0, header + 140 - 15, 240, header + 140), TEXT);
        let empty_panel = count(&cv, (240, header, 480, header + 140), TEXT);
        assert_eq!(fig_title, ink(&fig.title));
        assert_eq!(
            legend_black + legend_red,
            ink("exact (solver)predicted (alg 5)") + 2 * 34
        );
        assert_eq!(title, ink(&fig.panels[0].title));
        assert_eq!(xlabel, ink("t (s)"));
        assert_eq!(empty_panel, 0);
        // A legend too wide for one line wraps and the header grows by a line.
        let mut wide = fig.clone();
        wide.legend = (0..8).map(|k| (PALETTE[k % 5], "x".repeat(30))).collect();
        let (at, h) = legend_layout(&wide, 480);
        assert!(at
            .iter()
            .all(|&(x, _)| x + 20 + text_width(&"x".repeat(30)) <= 480 - 8));
        assert_eq!(h as i64, header + 3 * LINE);
    }

    #[test]
    fn a_log_axis_plots_positive_values_and_breaks_at_the_rest() {
        let x: Vec<f64> = (1..=40).map(f64::from).collect();
        let y: Vec<f64> = x.iter().map(|e| 2.0 * (-e / 8.0).exp()).collect();
        let mut fig = sine_figure();
        fig.panel = (420, 260);
        fig.panels = vec![Panel {
            title: "loss".into(),
            xlabel: "epoch".into(),
            series: vec![Series {
                x: x.clone(),
                y: y.iter()
                    .enumerate()
                    .map(|(i, v)| if i == 20 { 0.0 } else { *v })
                    .collect(),
                color: PALETTE[0],
            }],
            log_y: true,
        }];
        let cv = render(&fig).unwrap();
        let (xt, yt) = (&cv.axes[0].x, &cv.axes[0].y);
        assert_eq!(labels(yt), ["0.01", "0.1", "1", "10"]);
        assert_eq!(xt.labels.first().map(String::as_str), Some("0"));
        assert!(count(&cv, (0, 0, cv.w as i64, cv.h as i64), PALETTE[0]) > 200);
    }

    #[test]
    fn a_figure_that_cannot_be_laid_out_is_an_error() {
        let mut fig = sine_figure();
        fig.panels.push(Panel::default());
        let e = render(&fig).err().unwrap().to_string();
        assert!(e.contains("3 panels do not fit a 1 x 2 grid"), "{e}");
        let mut fig = sine_figure();
        fig.panel = (100, 140);
        let e = render(&fig).err().unwrap().to_string();
        assert!(
            e.contains("panel size 100 x 140 px is below the minimum 160 x 120"),
            "{e}"
        );
    }
}
