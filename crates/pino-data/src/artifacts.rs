//! The file names of every artifact the stages write and read: declared here once, looked up
//! by name (a stage's inputs are found by these names in its upstream directories, so they are
//! part of the public contract, `docs/model.md`).

/// The sampled designs `sample-params` writes: `sample_id`, `split`, then every sampled
/// parameter of the description in its unit ([`crate::records::read_params`] reads it).
pub const PARAMS_FILE: &str = "params.parquet";
/// Each sampled parameter's range (`name`, `unit`, `min`, `max`): `train` stores it with every
/// model so that `predict` flags designs outside it.
pub const RANGES_FILE: &str = "ranges.parquet";
/// The generated profile of every sample (`irregularity`): `sample_id`, `x`, `eta` (and
/// `profile` with several generated profiles).
pub const IRREGULARITY_FILE: &str = "irregularity.parquet";
/// File `irregularity` writes beside its profiles: the generator's controls (seed, dx, length).
pub const PROFILES_FILE: &str = "profiles.json";
/// The trajectories of one `simulate` shard: `sample_id`, `t`, every stored channel.
pub const SIMULATION_FILE: &str = "simulation.parquet";
/// The samples of one `simulate` shard whose state became non-finite: `sample_id`, `reason`.
pub const FAILURES_FILE: &str = "failures.parquet";
/// The run controls of a simulated dataset as a table ([`crate::provenance`]).
pub const PROVENANCE_FILE: &str = "provenance.parquet";
/// File `simulate` writes beside every dataset shard: `{"run": <the run controls>,
/// "profiles": <the irregularity stage's profiles.json, or null>}`, how the data were made.
pub const RUN_FILE: &str = "run.json";
/// The ODE magnitude weights of the training samples (`weights`): `sample_id`, `phi_<dof>`.
pub const WEIGHTS_FILE: &str = "weights.parquet";
/// The engineering indices of every simulated sample (`indices`).
pub const INDICES_FILE: &str = "indices.parquet";
/// The indices' settings, units and definitions (`indices`).
pub const INDICES_META_FILE: &str = "indices.json";
/// A trained model's weights (`train`).
pub const MODEL_WEIGHTS: &str = "model.safetensors";
/// A trained model's sidecar: its configuration, layout, normalisation and provenance.
pub const MODEL_META: &str = "model.json";
/// The loss and validation errors of every epoch of a training (`train`).
pub const HISTORY_FILE: &str = "history.parquet";
