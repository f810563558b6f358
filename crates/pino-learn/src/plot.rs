//! A tiny line-plot rasterizer writing PNG (no system fonts, no image stack): a header with
//! the figure title and a colour legend, then panels in a grid, each with a title, a frame, a
//! grey zero line, the series as 2 px polylines, its y range (min, max) inside the frame's
//! top-left and bottom-left corners and an x-axis label underneath. Text uses a built-in 5x7 bitmap font covering
//! printable ASCII, so the images explain themselves without a side file.

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

/// One polyline.
#[derive(Debug, Clone)]
pub struct Series {
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates (non-finite values break the line).
    pub y: Vec<f64>,
    /// Colour.
    pub color: Rgb,
}

/// One panel: its curves and the text around them.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    /// Printed above the frame.
    pub title: String,
    /// Printed centred below the frame.
    pub xlabel: String,
    /// Curves.
    pub series: Vec<Series>,
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
    /// Panel size in pixels (width, height).
    pub panel: (usize, usize),
    /// Panels (`rows * cols` entries).
    pub panels: Vec<Panel>,
}

/// Horizontal glyph pitch: 5 columns plus one of spacing.
const ADVANCE: i64 = 6;
/// Text line pitch: 7 rows plus room between lines.
const LINE: i64 = 12;

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

struct Canvas {
    w: usize,
    h: usize,
    px: Vec<u8>,
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

    /// Text in the 5x7 font with its top-left corner at (x, y); returns the x after it.
    /// Characters without a glyph are drawn as `?` so that a gap never hides a typo.
    fn text(&mut self, x: i64, y: i64, s: &str, c: Rgb) -> i64 {
        let mut cx = x;
        for ch in s.chars() {
            let g = glyph(ch).or_else(|| glyph('?')).unwrap_or_default();
            for (row, bits) in g.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        self.set(cx + col, y + row as i64, c);
                    }
                }
            }
            cx += ADVANCE;
        }
        cx
    }
}

fn text_width(s: &str) -> i64 {
    ADVANCE * s.chars().count() as i64
}

/// The 5x7 font for printable ASCII (0x20..=0x7E): seven rows top to bottom, bit 4 is the
/// leftmost column. Lower-case descenders are folded into the cell to keep one line height.
const FONT: [[u8; 7]; 95] = [
    [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00], // ' '
    [0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x04], // !
    [0x0A, 0x0A, 0x0A, 0x00, 0x00, 0x00, 0x00], // "
    [0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A], // #
    [0x04, 0x0F, 0x14, 0x0E, 0x05, 0x1E, 0x04], // $
    [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03], // %
    [0x0C, 0x12, 0x14, 0x08, 0x15, 0x12, 0x0D], // &
    [0x04, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00], // '
    [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02], // (
    [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08], // )
    [0x00, 0x04, 0x15, 0x0E, 0x15, 0x04, 0x00], // *
    [0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00], // +
    [0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08], // ,
    [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00], // -
    [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C], // .
    [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00], // /
    [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E], // 0
    [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E], // 1
    [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F], // 2
    [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E], // 3
    [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02], // 4
    [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E], // 5
    [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E], // 6
    [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08], // 7
    [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E], // 8
    [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C], // 9
    [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00], // :
    [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x04, 0x08], // ;
    [0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02], // <
    [0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00], // =
    [0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08], // >
    [0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04], // ?
    [0x0E, 0x11, 0x01, 0x0D, 0x15, 0x15, 0x0E], // @
    [0x0E, 0x11, 0x11, 0x11, 0x1F, 0x11, 0x11], // A
    [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E], // B
    [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E], // C
    [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C], // D
    [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F], // E
    [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10], // F
    [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F], // G
    [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11], // H
    [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E], // I
    [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C], // J
    [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11], // K
    [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F], // L
    [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11], // M
    [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11], // N
    [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E], // O
    [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10], // P
    [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D], // Q
    [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11], // R
    [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E], // S
    [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04], // T
    [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E], // U
    [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04], // V
    [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A], // W
    [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11], // X
    [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04], // Y
    [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F], // Z
    [0x0E, 0x08, 0x08, 0x08, 0x08, 0x08, 0x0E], // [
    [0x00, 0x10, 0x08, 0x04, 0x02, 0x01, 0x00], // backslash
    [0x0E, 0x02, 0x02, 0x02, 0x02, 0x02, 0x0E], // ]
    [0x04, 0x0A, 0x11, 0x00, 0x00, 0x00, 0x00], // ^
    [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F], // _
    [0x08, 0x04, 0x02, 0x00, 0x00, 0x00, 0x00], // `
    [0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F], // a
    [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1E], // b
    [0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E], // c
    [0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F], // d
    [0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E], // e
    [0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08], // f
    [0x00, 0x00, 0x0F, 0x11, 0x0F, 0x01, 0x0E], // g
    [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11], // h
    [0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E], // i
    [0x02, 0x00, 0x06, 0x02, 0x02, 0x12, 0x0C], // j
    [0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12], // k
    [0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E], // l
    [0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11], // m
    [0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11], // n
    [0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E], // o
    [0x00, 0x00, 0x1E, 0x11, 0x1E, 0x10, 0x10], // p
    [0x00, 0x00, 0x0D, 0x13, 0x0F, 0x01, 0x01], // q
    [0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10], // r
    [0x00, 0x00, 0x0E, 0x10, 0x0E, 0x01, 0x1E], // s
    [0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06], // t
    [0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0D], // u
    [0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04], // v
    [0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0A], // w
    [0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11], // x
    [0x00, 0x00, 0x11, 0x11, 0x0F, 0x01, 0x0E], // y
    [0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F], // z
    [0x02, 0x04, 0x04, 0x08, 0x04, 0x04, 0x02], // {
    [0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04], // |
    [0x08, 0x04, 0x04, 0x02, 0x04, 0x04, 0x08], // }
    [0x00, 0x00, 0x08, 0x15, 0x02, 0x00, 0x00], // ~
];

