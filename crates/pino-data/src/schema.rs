//! Column names of the pino-mbd artifacts (the public schema; see `docs/model.md`, Outputs).
//!
//! Simulation output, one row per sample and output time:
//! `sample_id`, `t`, the ten vehicle DOFs, their `_v` and `_a` derivatives, `z_r1..z_r4`,
//! `eta_1..eta_4`, `p_1..p_4`.

/// Sample identifier column (Int64), present in every per-sample artifact.
pub const SAMPLE_ID: &str = "sample_id";
/// Split label column (Utf8): [`SPLIT_TRAIN`], [`SPLIT_VALIDATION`] or [`SPLIT_TEST`].
pub const SPLIT: &str = "split";
/// Split label of training samples.
pub const SPLIT_TRAIN: &str = "train";
/// Split label of validation samples.
pub const SPLIT_VALIDATION: &str = "validation";
/// Split label of test samples (held out from every choice; Table 4 is scored on them).
pub const SPLIT_TEST: &str = "test";
/// Time column (s).
pub const TIME: &str = "t";
/// Position along the track of an irregularity profile (m).
pub const TRACK_X: &str = "x";
/// Irregularity profile value (m, positive downward like every displacement).
pub const TRACK_ETA: &str = "eta";

/// The 14 per-sample parameters, in the order of the spec's parameter table (SI units;
/// `v_kmh` in km/h).
pub const PARAMETERS: [&str; 14] = [
    "m_c", "j_c", "m_t", "j_t", "m_w", "k_p", "c_p", "k_s", "c_s", "l_c", "l_t", "v_kmh", "k_f",
    "c_f",
];

/// The ten vehicle degrees of freedom (m or rad), in equation order.
pub const VEHICLE_DOFS: [&str; 10] = [
    "z_c", "beta_c", "z_t1", "beta_t1", "z_t2", "beta_t2", "z_w1", "z_w2", "z_w3", "z_w4",
];
/// Rail displacement under each wheel (m).
pub const RAIL_UNDER_WHEEL: [&str; 4] = ["z_r1", "z_r2", "z_r3", "z_r4"];
/// Irregularity under each wheel (m).
pub const ETA_UNDER_WHEEL: [&str; 4] = ["eta_1", "eta_2", "eta_3", "eta_4"];
/// Wheel-rail contact force of each wheel (N).
pub const CONTACT_FORCES: [&str; 4] = ["p_1", "p_2", "p_3", "p_4"];
/// Suffix of first-derivative columns.
pub const VELOCITY_SUFFIX: &str = "_v";
/// Suffix of second-derivative columns.
pub const ACCELERATION_SUFFIX: &str = "_a";

/// The 14 solution channels the neural operator predicts: vehicle DOFs then rail.
pub fn solution_channels() -> Vec<&'static str> {
    VEHICLE_DOFS
        .iter()
        .chain(RAIL_UNDER_WHEEL.iter())
        .copied()
        .collect()
}

/// The 18 output channels the neural operator predicts, in channel order: the 14
/// [`solution_channels`] (displacements) then the contact forces [`CONTACT_FORCES`] (N).
pub fn output_channels() -> Vec<&'static str> {
    solution_channels()
        .into_iter()
        .chain(CONTACT_FORCES.iter().copied())
        .collect()
}

/// `z_c` -> `z_c_v`.
pub fn velocity(dof: &str) -> String {
    format!("{dof}{VELOCITY_SUFFIX}")
}

/// `z_c` -> `z_c_a`.
pub fn acceleration(dof: &str) -> String {
    format!("{dof}{ACCELERATION_SUFFIX}")
}

/// Every column of the simulation output, in file order.
pub fn simulation_columns() -> Vec<String> {
    let mut cols = vec![SAMPLE_ID.to_owned(), TIME.to_owned()];
    cols.extend(VEHICLE_DOFS.iter().map(|s| s.to_string()));
    cols.extend(RAIL_UNDER_WHEEL.iter().map(|s| s.to_string()));
    cols.extend(VEHICLE_DOFS.iter().map(|s| velocity(s)));
    cols.extend(VEHICLE_DOFS.iter().map(|s| acceleration(s)));
    cols.extend(ETA_UNDER_WHEEL.iter().map(|s| s.to_string()));
    cols.extend(CONTACT_FORCES.iter().map(|s| s.to_string()));
    cols
}

/// ODE magnitude weight columns `phi_1..phi_10`.
pub fn phi_columns() -> Vec<String> {
    (1..=10).map(|i| format!("phi_{i}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulation_columns_are_unique_and_complete() {
        let cols = simulation_columns();
        let set: std::collections::BTreeSet<_> = cols.iter().collect();
        assert_eq!(set.len(), cols.len());
        // keys 2, solutions 14, derivatives 20, eta 4, forces 4
        assert_eq!(cols.len(), 2 + 14 + 20 + 4 + 4);
        assert!(cols.contains(&"beta_t2_a".to_owned()));
    }
}
