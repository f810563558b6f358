//! The column names every pino-mbd artifact shares (the public schema; `docs/protocol.md`).
//! The columns of a system's signals, parameters and indices are the system description's
//! (`docs/systems.md`, the column rule), known from the compiled description, not here.

/// Sample identifier column (Int64), present in every per-sample artifact.
pub const SAMPLE_ID: &str = "sample_id";
/// Split label column (Utf8): `train`, `validation`, `test` or `calibration`, the labels of
/// `mbd_dataset::Split` (their one home, with what each split is for).
pub const SPLIT: &str = "split";
/// Time column (s).
pub const TIME: &str = "t";
/// Position along the track of an irregularity profile (m).
pub const TRACK_X: &str = "x";
/// Irregularity profile value (m, positive downward like every displacement).
pub const TRACK_ETA: &str = "eta";
/// The generated profile a row belongs to (its name in the description), present when a
/// description has several.
pub const PROFILE: &str = "profile";
