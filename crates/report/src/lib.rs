//! Reporting for pino-mbd: what a stage writes for people to read, kept apart from the
//! computations that produce the numbers.
//!
//! - [`plot`]: line plots written as PNG, panels in a grid, each with numbered axis ticks
//!   ([`plot::linear_ticks`], [`plot::log_ticks`]: steps of 1, 2 or 5 x 10^k, labels
//!   without float noise), light grid lines, a title, an x-axis label and a colour legend.
//!   Text uses a built-in 5x7 bitmap font, so nothing is read from the system.
//! - [`csv`]: a [`pino_data::Table`] as CSV, through the `csv` crate (RFC 4180 quoting of
//!   commas, quotes and line breaks).
//! - [`markdown`]: Markdown tables with `|` escaped in cells.
//!
//! Every file goes through [`atomic_file`]: same input, same bytes, never a partial file.
//!
//! Why a hand-written rasterizer and not `plotters` (measured in BENCHMARKS.md, Reports):
//! plotters' default text needs system fonts through font-kit (freetype and fontconfig, C
//! libraries a fresh machine may lack); its pure-Rust route (`ab_glyph`) needs a TTF shipped
//! in the repository with its licence (DejaVu Sans: 740 KB). That minimal build (bitmap
//! backend, line series, ab_glyph) costs 12 s of CPU per cold build profile and 3.3 MB per
//! plotting binary, and its default axes still clip the curves (no covering "nice" range) and
//! print labels such as `-0.0` and `15000.0`, so the nice-number and label code below would be
//! needed anyway. It would save about 400 lines here (590 lines of rasterizer, font and ticks
//! against an estimated 150-200 of plotters set-up); for that price the figures gain
//! anti-aliased text and nothing a reader needs: both draw numbered ticks on every axis.
//!
//! ```
//! # let dir = tempfile::tempdir().unwrap();
//! use report::plot::{write_png, Figure, Panel, Series, BLACK};
//! let x: Vec<f64> = (0..50).map(|i| i as f64 * 0.02).collect();
//! let fig = Figure {
//!     title: "a sine".into(),
//!     legend: vec![(BLACK, "sin(2 pi t)".into())],
//!     rows: 1,
//!     cols: 1,
//!     panel: (320, 200),
//!     panels: vec![Panel {
//!         title: "y (m)".into(),
//!         xlabel: "t (s)".into(),
//!         series: vec![Series { y: x.iter().map(|t| (6.283 * t).sin()).collect(), x, color: BLACK }],
//!         log_y: false,
//!     }],
//! };
//! write_png(&dir.path().join("sine.png"), &fig)?;
//! # Ok::<(), report::Error>(())
//! ```
#![warn(missing_docs)]

pub mod csv;
mod font;
pub mod markdown;
pub mod plot;

use std::path::PathBuf;

/// Errors of the reporting crate; each names the file or figure at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file system error on a named file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The CSV writer failed.
    #[error("{path}: csv: {source}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// What the writer said.
        source: ::csv::Error,
    },
    /// The PNG encoder failed.
    #[error("{path}: png: {source}")]
    Png {
        /// The file.
        path: PathBuf,
        /// What the encoder said.
        source: png::EncodingError,
    },
    /// A figure cannot be laid out (more panels than the grid holds, panels too small).
    #[error("figure `{title}`: {message}")]
    Layout {
        /// The figure's title.
        title: String,
        /// What is wrong, with the offending values.
        message: String,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// A failed atomic write ([`atomic_file::write_atomic`]) is an I/O error on its path.
impl From<atomic_file::Error> for Error {
    fn from(e: atomic_file::Error) -> Self {
        Error::Io {
            path: e.path,
            source: e.source,
        }
    }
}