fn glyph(c: char) -> Option<[u8; 7]> {
    let i = (c as u32).checked_sub(0x20)? as usize;
    FONT.get(i).copied()
}

fn label(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-2..1e4).contains(&v.abs()) {
        format!("{v:.3}")
    } else {
        format!("{v:.2e}")
    }
}

/// Renders a figure to RGB pixels (`width * height * 3`).
fn render(fig: &Figure) -> Canvas {
    let (pw, ph) = fig.panel;
    let (at, header) = legend_layout(fig, pw * fig.cols);
    let mut cv = Canvas {
        w: pw * fig.cols,
        h: header + ph * fig.rows,
        px: vec![255; pw * fig.cols * (header + ph * fig.rows) * 3],
    };
    cv.text(8, 4, &fig.title, TEXT);
    for ((c, name), &(x, y)) in fig.legend.iter().zip(&at) {
        cv.line((x, y + 3), (x + 16, y + 3), *c, true);
        cv.text(x + 20, y, name, *c);
    }
    // Room for the title above the frame and the x label below it; the y range is printed
    // inside the frame's left edge, so no left margin is needed for it.
    let (top, bottom, side) = (LINE + 6, LINE + 6, 8i64);
    for (p, panel) in fig.panels.iter().enumerate() {
        let series = &panel.series;
        let (ox, oy) = (
            (p % fig.cols * pw) as i64,
            (header + p / fig.cols * ph) as i64,
        );
        let (x0, y0, x1, y1) = (
            ox + side,
            oy + top,
            ox + pw as i64 - side,
            oy + ph as i64 - bottom,
        );
        cv.text(x0, oy + 4, &panel.title, TEXT);
        let xl = (x0 + x1 - text_width(&panel.xlabel)) / 2;
        cv.text(xl, y1 + 5, &panel.xlabel, TEXT);
        let finite = |v: &f64| v.is_finite();
        let xs = series
            .iter()
            .flat_map(|s| s.x.iter().copied())
            .filter(finite);
        let ys = series
            .iter()
            .flat_map(|s| s.y.iter().copied())
            .filter(finite);
        let (xmin, xmax) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        let (mut ymin, mut ymax) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        for (a, b) in [
            ((x0, y0), (x1, y0)),
            ((x1, y0), (x1, y1)),
            ((x1, y1), (x0, y1)),
            ((x0, y1), (x0, y0)),
        ] {
            cv.line(a, b, [120, 120, 120], false);
        }
        if !(xmin.is_finite() && ymin.is_finite()) {
            continue;
        }
        let (ymin_data, ymax_data) = (ymin, ymax);
        if ymax - ymin <= 1e-300 {
            ymin -= 1.0;
            ymax += 1.0;
        }
        // 12 % headroom at both ends keeps the curves clear of the y-range labels.
        let pad = 0.12 * (ymax - ymin);
        let (ylo, yhi) = (ymin - pad, ymax + pad);
        let xspan = if xmax > xmin { xmax - xmin } else { 1.0 };
        let map = |x: f64, y: f64| -> (i64, i64) {
            let px = x0 as f64 + (x - xmin) / xspan * (x1 - x0) as f64;
            let py = y1 as f64 - (y - ylo) / (yhi - ylo) * (y1 - y0) as f64;
            (px.round() as i64, py.round() as i64)
        };
        if ylo < 0.0 && yhi > 0.0 {
            let (_, zy) = map(xmin, 0.0);
            cv.line((x0, zy), (x1, zy), [200, 200, 200], false);
        }
        for s in series {
            let mut last: Option<(i64, i64)> = None;
            for (&x, &y) in s.x.iter().zip(&s.y) {
                if !(x.is_finite() && y.is_finite()) {
                    last = None;
                    continue;
                }
                let q = map(x, y);
                if let Some(prev) = last {
                    cv.line(prev, q, s.color, true);
                }
                last = Some(q);
            }
        }
        cv.text(x0 + 3, y0 + 3, &format!("max {}", label(ymax_data)), TEXT);
        cv.text(x0 + 3, y1 - 9, &format!("min {}", label(ymin_data)), TEXT);
    }
    cv
}

