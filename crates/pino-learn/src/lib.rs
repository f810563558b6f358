//! The learning half of pino-mbd: a 1-D Fourier neural operator over time that maps a described
//! system's sampled parameters and the excitations under its elements to its solution channels,
//! trained as FNO, PINO or PINO-MBD (`docs/learning.md`, the paper's sections 3 and 4.2). Every
//! channel name and count comes from the system description ([`layout::Layout`]).
//!
//! Tensors (one sample, `T` time points of the training window, spacing `dt`):
//! - input `a` `[T, 1 + E + P]`: `t`, the `E` excitation columns, the `P` sampled parameters
//!   broadcast over time;
//! - output `u` `[T, S + F]`: the `S` solutions (the rigid DOFs' displacements first, then the
//!   displacements stored under moving points and at sensors) and the `F` stored element forces;
//!
//! every channel z-scored with training-split statistics ([`norm`]). For the vehicle-track
//! description that is 19 inputs and `z_c, beta_c, .., z_w4, z_r1..z_r4, p_1..p_4` (18 outputs,
//! 14 solutions). The model ([`model::Fno`]) is
//! ```text
//! u = Q( (K_L + W_L) ... GELU((K_1 + W_1)( P(a) )) )      K_l v = F^-1( R_l . F v )  (lowest M modes)
//! ```
//! with the spectral convolution `K` in [`spectral`]. Derivatives of predictions are central
//! differences; the losses of the five algorithms of Table 3 are in [`loss`]:
//! ```text
//! L_data  = mean_k ||u_k - u*_k|| / ||u*_k||                      (z-scored outputs)
//! L_deriv = relL2(v) + relL2(a)                                   (the rigid DOFs, z-scored)
//! L_ode_global = mean_{i,t} |R_i| / F_ref      L_ode_phi = mean_{i,t} rho |R_i| / phi_ki
//! ```
//! `R_i` the equations of motion of the DOFs whose forces close on the outputs and inputs, in
//! physical units (N, N m), computed by the engine's own element code ([`residual`]).
//!
//! Modules: [`layout`] (channels from the description), [`config`] (algorithms, sizes),
//! [`data`] (Parquet -> samples, streamed), [`store`] (sample series in memory or spilled),
//! [`norm`], [`spectral`], [`model`], [`residual`] and [`loss`], [`weights`] (ODE magnitude
//! weights), [`optim`] (Adam, step decay), [`checkpoint`], [`train`] and [`infer`] (batched
//! inference). The small consistent datasets its tests and benchmarks train on are the
//! `learn-fixtures` crate's (a dev-dependency).
//!
//! This crate is the neural-operator engine: it knows no particular system, only what a
//! description says. What an engineer reads of a trained model (Table 4, per-channel errors,
//! the engineering indices against the solver, predictions of designs) is the `pino-eval`
//! crate's.
#![warn(missing_docs)]

pub mod checkpoint;
pub mod config;
pub mod data;
pub mod infer;
pub mod kernels;
pub mod layout;
pub mod loss;
pub mod model;
pub mod norm;
pub mod optim;
pub mod residual;
pub mod spectral;
pub mod store;
pub mod train;
pub mod weights;

// The unit tests' datasets: learn-fixtures' `synthetic` module, compiled into this crate's test
// build from its one source (a dev-dependency on learn-fixtures would link a second copy of
// this crate, whose types are not these). The module names this crate `pino_learn`.
#[cfg(test)]
extern crate self as pino_learn;
#[cfg(test)]
#[allow(dead_code)] // the items only other crates' tests use
#[path = "../../learn-fixtures/src/synthetic.rs"]
mod synthetic;

pub use config::{Algorithm, DeviceKind, ModelConfig, TrainConfig};

/// Keeps freed memory in the process for reuse instead of returning it to the kernel.
///
/// A training step allocates and frees the same few megabytes of activations and gradients
/// every time; with glibc's defaults each large buffer is a fresh `mmap` whose pages fault in
/// and are zeroed by the kernel on every step (about a tenth of a CPU step, measured with
/// `perf`). Raising the mmap and trim thresholds keeps those buffers in the heap. Two arenas:
/// with glibc's default (up to eight per core), buffers freed by a thread other than the one
/// that allocated them fragment the arenas and the resident set grew by ~3.6 MB per step at
/// the paper's sizes (1.26 -> 1.44 GB from the first to the second epoch of 50 steps); with
/// two it stays flat (1.2-1.3 GB after 50, 100 and 150 steps); with one, the threads of a
/// parallel prediction queue on its lock (inference 20 % slower). BENCHMARKS.md, "Training
/// memory at the paper's sizes". Call once at the start of a learning process; a no-op
/// elsewhere than glibc.
pub fn tune_allocator() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters; it is called with valid option codes.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 30);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
        libc::mallopt(libc::M_ARENA_MAX, 2);
    }
}

