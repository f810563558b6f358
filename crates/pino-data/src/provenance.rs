//! The dataset's provenance: the physical constants a simulated dataset was made with,
//! stored next to it so that the stages that learn from it can check theirs.
//!
//! `simulate` writes `provenance.parquet` (columns `name` (string), `value` (f64), `unit`
//! (string, from [`crate::units`]), one row per constant, sorted by name) into every shard's
//! output; `weights` and `train` call
//! [`check_constants`] with the values they were configured with, and a difference is an
//! error naming the constant, both values and the file. (The pipeline file gives all of them
//! the same `${constants.NAME}`; the check catches a dataset made elsewhere or by hand.)

use crate::{read_parquet, write_parquet, Column, Error, Result, Table};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// File name of the provenance record in a dataset directory.
pub const PROVENANCE_FILE: &str = "provenance.parquet";

/// Writes the constants (name, value, unit) to `path`, sorted by name; a constant without a
/// unit in [`crate::units`] is an error.
pub fn write_provenance(path: &Path, constants: &[(&str, f64)]) -> Result<()> {
    let sorted: BTreeMap<&str, f64> = constants.iter().copied().collect();
    let units = sorted
        .keys()
        .map(|name| {
            crate::units::unit(name)
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

/// Checks `expected` (a stage's configured constants) against the provenance record of every
/// dataset directory in `dirs`. A directory without a record is refused (its constants are
/// unknown), as is a record without one of the constants or with another value.
pub fn check_constants(dirs: &[PathBuf], expected: &[(&str, f64)]) -> Result<()> {
    for dir in dirs {
        let path = dir.join(PROVENANCE_FILE);
        if !path.is_file() {
            return Err(Error::Provenance {
                path,
                message: "missing: the dataset does not say which physical constants made it (re-run `simulate`)".into(),
            });
        }
        let record = read_provenance(&path)?;
        for (name, value) in expected {
            match record.get(*name) {
                Some(v) if v.to_bits() == value.to_bits() => {}
                Some(v) => {
                    return Err(Error::Provenance {
                        path,
                        message: format!(
                            "the dataset was simulated with {name} = {v}, this stage is configured with {name} = {value}; give both the same value (in the pipeline file, `constants.{name}`)"
                        ),
                    })
                }
                None => {
                    return Err(Error::Provenance {
                        path,
                        message: format!("no value for `{name}`"),
                    })
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_mismatch_names_both_values() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_owned();
        write_provenance(
            &d.join(PROVENANCE_FILE),
            &[("wheel_radius", 0.43), ("gravity", 9.81)],
        )
        .unwrap();
        let back = read_provenance(&d.join(PROVENANCE_FILE)).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!(back["gravity"], 9.81);
        let t = read_parquet(&d.join(PROVENANCE_FILE), Some(&["unit"])).unwrap();
        assert_eq!(t.str("unit").unwrap(), &["m/s^2", "m"]);
        let e = write_provenance(&d.join("x.parquet"), &[("speed_of_light", 3e8)])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`speed_of_light (a constant)` has no unit"),
            "{e}"
        );
        let dirs = [d.clone()];
        check_constants(&dirs, &[("gravity", 9.81), ("wheel_radius", 0.43)]).unwrap();
        let e = check_constants(&dirs, &[("gravity", 9.8)])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("gravity = 9.81")
                && e.contains("gravity = 9.8;")
                && e.contains(PROVENANCE_FILE),
            "{e}"
        );
        let e = check_constants(&dirs, &[("x0", 1.0)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("no value for `x0`"), "{e}");
        let e = check_constants(&[d.join("nope")], &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing"), "{e}");
    }
}
