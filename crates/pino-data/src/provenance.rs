//! The dataset's provenance in a table: the run controls a simulated dataset was made with
//! (time step, duration, output rate, start-up fractions, `x0`), stored next to it for readers
//! in pandas, polars or DuckDB. (The machine record of the same run is `run.json`,
//! [`crate::artifacts::RUN_FILE`]; the physics is the description's, `system.json`.)
//!
//! `simulate` writes `provenance.parquet` ([`crate::artifacts::PROVENANCE_FILE`]) (columns `name` (string), `value` (f64), `unit`
//! (string, from the fixed table of [`crate::units`]), one row per control, sorted by name) into every shard's
//! output.

use crate::{read_parquet, write_parquet, Column, Error, Result, Table};
use std::collections::BTreeMap;
use std::path::Path;

/// Writes the constants (name, value, unit) to `path`, sorted by name; a constant without a
/// unit in the fixed table of [`crate::units`] is an error.
pub fn write_provenance(path: &Path, constants: &[(&str, f64)]) -> Result<()> {
    let sorted: BTreeMap<&str, f64> = constants.iter().copied().collect();
    let units = sorted
        .keys()
        .map(|name| {
            crate::units::fixed_unit(name)
                .map(str::to_owned)
                .ok_or_else(|| Error::NoUnit {
                    path: path.to_owned(),
                    column: format!("{name} (a constant)"),
                })
        })
        .collect::<Result<Vec<_>>>()?;
    let mut t = Table::default();
    t.push(
        "name",
        Column::Str(sorted.keys().map(|k| (*k).to_owned()).collect()),
    )?;
    t.push("value", Column::F64(sorted.values().copied().collect()))?;
    t.push(crate::units::UNIT_KEY, Column::Str(units))?;
    write_parquet(path, &t)
}

/// Reads a provenance record.
pub fn read_provenance(path: &Path) -> Result<BTreeMap<String, f64>> {
    let t = read_parquet(path, Some(&["name", "value"]))?;
    Ok(t.str("name")?
        .iter()
        .cloned()
        .zip(t.f64("value")?.iter().copied())
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::artifacts::PROVENANCE_FILE;

    #[test]
    fn round_trip_with_units_and_unknown_names_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_owned();
        write_provenance(&d.join(PROVENANCE_FILE), &[("x0", 20.0), ("dt", 1e-4)]).unwrap();
        let back = read_provenance(&d.join(PROVENANCE_FILE)).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!((back["dt"], back["x0"]), (1e-4, 20.0));
        let t = read_parquet(&d.join(PROVENANCE_FILE), Some(&["name", "unit"])).unwrap();
        assert_eq!(t.str("name").unwrap(), &["dt", "x0"], "sorted by name");
        assert_eq!(t.str("unit").unwrap(), &["s", "m"]);
        let e = write_provenance(&d.join("x.parquet"), &[("speed_of_light", 3e8)])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`speed_of_light (a constant)` has no unit"),
            "{e}"
        );
        assert!(!d.join("x.parquet").exists());
    }
}