use std::path::PathBuf;

/// Errors of the learning library; each names the file, field or tensor at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The data layer failed (missing column, unreadable file, ...).
    #[error(transparent)]
    Data(#[from] pino_data::Error),
    /// candle failed.
    #[error("tensor: {0}")]
    Tensor(#[from] candle_core::Error),
    /// A file system error on a named file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A JSON or YAML file is malformed.
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        message: String,
    },
    /// Algorithm id outside 1..=5.
    #[error("unknown algorithm {0}: allowed are 1 (FNO), 2 (PINO), 3 (PINO-MBD ODE weights), 4 and 5 (PINO-MBD direct derivatives)")]
    UnknownAlgorithm(i64),
    /// A design that does not fit the system's sampled parameters (count or names).
    #[error(transparent)]
    Design(Box<mbd_system::SampledError>),
    /// A rate output the description does not store (`train`'s `rate_outputs`).
    #[error("params.rate_outputs: {0}")]
    RateOutputs(String),
    /// A configuration value is outside its allowed range.
    #[error("`{field}` = {value} is out of range: {allowed}")]
    OutOfRange {
        /// The field.
        field: String,
        /// Its value, as text.
        value: String,
        /// The allowed range.
        allowed: String,
    },
    /// The dataset is inconsistent (record lengths, time grids, splits, ids).
    #[error("{path}: {message}")]
    Dataset {
        /// The file at fault.
        path: PathBuf,
        /// What is wrong, with the offending values.
        message: String,
    },
    /// A model file does not match its configuration (another width, depth, ...).
    #[error("{path}: tensor `{tensor}` has shape {found:?}, the configuration {config} needs {expected:?}")]
    ModelMismatch {
        /// The weights file.
        path: PathBuf,
        /// The tensor name.
        tensor: String,
        /// Its shape in the file.
        found: Vec<usize>,
        /// The shape the configuration needs.
        expected: Vec<usize>,
        /// The configuration, as text (boxed: keeps every `Result` of this crate small).
        config: Box<str>,
    },
    /// A model file holds a tensor its configuration does not have (another depth, ...).
    #[error("{path}: tensor `{tensor}` is not part of the configuration {config} (a model file from another configuration?)")]
    UnexpectedTensor {
        /// The weights file.
        path: PathBuf,
        /// The tensor name.
        tensor: String,
        /// The configuration, as text.
        config: String,
    },
    /// Computing something of one sample failed (the cause is the source).
    #[error("sample {id}")]
    Sample {
        /// The sample id.
        id: i64,
        /// What failed.
        #[source]
        source: Box<Error>,
    },
    /// A sample's records appear in more than one dataset file.
    #[error("sample {0} appears in more than one dataset file")]
    DuplicateSample(i64),
    /// Training diverged (a loss is not finite).
    #[error("training diverged at epoch {epoch}, step {step}: loss = {loss}")]
    Diverged {
        /// Epoch (1-based).
        epoch: usize,
        /// Optimizer step.
        step: u64,
        /// The loss value.
        loss: f64,
    },
}

impl From<mbd_system::SampledError> for Error {
    fn from(e: mbd_system::SampledError) -> Self {
        Error::Design(Box::new(e))
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// A failed atomic write ([`atomic_file::write_atomic`]) is an I/O error on its path.
impl From<atomic_file::Error> for Error {
    fn from(e: atomic_file::Error) -> Self {
        Error::Io {
            path: e.path,
            source: e.source,
        }
    }
}

/// An [`Error::Io`] on `path`.
pub fn io_err(path: &std::path::Path, source: std::io::Error) -> Error {
    Error::Io {
        path: path.to_owned(),
        source,
    }
}

/// Makes candle (and rayon) single-threaded unless `CANDLE_NUM_THREADS` / `RAYON_NUM_THREADS`
/// are set. Call first thing in `main`, before any tensor exists. On the shared 2-core
/// development machine candle's worker pool spin-waits for descheduled workers, and one
/// thread measured about 1.5-2x faster than two (BENCHMARKS.md, Learning); results do not
/// depend on the thread count.
pub fn single_threaded_by_default() {
    for var in ["CANDLE_NUM_THREADS", "RAYON_NUM_THREADS"] {
        if std::env::var_os(var).is_none() {
            // Single-threaded at this point: nothing else reads the environment yet.
            std::env::set_var(var, "1");
        }
    }
}

/// For inference stages (`evaluate`, `predict`): candle's own pool single-threaded (its
/// spin-waiting workers are the problem above) while the fused kernels, which do all the work
/// of a CPU forward pass, use rayon on every core. Call first thing in `main`.
pub fn candle_single_threaded_by_default() {
    if std::env::var_os("CANDLE_NUM_THREADS").is_none() {
        // Single-threaded at this point: nothing else reads the environment yet.
        std::env::set_var("CANDLE_NUM_THREADS", "1");
    }
}
