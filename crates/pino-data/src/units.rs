//! The unit of every column of every pino-mbd artifact: a fixed table for the bookkeeping
//! columns, and the units a table carries for the columns of its system description.
//!
//! Every Parquet file the project writes carries, for each column, its unit in the Arrow field
//! metadata under [`UNIT_KEY`] (and all of them as one JSON object in the file's key-value
//! metadata, see [`crate::metadata`]). The writer takes each unit from the table's own
//! [`Units`] ([`crate::Table::with_units`]; a system's are [`crate::system::units_of`]: its
//! parameters, channels and magnitude weights; a writer of index columns adds theirs, which the
//! indices crate declares), else from the fixed table of keys,
//! labels, scores and bookkeeping columns ([`fixed_unit`]). A column neither knows cannot be
//! written ([`crate::Error::NoUnit`], naming it): adding a bookkeeping column to an artifact
//! means stating its unit here, a system's column has its unit in the description. There is no
//! process-wide registry: two systems' tables written by one process each carry their own.
//!
//! Notation: SI symbols as in `docs/model.md`, products with a space (`N m`, `N s/m`,
//! `kg m^2`), powers with `^`; `1` for a dimensionless number, a count, a flag, an identifier
//! or a label (the one spelling: the descriptions' dimensionless parameters say `"1"` too);
//! `%` for a percentage. [`PER_ROW`] (`{unit}`) says that the unit differs from row to row
//! and is the value of the row's `unit` column (`channel_errors.parquet`,
//! `provenance.parquet`).

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::schema;

/// Arrow field-metadata key of a column's unit.
pub const UNIT_KEY: &str = "unit";

/// The unit of a dimensionless number, a count, a flag, an identifier or a label.
pub const DIMENSIONLESS: &str = "1";

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

/// The unit of column `name` in the fixed table of bookkeeping columns (keys, labels, scores),
/// `None` for any other name: the columns a system description defines have their units in
/// the [`Units`] a table carries.
///
/// ```
/// use pino_data::units::fixed_unit;
/// assert_eq!(fixed_unit("sample_id"), Some("1"));
/// assert_eq!(fixed_unit("t"), Some("s"));
/// assert_eq!(fixed_unit("z_s"), None);
/// ```
pub fn fixed_unit(name: &str) -> Option<&'static str> {
    NAMED.iter().find(|(n, _)| *n == name).map(|(_, u)| *u)
}

/// The units of the columns a table holds beyond the fixed table: `name -> unit`, owned (the
/// columns of a system description, [`crate::system::units_of`], and any a writer adds with
/// [`Units::with`]). Cheap to clone (shared). No name has two units: one the fixed table knows
/// keeps its unit there, and [`Units::with`] refuses another.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Units(Arc<BTreeMap<String, String>>);

impl Units {
    /// These units with `pairs` (`name`, `unit`) added; a name that already has another unit
    /// (here or in the fixed table) is [`crate::Error::UnitConflict`], naming both.
    ///
    /// ```
    /// use pino_data::units::Units;
    /// let units = Units::default().with([("z_s", "m"), ("phi_z_s", "N")]).unwrap();
    /// assert_eq!(units.unit("z_s"), Some("m"));
    /// assert_eq!(units.unit("sample_id"), Some("1"));
    /// assert_eq!(units.unit("no_such_column"), None);
    /// assert!(units.with([("z_s", "rad")]).is_err());
    /// ```
    pub fn with<N, U>(mut self, pairs: impl IntoIterator<Item = (N, U)>) -> crate::Result<Self>
    where
        N: AsRef<str>,
        U: AsRef<str>,
    {
        for (name, unit) in pairs {
            let (name, unit) = (name.as_ref(), unit.as_ref());
            match self.unit(name) {
                Some(existing) if existing != unit => {
                    return Err(crate::Error::UnitConflict {
                        column: name.to_owned(),
                        unit: unit.to_owned(),
                        existing: existing.to_owned(),
                    })
                }
                Some(_) => {}
                None => {
                    Arc::make_mut(&mut self.0).insert(name.to_owned(), unit.to_owned());
                }
            }
        }
        Ok(self)
    }

    /// These units and those of `other` (a name with two different units is an error, as in
    /// [`Units::with`]).
    pub fn merged(self, other: &Units) -> crate::Result<Self> {
        if self.0.is_empty() {
            return Ok(other.clone());
        }
        self.with(other.iter())
    }

    /// The unit of column `name`: its own, else the fixed table's ([`fixed_unit`]); `None` for
    /// a column neither knows.
    pub fn unit(&self, name: &str) -> Option<&str> {
        self.0
            .get(name)
            .map(String::as_str)
            .or_else(|| fixed_unit(name))
    }

    /// The units beyond the fixed table, by name.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &str)> {
        self.0.iter().map(|(n, u)| (n.as_str(), u.as_str()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bookkeeping columns carry their units; an added column its own; a second unit for
    /// a name (added or fixed) is refused naming both.
    #[test]
    fn fixed_and_added_units() {
        let units = Units::default();
        for (c, u) in [
            ("t", "s"),
            ("sample_id", "1"),
            ("rms_error", PER_ROW),
            ("dt", "s"),
        ] {
            assert_eq!(units.unit(c), Some(u), "{c}");
        }
        let units = units
            .with([("units_test_z", "m"), ("units_test_phi", "N m")])
            .unwrap();
        assert_eq!(units.unit("units_test_z"), Some("m"));
        assert_eq!(units.unit("units_test_phi"), Some("N m"));
        let units = units.with([("units_test_z", "m"), ("t", "s")]).unwrap();
        assert_eq!(
            units.iter().count(),
            2,
            "nothing added twice, fixed ones not copied"
        );
        let e = units
            .clone()
            .with([("units_test_z", "rad")])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(
                "column `units_test_z` is declared with unit `rad` but already has unit `m`"
            ),
            "{e}"
        );
        let e = units.with([("t", "ms")]).unwrap_err().to_string();
        assert!(
            e.contains("`t` is declared with unit `ms` but already has unit `s`"),
            "{e}"
        );
    }

    /// Two sets of units are independent: what one adds the other does not see, and merging
    /// them refuses a name with two units.
    #[test]
    fn units_are_values_not_a_registry() {
        let a = Units::default().with([("units_test_q", "m")]).unwrap();
        let b = Units::default().with([("units_test_q", "rad")]).unwrap();
        assert_eq!(
            (a.unit("units_test_q"), b.unit("units_test_q")),
            (Some("m"), Some("rad"))
        );
        assert_eq!(Units::default().unit("units_test_q"), None);
        let e = a.clone().merged(&b).unwrap_err().to_string();
        assert!(e.contains("`units_test_q`"), "{e}");
        let c = Units::default().with([("units_test_r", "N")]).unwrap();
        let ac = a.merged(&c).unwrap();
        assert_eq!(
            (ac.unit("units_test_q"), ac.unit("units_test_r")),
            (Some("m"), Some("N"))
        );
    }

    #[test]
    fn unknown_names_have_no_unit() {
        for c in ["", "z_c", "phi_1", "p_1", "units_test_unknown", "t_exact"] {
            assert_eq!(fixed_unit(c), None, "{c}");
            assert_eq!(Units::default().unit(c), None, "{c}");
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
