//! The unit of every column of every pino-mbd artifact, in one table.
//!
//! Every Parquet file the project writes carries, for each column, its unit in the Arrow field
//! metadata under [`UNIT_KEY`] (and all of them as one JSON object in the file's key-value
//! metadata, see [`crate::metadata`]); [`unit()`] is where they come from. A column the table
//! does not know cannot be written ([`crate::Error::NoUnit`]): adding a column to an artifact
//! means stating its unit here.
//!
//! Notation: SI symbols as in `docs/model.md`, products with a space (`N m`, `N s/m`,
//! `kg m^2`), powers with `^`; `-` for a dimensionless number, an identifier or a label;
//! `%` for a percentage. [`PER_ROW`] (`{unit}`) says that the unit differs from row to row
//! and is the value of the row's `unit` column (`channel_errors.parquet`,
//! `provenance.parquet`).

use std::collections::BTreeMap;

use crate::schema;

/// Arrow field-metadata key of a column's unit.
pub const UNIT_KEY: &str = "unit";

/// The unit of a dimensionless number, an identifier or a label.
pub const DIMENSIONLESS: &str = "-";

/// The unit of a column whose rows have different units: each row's unit is the value of its
/// `unit` column.
pub const PER_ROW: &str = "{unit}";

/// Columns that are not signals of the model: keys, labels, scores and bookkeeping.
const NAMED: &[(&str, &str)] = &[
    // Keys and labels of every artifact.
    (schema::SAMPLE_ID, DIMENSIONLESS),
    (schema::SPLIT, DIMENSIONLESS),
    (schema::TIME, "s"),
    (schema::TRACK_X, "m"),
    (schema::TRACK_ETA, "m"),
    (schema::PROFILE, DIMENSIONLESS),
    // simulate: failures.parquet.
    ("reason", DIMENSIONLESS),
    // simulate: provenance.parquet (one row per constant, the unit in its own column).
    ("name", DIMENSIONLESS),
    ("value", PER_ROW),
    (UNIT_KEY, DIMENSIONLESS),
    // The run controls of provenance.parquet (`name` values), for its `unit` column.
    ("dt", "s"),
    ("duration", "s"),
    ("output_every", DIMENSIONLESS),
    ("x0", "m"),
    ("startup_zero_fraction", DIMENSIONLESS),
    ("startup_ramp_fraction", DIMENSIONLESS),
    // train: history.parquet (losses and validation errors are relative: fractions).
    ("epoch", DIMENSIONLESS),
    ("step", DIMENSIONLESS),
    ("lr", DIMENSIONLESS),
    ("loss_total", DIMENSIONLESS),
    ("loss_data", DIMENSIONLESS),
    ("loss_deriv", DIMENSIONLESS),
    ("loss_ode", DIMENSIONLESS),
    ("val_solution", DIMENSIONLESS),
    ("val_first", DIMENSIONLESS),
    ("val_second", DIMENSIONLESS),
    // evaluate: table4.parquet and channel_errors.parquet.
    ("algorithm", DIMENSIONLESS),
    ("depth", DIMENSIONLESS),
    ("samples", DIMENSIONLESS),
    ("solutions_pct", "%"),
    ("first_derivatives_pct", "%"),
    ("second_derivatives_pct", "%"),
    ("contact_forces_pct", "%"),
    ("peak_contact_force_error_pct_w", "%"),
    ("paper_solutions_pct", "%"),
    ("paper_first_derivatives_pct", "%"),
    ("paper_second_derivatives_pct", "%"),
    ("channel", DIMENSIONLESS),
    ("rel_l2_pct", "%"),
    ("rms_error", PER_ROW),
    ("rms_exact", PER_ROW),
    ("worst_sample_id", DIMENSIONLESS),
    ("worst_rel_l2_pct", "%"),
    ("peak_error_pct_w", "%"),
    // predict: the parameter set a row belongs to.
    ("set", DIMENSIONLESS),
    // predict: the parameters of a design outside the model's training ranges (`name=value`).
    ("outside_training_range", DIMENSIONLESS),
    // sample-params' ranges.parquet: a parameter's sampling range, in the row's `unit`.
    ("min", PER_ROW),
    ("max", PER_ROW),
    // indices: beside the index columns (declared by the description) of indices.parquet and
    // predict --indices; evaluate's indices_errors.parquet (one row per index and algorithm).
    ("window_s", "s"),
    ("pass", DIMENSIONLESS),
    ("failed", DIMENSIONLESS),
    ("index", DIMENSIONLESS),
    ("exact_mean", PER_ROW),
    ("mean_abs_error", PER_ROW),
    ("worst_abs_error", PER_ROW),
    ("worst_abs_sample_id", DIMENSIONLESS),
    ("mean_rel_error_pct", "%"),
    ("worst_rel_error_pct", "%"),
    ("correlation", DIMENSIONLESS),
    // evaluate: coverage.parquet and coverage_conditional.parquet (the calibration's intervals
    // on the test split, docs/uncertainty.md).
    ("kind", DIMENSIONLESS),
    ("quantity", DIMENSIONLESS),
    ("normaliser", DIMENSIONLESS),
    ("chosen", DIMENSIONLESS),
    ("level", DIMENSIONLESS),
    ("n_calibration", DIMENSIONLESS),
    ("n_test", DIMENSIONLESS),
    ("coverage", DIMENSIONLESS),
    ("mean_width", PER_ROW),
    ("width_over_std", DIMENSIONLESS),
    ("group", DIMENSIONLESS),
    ("bin", DIMENSIONLESS),
    ("n", DIMENSIONLESS),
    // predict --indices with a calibration: the level, the design's difficulty and verdicts.
    ("extrapolated", DIMENSIONLESS),
    ("relative_residual", DIMENSIONLESS),
    ("verdict", DIMENSIONLESS),
];

