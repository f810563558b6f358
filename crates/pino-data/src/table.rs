//! An in-memory columnar table: named, equally long `f64`, `i64`, Boolean or string columns
//! (strings with or without nulls), with the units of the columns that the fixed table of
//! [`crate::units`] does not know.

use crate::units::Units;
use crate::{Error, Result};
use std::path::PathBuf;

/// One column's values.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// 64-bit floats (Parquet DOUBLE).
    F64(Vec<f64>),
    /// 64-bit integers (Parquet INT64).
    I64(Vec<i64>),
    /// UTF-8 strings (Parquet BYTE_ARRAY / STRING).
    Str(Vec<String>),
    /// Booleans (Parquet BOOLEAN).
    Bool(Vec<bool>),
    /// UTF-8 strings where `None` is absent (a null: a nullable Parquet STRING), for a column
    /// whose rows may have no value (a flag that names what is wrong, empty when nothing is).
    OptStr(Vec<Option<String>>),
}

impl Column {
    /// A [`Column::OptStr`] of `values` where an empty string (no flag, nothing named) is a
    /// null: the one rule by which every artifact writes an absent text.
    pub fn null_if_empty(values: impl IntoIterator<Item = String>) -> Column {
        Column::OptStr(
            values
                .into_iter()
                .map(|s| (!s.is_empty()).then_some(s))
                .collect(),
        )
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Column::F64(v) => v.len(),
            Column::I64(v) => v.len(),
            Column::Str(v) => v.len(),
            Column::Bool(v) => v.len(),
            Column::OptStr(v) => v.len(),
        }
    }

    /// Whether the column has no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The type's name, for messages.
    pub fn type_name(&self) -> &'static str {
        match self {
            Column::F64(_) => "f64",
            Column::I64(_) => "i64",
            Column::Str(_) => "string",
            Column::Bool(_) => "bool",
            Column::OptStr(_) => "nullable string",
        }
    }

    fn extend(&mut self, other: Column) -> std::result::Result<(), &'static str> {
        match (self, other) {
            (Column::F64(a), Column::F64(b)) => a.extend(b),
            (Column::I64(a), Column::I64(b)) => a.extend(b),
            (Column::Str(a), Column::Str(b)) => a.extend(b),
            (Column::Bool(a), Column::Bool(b)) => a.extend(b),
            (Column::OptStr(a), Column::OptStr(b)) => a.extend(b),
            (Column::OptStr(a), Column::Str(b)) => a.extend(b.into_iter().map(Some)),
            (this @ Column::Str(_), Column::OptStr(b)) => {
                let Column::Str(a) = std::mem::replace(this, Column::OptStr(Vec::new())) else {
                    unreachable!("matched above")
                };
                *this = Column::OptStr(a.into_iter().map(Some).chain(b).collect());
            }
            (_, other) => return Err(other.type_name()),
        }
        Ok(())
    }
}

/// Named columns of equal length, in insertion order. `origin` names where the table came
/// from (a file path) so that errors point at it; `units` gives the unit of each column the
/// fixed table of [`crate::units`] does not know (a system's parameters, channels, indices),
/// for the writers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Table {
    columns: Vec<(String, Column)>,
    origin: PathBuf,
    units: Units,
}

impl Table {
    /// An empty table whose errors will name `origin`.
    pub fn with_origin(origin: impl Into<PathBuf>) -> Self {
        Self {
            origin: origin.into(),
            ..Self::default()
        }
    }

    /// This table carrying `units` for its columns (they replace any it carried): what the
    /// writers take each column's unit from, before the fixed table.
    pub fn with_units(mut self, units: Units) -> Self {
        self.units = units;
        self
    }

    /// Adds `pairs` (`name`, `unit`) to the units this table carries; a name that already
    /// has another unit is [`Error::UnitConflict`].
    pub fn add_units<N, U>(&mut self, pairs: impl IntoIterator<Item = (N, U)>) -> Result<()>
    where
        N: AsRef<str>,
        U: AsRef<str>,
    {
        self.units = std::mem::take(&mut self.units).with(pairs)?;
        Ok(())
    }

    /// The units this table carries ([`Table::with_units`]).
    pub fn units(&self) -> &Units {
        &self.units
    }

    /// The unit of column `name`: the table's own, else the fixed table's; `None` for a
    /// column neither knows.
    pub fn unit(&self, name: &str) -> Option<&str> {
        self.units.unit(name)
    }

