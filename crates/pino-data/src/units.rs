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

use crate::schema::{
    self, ACCELERATION_SUFFIX, CONTACT_FORCES, ETA_UNDER_WHEEL, PARAMETERS, RAIL_UNDER_WHEEL,
    VEHICLE_DOFS, VELOCITY_SUFFIX,
};

/// Arrow field-metadata key of a column's unit.
pub const UNIT_KEY: &str = "unit";

/// The unit of a dimensionless number, an identifier or a label.
pub const DIMENSIONLESS: &str = "-";

/// The unit of a column whose rows have different units: each row's unit is the value of its
/// `unit` column.
pub const PER_ROW: &str = "{unit}";

/// Units of the 14 sampled parameters, in [`PARAMETERS`] order.
const PARAMETER_UNITS: [&str; 14] = [
    "kg", "kg m^2", "kg", "kg m^2", "kg", "N/m", "N s/m", "N/m", "N s/m", "m", "m", "km/h", "N/m",
    "N s/m",
];

/// Columns that are not signals of the model: keys, labels, scores and bookkeeping.
const NAMED: &[(&str, &str)] = &[
    // Keys and labels of every artifact.
    (schema::SAMPLE_ID, DIMENSIONLESS),
    (schema::SPLIT, DIMENSIONLESS),
    (schema::TIME, "s"),
    (schema::TRACK_X, "m"),
    (schema::TRACK_ETA, "m"),
    // simulate: failures.parquet.
    ("reason", DIMENSIONLESS),
    // simulate: provenance.parquet (one row per constant, the unit in its own column).
    ("name", DIMENSIONLESS),
    ("value", PER_ROW),
    (UNIT_KEY, DIMENSIONLESS),
    // The constants of provenance.parquet (`name` values), for its `unit` column.
    ("gravity", "m/s^2"),
    ("wheel_radius", "m"),
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
    // indices: beside the index columns ([`INDICES`]) of indices.parquet and predict
    // --indices; evaluate's indices_errors.parquet (one row per index and algorithm).
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
];

/// The engineering indices (`docs/indices.md`), each also with the suffix [`EXACT_SUFFIX`]
/// (the solver's value beside the surrogate's, `indices_samples.parquet`).
const INDICES: &[(&str, &str)] = &[
    ("peak_wheel_rail_force_kn", "kN"),
    ("wheel_load_reduction_rate", DIMENSIONLESS),
    ("car_body_acc_peak_centre_ms2", "m/s^2"),
    ("car_body_acc_peak_front_ms2", "m/s^2"),
    ("car_body_acc_peak_rear_ms2", "m/s^2"),
    ("car_body_acc_rms_centre_ms2", "m/s^2"),
    ("car_body_acc_rms_front_ms2", "m/s^2"),
    ("car_body_acc_rms_rear_ms2", "m/s^2"),
    ("sperling_wz_centre", DIMENSIONLESS),
    ("sperling_wz_front", DIMENSIONLESS),
    ("sperling_wz_rear", DIMENSIONLESS),
    ("bogie_acc_peak_front_ms2", "m/s^2"),
    ("bogie_acc_peak_rear_ms2", "m/s^2"),
    ("rail_deflection_peak_mm", "mm"),
];

/// Suffix of the exact (solver) value of an index beside the predicted one.
const EXACT_SUFFIX: &str = "_exact";

/// Units declared by this process for the columns of its system description (parameters,
/// channels, magnitude weights): `name -> unit`, consulted before the fixed tables.
static DECLARED: std::sync::RwLock<BTreeMap<String, &'static str>> =
    std::sync::RwLock::new(BTreeMap::new());