/// Units declared by this process for the columns of its system description (parameters,
/// channels, magnitude weights, indices): `name -> unit`, consulted before the fixed table.
static DECLARED: std::sync::RwLock<BTreeMap<String, &'static str>> =
    std::sync::RwLock::new(BTreeMap::new());

/// Declares the units of columns a system description defines (its parameters and stored
/// channels, see [`crate::system::declare_units`]). A name already declared or in the fixed
/// tables with another unit is an error naming both.
pub fn declare<'a>(pairs: impl IntoIterator<Item = (&'a str, &'a str)>) -> crate::Result<()> {
    let mut map = DECLARED.write().unwrap_or_else(|e| e.into_inner());
    for (name, u) in pairs {
        let fixed = NAMED.iter().find(|(n, _)| *n == name).map(|(_, u)| *u);
        match map.get(name).copied().or(fixed) {
            Some(old) if old != u => {
                return Err(crate::Error::Origin(format!(
                    "column `{name}` is declared with unit `{u}` but already has unit `{old}`"
                )))
            }
            Some(_) => {}
            None => {
                map.insert(name.to_owned(), Box::leak(u.to_owned().into_boxed_str()));
            }
        }
    }
    Ok(())
}

/// The unit of column `name` of any pino-mbd artifact, `None` for a column no artifact has:
/// the bookkeeping columns of the fixed table, and the columns of the system description this
/// process declared ([`declare`], [`crate::system::declare_units`]).
///
/// ```
/// use pino_data::units::{declare, unit};
/// declare([("z_s", "m"), ("phi_z_s", "N")]).unwrap();
/// assert_eq!(unit("z_s"), Some("m"));
/// assert_eq!(unit("sample_id"), Some("-"));
/// assert_eq!(unit("no_such_column"), None);
/// ```
pub fn unit(name: &str) -> Option<&'static str> {
    if let Some(&u) = DECLARED.read().unwrap_or_else(|e| e.into_inner()).get(name) {
        return Some(u);
    }
    NAMED.iter().find(|(n, _)| *n == name).map(|(_, u)| *u)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bookkeeping columns carry their units; a declared column its declared one; a
    /// second declaration with another unit is refused naming both.
    #[test]
    fn fixed_and_declared_units() {
        for (c, u) in [
            ("t", "s"),
            ("sample_id", "-"),
            ("rms_error", PER_ROW),
            ("dt", "s"),
        ] {
            assert_eq!(unit(c), Some(u), "{c}");
        }
        declare([("units_test_z", "m"), ("units_test_phi", "N m")]).unwrap();
        assert_eq!(unit("units_test_z"), Some("m"));
        assert_eq!(unit("units_test_phi"), Some("N m"));
        declare([("units_test_z", "m")]).unwrap();
        let e = declare([("units_test_z", "rad")]).unwrap_err().to_string();
        assert!(
            e.contains(
                "column `units_test_z` is declared with unit `rad` but already has unit `m`"
            ),
            "{e}"
        );
        let e = declare([("t", "ms")]).unwrap_err().to_string();
        assert!(
            e.contains("`t` is declared with unit `ms` but already has unit `s`"),
            "{e}"
        );
    }

    #[test]
    fn unknown_names_have_no_unit() {
        for c in ["", "z_c", "phi_1", "p_1", "units_test_unknown", "t_exact"] {
            assert_eq!(unit(c), None, "{c}");
        }
    }

    #[test]
    fn the_table_names_each_column_once() {
        let mut names: Vec<&str> = NAMED.iter().map(|(n, _)| *n).collect();
        names.sort_unstable();
        let n = names.len();
        names.dedup();
        assert_eq!(names.len(), n);
    }
}
