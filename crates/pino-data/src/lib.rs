//! The public data contract of pino-mbd and its Parquet I/O.
//!
//! - [`artifacts`]: the file name of every artifact the stages write and read.
//! - [`schema`]: the column names every artifact uses (from `docs/model.md`); users read them
//!   from pandas, polars or DuckDB, so they are a contract.
//! - [`Table`]: a small columnar table of named `f64`, `i64`, Boolean or string columns (a
//!   string column may hold nulls: an absent value, [`Column::null_if_empty`]), carrying the
//!   units of the columns its system defines ([`units::Units`]).
//! - [`write_parquet`]: writes a table atomically (temporary file, fsync, rename) with fixed
//!   writer settings, so the same table always gives the same bytes.
//! - [`StreamWriter`]: writes a large table row group by row group (atomic on finish).
//! - [`batch`]: a table as an Arrow record batch in memory (units on the fields) and back.
//! - [`read_parquet`]: reads chosen columns, naming the file and the column when one is
//!   missing or of another type.
//! - [`records`]: the per-sample record reader of files sorted by sample, and the reader of
//!   `params.parquet`.
//! - [`provenance`]: the physical constants a dataset was simulated with, checked by the
//!   stages that learn from it.
//! - [`system`]: the system description a stage's command names, its record beside the
//!   artifacts (`system.json`) and the units of its columns.
//! - [`units`]: the unit of every column of every artifact (a fixed table, and the units a
//!   table carries); [`metadata`]: what each file
//!   carries about itself (every column's unit, the writing stage, unit and parameters, the
//!   version), readable from pyarrow, polars and DuckDB.
//!
//! ```no_run
//! use pino_data::{Table, Column, write_parquet, read_parquet};
//! let mut t = Table::default();
//! t.push("sample_id", Column::I64(vec![0, 1]))?;
//! t.push("x", Column::F64(vec![0.5, 1.5]))?;
//! write_parquet(std::path::Path::new("t.parquet"), &t)?;
//! let back = read_parquet(std::path::Path::new("t.parquet"), Some(&["x"]))?;
//! assert_eq!(back.f64("x")?, &[0.5, 1.5]);
//! # Ok::<(), pino_data::Error>(())
//! ```
#![warn(missing_docs)]

pub mod artifacts;
pub mod batch;
pub mod metadata;
mod parquet_io;
pub mod provenance;
pub mod records;
pub mod schema;
mod stream;
pub mod system;
mod table;
pub mod units;

pub use parquet_io::{
    for_each_batch, read_parquet, read_parquet_files, row_count, write_parquet, write_parquet_from,
    write_parquet_with,
};
pub use stream::StreamWriter;
pub use table::{Column, Table};

use std::path::PathBuf;

/// Errors of the data layer; each names the file and, where it applies, the column.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// File system error on a named file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Parquet or Arrow failed on a named file.
    #[error("{path}: parquet: {message}")]
    Parquet {
        /// The file.
        path: PathBuf,
        /// What the library said.
        message: String,
    },
    /// A required column is absent.
    #[error("{path}: missing column `{column}` (present: {present})")]
    MissingColumn {
        /// The file (or table description).
        path: PathBuf,
        /// The column asked for.
        column: String,
        /// The columns that are there.
        present: String,
    },
    /// A column has another type than asked.
    #[error("{path}: column `{column}` is {found}, expected {expected}")]
    ColumnType {
        /// The file (or table description).
        path: PathBuf,
        /// The column.
        column: String,
        /// Its type.
        found: String,
        /// The type asked for.
        expected: String,
    },
    /// Columns of one table differ in length.
    #[error("column `{column}` has {found} rows, the table has {expected}")]
    Length {
        /// The column.
        column: String,
        /// Its length.
        found: usize,
        /// The table's length.
        expected: usize,
    },
    /// The same column name twice in one table.
    #[error("duplicate column `{0}`")]
    Duplicate(String),
    /// A column that neither the table's [`units::Units`] nor the fixed table has a unit for
    /// (every written column must have one).
    #[error("{path}: column `{column}` has no unit: state it in crates/pino-data/src/units.rs")]
    NoUnit {
        /// The file being written.
        path: PathBuf,
        /// The column.
        column: String,
    },
    /// A column given a unit while it already has another ([`units::Units::with`]).
    #[error("column `{column}` is declared with unit `{unit}` but already has unit `{existing}`")]
    UnitConflict {
        /// The column.
        column: String,
        /// The unit given now.
        unit: String,
        /// The unit it already has.
        existing: String,
    },
    /// A process declared two different origins ([`metadata::set_origin`]).
    #[error("origin of the written files: {0}")]
    Origin(String),
    /// Records of a file are not grouped by sample, or a sample id repeats.
    #[error("{path}: {message}")]
    Records {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The system description could not be read, compiled or matched.
    #[error("{0}")]
    System(String),
}

/// A Parquet or Arrow failure on `path`.
pub(crate) fn pq(path: &std::path::Path, e: impl std::fmt::Display) -> Error {
    Error::Parquet {
        path: path.to_owned(),
        message: e.to_string(),
    }
}

/// A file system failure on `path`.
pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Error {
    Error::Io {
        path: path.to_owned(),
        source,
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;
