//! A tiny line-plot rasterizer writing PNG (no fonts, no image stack): panels in a grid, each
//! with a frame, a grey zero line, the series as 1-2 px polylines, and its y range printed
//! at the top-left and bottom-left corners in a built-in 3x5 digit font. What each panel and
//! colour means is written next to the image by the caller (see `evaluate`'s `plots.md`).

use crate::{Error, Result};
use std::path::Path;

/// An RGB colour.
pub type Rgb = [u8; 3];
/// Black (exact solution).
pub const BLACK: Rgb = [0, 0, 0];
/// Red (prediction).
pub const RED: Rgb = [220, 40, 40];
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

/// A grid of panels, row-major.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Panel rows.
    pub rows: usize,
    /// Panel columns.
    pub cols: usize,
    /// Panel size in pixels (width, height).
    pub panel: (usize, usize),
    /// Series of each panel (`rows * cols` entries).
    pub panels: Vec<Vec<Series>>,
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

    /// Text in the 3x5 font scaled by 2 (digits, `-`, `.`, `e`, `+`).
    fn text(&mut self, x: i64, y: i64, s: &str, c: Rgb) {
        for (k, ch) in s.chars().enumerate() {
            let Some(g) = glyph(ch) else { continue };
            for (row, bits) in g.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        for (ox, oy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            self.set(x + 8 * k as i64 + 2 * col + ox, y + 2 * row as i64 + oy, c);
                        }
                    }
                }
            }
        }
    }
}

fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '-' => [0, 0, 7, 0, 0],
        '+' => [0, 2, 7, 2, 0],
        '.' => [0, 0, 0, 0, 2],
        'e' => [0, 7, 7, 4, 7],
        _ => return None,
    })
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
    let mut cv = Canvas {
        w: pw * fig.cols,
        h: ph * fig.rows,
        px: vec![255; pw * fig.cols * ph * fig.rows * 3],
    };
    let margin = 24i64;
    for (p, series) in fig.panels.iter().enumerate() {
        let (ox, oy) = ((p % fig.cols * pw) as i64, (p / fig.cols * ph) as i64);
        let (x0, y0, x1, y1) = (
            ox + margin,
            oy + margin,
            ox + pw as i64 - 8,
            oy + ph as i64 - margin,
        );
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
        if ymax - ymin <= 1e-300 {
            ymin -= 1.0;
            ymax += 1.0;
        }
        let pad = 0.05 * (ymax - ymin);
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
        cv.text(x0 + 2, oy + 4, &label(ymax), [60, 60, 60]);
        cv.text(x0 + 2, y1 + 6, &label(ymin), [60, 60, 60]);
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

    #[test]
    fn a_line_plot_is_a_valid_png_with_the_series_colour() {
        let dir = tempfile::tempdir().unwrap();
        let x: Vec<f64> = (0..100).map(|i| i as f64).collect();
        let y: Vec<f64> = x.iter().map(|v| (v / 10.0).sin()).collect();
        let fig = Figure {
            rows: 1,
            cols: 2,
            panel: (200, 120),
            panels: vec![
                vec![Series {
                    x: x.clone(),
                    y,
                    color: RED,
                }],
                vec![],
            ],
        };
        let p = dir.path().join("a.png");
        write_png(&p, &fig).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        let cv = render(&fig);
        assert_eq!((cv.w, cv.h), (400, 120));
        let red = cv.px.chunks(3).filter(|c| *c == RED).count();
        // A 150 px wide curve drawn 2 px thick covers at least 2 * 150 pixels.
        assert!(red >= 300, "{red}");
    }
}