/// Renders and writes a PNG atomically (same figure, same bytes).
pub fn write_png(path: &Path, fig: &Figure) -> Result<()> {
    let cv = render(fig);
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, cv.w as u32, cv.h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let fmt = |e: png::EncodingError| Error::Format {
            path: path.to_owned(),
            message: format!("png: {e}"),
        };
        let mut w = enc.write_header().map_err(fmt)?;
        w.write_image_data(&cv.px).map_err(fmt)?;
    }
    crate::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

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
                    xlabel: "t (s) 0.00 - 1.98".into(),
                    series: vec![Series { x, y, color: RED }],
                },
                Panel::default(),
            ],
        }
    }

    #[test]
    fn a_line_plot_is_a_valid_png_with_the_series_colour() {
        let dir = tempfile::tempdir().unwrap();
        let fig = sine_figure();
        let p = dir.path().join("a.png");
        write_png(&p, &fig).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        let cv = render(&fig);
        let header = legend_layout(&fig, 480).1;
        assert_eq!((cv.w, cv.h), (480, header + 140));
        let red = cv.px.chunks(3).filter(|c| *c == RED).count();
        // A ~220 px wide curve drawn 2 px thick covers at least 2 * 200 pixels.
        assert!(red >= 400, "{red}");
        // Same figure, same bytes.
        write_png(&dir.path().join("b.png"), &fig).unwrap();
        assert_eq!(bytes, std::fs::read(dir.path().join("b.png")).unwrap());
    }

    #[test]
    fn every_printable_ascii_character_has_a_glyph() {
        for c in ' '..='~' {
            assert!(glyph(c).is_some(), "{c:?}");
        }
        assert!(glyph('\u{7f}').is_none() && glyph('\n').is_none());
        // Distinct shapes for everything but the space (a copy-paste slip would duplicate one).
        let mut seen: Vec<[u8; 7]> = FONT[1..].to_vec();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), FONT.len() - 1);
        // Every glyph fits the 5 columns.
        assert!(FONT.iter().flatten().all(|&b| b < 0x20));
    }

    #[test]
    fn titles_labels_and_legend_are_drawn() {
        let fig = sine_figure();
        let cv = render(&fig);
        let header = legend_layout(&fig, cv.w).1;
        assert_eq!(header, 2 * LINE as usize + 6);
        let count = |x0: usize, x1: usize, y0: usize, y1: usize, c: Rgb| {
            (y0..y1)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .filter(|&(x, y)| {
                    let i = 3 * (y * cv.w + x);
                    cv.px[i..i + 3] == c
                })
                .count()
        };
        let fig_title = count(0, cv.w, 0, LINE as usize, TEXT);
        let legend_black = count(0, cv.w, LINE as usize, header, BLACK);
        let legend_red = count(0, cv.w, LINE as usize, header, RED);
        let title = count(0, 240, header, header + LINE as usize + 4, TEXT);
        let xlabel = count(0, 240, header + 140 - LINE as usize - 2, header + 140, TEXT);
        let empty_title = count(240, 480, header, header + LINE as usize + 4, TEXT);
        // Each drawn character sets several pixels; an empty string sets none.
        assert!(fig_title > 100, "{fig_title}");
        assert!(
            legend_black > 50 && legend_red > 50,
            "{legend_black} {legend_red}"
        );
        assert!(title > 80, "{title}");
        assert!(xlabel > 40, "{xlabel}");
        assert_eq!(empty_title, 0);
        // A legend too wide for one line wraps and the header grows by a line.
        let mut wide = fig.clone();
        wide.legend = (0..8).map(|k| (PALETTE[k % 5], "x".repeat(30))).collect();
        let (at, h) = legend_layout(&wide, 480);
        assert!(at.iter().all(|&(x, _)| x + 20 + 6 * 30 <= 480 - 8));
        assert_eq!(h, header + 3 * LINE as usize);
    }
}
