//! A trained model's outputs as an engineer reads them, for any described system: the ground
//! that prediction, calibration, the surrogate and evaluation stand on. The neural-operator
//! engine itself (layout, model, losses, training, inference) is `pino-learn`.
//!
//! - [`physical`]: a prediction and the exact series in physical units (the network's z-scored
//!   outputs back to SI, the rigid DOFs' rates by central differences).
//! - [`channels`]: the channels of a prediction and where each comes from in its physical
//!   series.
//! - [`indices_eval`]: the description's engineering indices of a prediction (the railway
//!   family bound by name, or the description's simple indices), from the predicted outputs and
//!   central-difference rates, and their errors against the solver.
//! - [`split`]: the split an evaluation scores, loaded once per window and statistics.
//!
//! Errors ([`error`]) are the engine's ([`pino_learn::Error`]), each naming the file, field or
//! tensor at fault, or a report file's; the crates above return the same type.
#![warn(missing_docs)]

pub mod channels;
pub mod error;
pub mod indices_eval;
pub mod physical;
pub mod split;

pub use error::{Error, Result};
