//! Designs from a caller's table: one row per design, a column per design parameter (by name;
//! a missing parameter takes its nominal value), plus an optional `sample_id` (the stream or
//! sample of the excitation the design runs on, [`crate::excitation`]; in `System.simulate`
//! also its rows' key in the output) and a `split` (ignored: `params.parquet`'s rows are
//! designs as they are). Unknown names, non-numeric columns and non-finite values are
//! refused naming the column and row; then every design is checked against the description's
//! domains ([`DesignSpace::check`]), which names the field and its allowed range.

use crate::error::value_error;
use pino_data::{schema, Column, Table};
use pino_predict::DesignSpace;
use pyo3::PyResult;
use std::path::Path;

/// The designs of a table.
pub struct Designs {
    /// Each design's parameters in [`DesignSpace::names`] order.
    pub sets: Vec<Vec<f64>>,
    /// Each design's `sample_id`, when the table has the column.
    pub ids: Option<Vec<i64>>,
}

impl Designs {
    /// Each design's `sample_id`, else its row number.
    pub fn ids_or_rows(&self) -> Vec<i64> {
        self.ids
            .clone()
            .unwrap_or_else(|| (0..self.sets.len() as i64).collect())
    }
}

/// Reads `table` (named `what` in errors) as designs of `space`.
pub fn designs(space: &DesignSpace, table: &Table, what: &str) -> PyResult<Designs> {
    let n = table.num_rows();
    if n == 0 {
        return Err(value_error(format!("{what}: no rows (one row per design)")));
    }
    let mut sets = vec![space.nominal(); n];
    let mut ids = None;
    for (name, col) in table.columns() {
        if name == schema::SPLIT {
            continue;
        }
        if name == schema::SAMPLE_ID {
            ids = Some(sample_ids(col, what, name)?);
            continue;
        }
        let j = space
            .index(name, Path::new(what))
            .map_err(|e| value_error(format!("{e} (besides: sample_id, split)")))?;
        let values: Vec<f64> = match col {
            Column::F64(v) => v.clone(),
            Column::I64(v) => v.iter().map(|&x| x as f64).collect(),
            Column::Str(_) => {
                return Err(value_error(format!(
                    "{what}.{name}: strings; allowed numbers"
                )))
            }
            other => {
                return Err(value_error(format!(
                    "{what}.{name}: {}; allowed numbers",
                    other.type_name()
                )))
            }
        };
        for (r, x) in values.into_iter().enumerate() {
            if !x.is_finite() {
                return Err(value_error(format!(
                    "{what}.{name}[{r}] = {x}: allowed a finite number"
                )));
            }
            sets[r][j] = x;
        }
    }
    for (k, s) in sets.iter().enumerate() {
        space
            .check(s, &format!("{what}[{k}]"))
            .map_err(|e| value_error(e.to_string()))?;
    }
    Ok(Designs { sets, ids })
}

/// The `sample_id` column `col` of a designs table: integers >= 0 (whole floats accepted).
fn sample_ids(col: &Column, what: &str, name: &str) -> PyResult<Vec<i64>> {
    let bad = |r: usize, x: &dyn std::fmt::Display| {
        value_error(format!("{what}.{name}[{r}] = {x}: allowed an integer >= 0"))
    };
    let ids: Vec<i64> = match col {
        Column::I64(v) => v.clone(),
        Column::F64(v) => v
            .iter()
            .enumerate()
            .map(|(r, &x)| {
                if x.fract() == 0.0 && x.abs() < 9.0e15 {
                    Ok(x as i64)
                } else {
                    Err(bad(r, &x))
                }
            })
            .collect::<PyResult<_>>()?,
        other => {
            return Err(value_error(format!(
                "{what}.{name}: {}; allowed integers >= 0",
                other.type_name()
            )))
        }
    };
    match ids.iter().enumerate().find(|(_, &id)| id < 0) {
        Some((r, id)) => Err(bad(r, id)),
        None => Ok(ids),
    }
}