/// Declares the units of columns a system description defines (its parameters and stored
/// channels, see [`crate::system::declare_units`]). A name already declared or in the fixed
/// tables with another unit is an error naming both.
pub fn declare<'a>(pairs: impl IntoIterator<Item = (&'a str, &'a str)>) -> crate::Result<()> {
    let mut map = DECLARED.write().unwrap_or_else(|e| e.into_inner());
    for (name, u) in pairs {
        let fixed = NAMED
            .iter()
            .chain(INDICES)
            .find(|(n, _)| *n == name)
            .map(|(_, u)| *u);
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

/// The unit of column `name` of any pino-mbd artifact, `None` for a column no artifact has.
///
/// ```
/// use pino_data::units::unit;
/// assert_eq!(unit("p_1"), Some("N"));
/// assert_eq!(unit("beta_c_v"), Some("rad/s"));
/// assert_eq!(unit("phi_2"), Some("N m"));
/// assert_eq!(unit("no_such_column"), None);
/// ```
pub fn unit(name: &str) -> Option<&'static str> {
    if let Some(&u) = DECLARED.read().unwrap_or_else(|e| e.into_inner()).get(name) {
        return Some(u);
    }
    if let Some(&(_, u)) = NAMED.iter().find(|(n, _)| *n == name) {
        return Some(u);
    }
    let index = name.strip_suffix(EXACT_SUFFIX).unwrap_or(name);
    if let Some(&(_, u)) = INDICES.iter().find(|(n, _)| *n == index) {
        return Some(u);
    }
    if let Some(j) = PARAMETERS.iter().position(|p| *p == name) {
        return Some(PARAMETER_UNITS[j]);
    }
    if RAIL_UNDER_WHEEL.contains(&name) || ETA_UNDER_WHEEL.contains(&name) {
        return Some("m");
    }
    if CONTACT_FORCES.contains(&name) {
        return Some("N");
    }
    // The vehicle DOFs and their derivatives: m or rad, per s, per s^2.
    let (dof, per) = if let Some(d) = name.strip_suffix(VELOCITY_SUFFIX) {
        (d, "/s")
    } else if let Some(d) = name.strip_suffix(ACCELERATION_SUFFIX) {
        (d, "/s^2")
    } else {
        (name, "")
    };
    if VEHICLE_DOFS.contains(&dof) {
        return Some(match (is_angle(dof), per) {
            (false, "") => "m",
            (false, "/s") => "m/s",
            (false, _) => "m/s^2",
            (true, "") => "rad",
            (true, "/s") => "rad/s",
            (true, _) => "rad/s^2",
        });
    }
    // Magnitude weights phi_1..phi_10: the residual of equation i, a force (N) for a
    // vertical DOF, a moment (N m) for a pitch DOF.
    let i: usize = name.strip_prefix("phi_")?.parse().ok()?;
    let dof = VEHICLE_DOFS.get(i.checked_sub(1)?)?;
    Some(if is_angle(dof) { "N m" } else { "N" })
}

/// Pitch DOFs (`beta_*`) are angles; the others are vertical displacements.
fn is_angle(dof: &str) -> bool {
    dof.starts_with("beta")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every column of the public schema has a unit, and the SI one of the spec.
    #[test]
    fn every_public_column_has_its_unit() {
        for c in schema::simulation_columns() {
            assert!(unit(&c).is_some(), "{c}");
        }
        for c in schema::phi_columns() {
            assert!(unit(&c).is_some(), "{c}");
        }
        for p in PARAMETERS {
            assert!(unit(p).is_some(), "{p}");
        }
        let cases = [
            ("t", "s"),
            ("z_c", "m"),
            ("beta_t1", "rad"),
            ("z_w3_v", "m/s"),
            ("beta_c_v", "rad/s"),
            ("z_t2_a", "m/s^2"),
            ("beta_t2_a", "rad/s^2"),
            ("z_r4", "m"),
            ("eta_2", "m"),
            ("p_3", "N"),
            ("phi_1", "N"),
            ("phi_2", "N m"),
            ("phi_6", "N m"),
            ("phi_10", "N"),
            ("m_c", "kg"),
            ("j_t", "kg m^2"),
            ("c_f", "N s/m"),
            ("v_kmh", "km/h"),
            ("sample_id", "-"),
            ("peak_wheel_rail_force_kn", "kN"),
            ("peak_wheel_rail_force_kn_exact", "kN"),
            ("rms_error", PER_ROW),
        ];
        for (c, u) in cases {
            assert_eq!(unit(c), Some(u), "{c}");
        }
    }

    #[test]
    fn unknown_names_have_no_unit() {
        for c in [
            "",
            "phi_0",
            "phi_11",
            "phi_x",
            "z_r1_v",
            "p_1_a",
            "z_c_v_v",
            "beta",
            "P_1",
            "t_exact",
            "z_c_exact",
        ] {
            assert_eq!(unit(c), None, "{c}");
        }
    }

    #[test]
    fn the_table_names_each_column_once() {
        let mut names: Vec<&str> = NAMED.iter().chain(INDICES).map(|(n, _)| *n).collect();
        names.sort_unstable();
        let n = names.len();
        names.dedup();
        assert_eq!(names.len(), n);
        for n in names {
            assert!(
                !PARAMETERS.contains(&n) && !VEHICLE_DOFS.contains(&n),
                "{n}"
            );
        }
    }
}
