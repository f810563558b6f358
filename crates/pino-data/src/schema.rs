//! The column names every pino-mbd artifact shares (the public schema; `docs/protocol.md`).
//! The columns of a system's signals, parameters and indices are the system description's
//! (`docs/systems.md`, the column rule), known from the compiled description, not here.

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
/// The generated profile a row belongs to (its name in the description), present when a
/// description has several.
pub const PROFILE: &str = "profile";