    /// Appends a column; its length must match the existing ones.
    pub fn push(&mut self, name: &str, column: Column) -> Result<()> {
        if self.columns.iter().any(|(n, _)| n == name) {
            return Err(Error::Duplicate(name.to_owned()));
        }
        if let Some((_, first)) = self.columns.first() {
            if first.len() != column.len() {
                return Err(Error::Length {
                    column: name.to_owned(),
                    found: column.len(),
                    expected: first.len(),
                });
            }
        }
        self.columns.push((name.to_owned(), column));
        Ok(())
    }

    /// Number of rows.
    pub fn num_rows(&self) -> usize {
        self.columns.first().map_or(0, |(_, c)| c.len())
    }

    /// Column names in order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.columns.iter().map(|(n, _)| n.as_str())
    }

    /// All columns in order.
    pub fn columns(&self) -> &[(String, Column)] {
        &self.columns
    }

    /// The columns, moved out (the table's vectors, no copy).
    pub fn into_columns(self) -> Vec<(String, Column)> {
        self.columns
    }

    /// Where this table came from.
    pub fn origin(&self) -> &std::path::Path {
        &self.origin
    }

    /// A column by name.
    pub fn column(&self, name: &str) -> Result<&Column> {
        self.columns
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, c)| c)
            .ok_or_else(|| Error::MissingColumn {
                path: self.origin.clone(),
                column: name.to_owned(),
                present: self.names().collect::<Vec<_>>().join(", "),
            })
    }

    /// An `f64` column by name.
    pub fn f64(&self, name: &str) -> Result<&[f64]> {
        match self.column(name)? {
            Column::F64(v) => Ok(v),
            other => Err(self.type_error(name, other, "f64")),
        }
    }

    /// An `i64` column by name.
    pub fn i64(&self, name: &str) -> Result<&[i64]> {
        match self.column(name)? {
            Column::I64(v) => Ok(v),
            other => Err(self.type_error(name, other, "i64")),
        }
    }

    /// A string column by name.
    pub fn str(&self, name: &str) -> Result<&[String]> {
        match self.column(name)? {
            Column::Str(v) => Ok(v),
            other => Err(self.type_error(name, other, "string")),
        }
    }

    /// A Boolean column by name.
    pub fn bool(&self, name: &str) -> Result<&[bool]> {
        match self.column(name)? {
            Column::Bool(v) => Ok(v),
            other => Err(self.type_error(name, other, "bool")),
        }
    }

    /// A string column by name, each row `None` where it is null (a column read without
    /// nulls is a plain string column: both are accepted).
    pub fn opt_str(&self, name: &str) -> Result<Vec<Option<&str>>> {
        match self.column(name)? {
            Column::OptStr(v) => Ok(v.iter().map(Option::as_deref).collect()),
            Column::Str(v) => Ok(v.iter().map(|s| Some(s.as_str())).collect()),
            other => Err(self.type_error(name, other, "string")),
        }
    }

    /// Appends the rows of `other`, which must have the same columns in the same order; the
    /// table carries the units of both (a column with two units is an error).
    pub fn append(&mut self, other: Table) -> Result<()> {
        let units = std::mem::take(&mut self.units).merged(&other.units)?;
        if self.columns.is_empty() {
            let origin = std::mem::take(&mut self.origin);
            *self = other;
            if !origin.as_os_str().is_empty() {
                self.origin = origin;
            }
            self.units = units;
            return Ok(());
        }
        self.units = units;
        let theirs: Vec<String> = other.names().map(str::to_owned).collect();
        let ours: Vec<String> = self.names().map(str::to_owned).collect();
        if theirs != ours {
            let column = ours
                .iter()
                .find(|c| !theirs.contains(c))
                .cloned()
                .unwrap_or_else(|| ours.join(","));
            return Err(Error::MissingColumn {
                path: other.origin,
                column,
                present: theirs.join(", "),
            });
        }
        for ((name, mine), (_, col)) in self.columns.iter_mut().zip(other.columns) {
            let found = col.type_name();
            let expected = mine.type_name();
            mine.extend(col).map_err(|_| Error::ColumnType {
                path: other.origin.clone(),
                column: name.clone(),
                found: found.to_owned(),
                expected: expected.to_owned(),
            })?;
        }
        Ok(())
    }

    fn type_error(&self, name: &str, col: &Column, expected: &str) -> Error {
        Error::ColumnType {
            path: self.origin.clone(),
            column: name.to_owned(),
            found: col.type_name().to_owned(),
            expected: expected.to_owned(),
        }
    }
}
