//! What an engineer reads of a trained model, for any described system: the model against the
//! solver and the model on new designs. The neural-operator engine itself (layout, model,
//! losses, training, inference) is `pino-learn`; this crate knows which channels, groups and
//! indices a description declares and turns predictions into what people read.
//!
//! - [`calibration`]: conformal calibration of a model on held-out solver runs (the
//!   `calibrate` stage), the intervals, bands and three-valued verdicts it gives an answer,
//!   and its coverage on the test split.
//! - [`eval`]: Table 4 on the test split (solutions, first and second derivatives of the DOFs,
//!   the force outputs) with the truth row, per-channel errors in the description's units,
//!   plots of channels chosen by name, the engineering indices against the solver; the files of
//!   the `evaluate` stage (written through the `report` crate).
//! - [`indices_eval`]: the description's engineering indices of a prediction (the railway
//!   family bound by name, or the description's simple indices), from the predicted outputs and
//!   central-difference rates.
//! - [`predict`]: designs by parameter name (sets, grids, random sweeps) through a trained
//!   model, with the training ranges checked and the excitations regenerated or read; the
//!   `predict` command's library.
//! - [`surrogate`]: several trained models behind one answer, each index and channel from the
//!   model most accurate on it over the validation split, with its calibration (the
//!   `surrogate` stage's artifact, or one model alone).
//! - [`solve`]: a design through the exact solver in a prediction's form (the explorer's
//!   "Solve exactly", the studies' solver checks).
//!
//! Errors ([`error`]) are the engine's ([`pino_learn::Error`]), each naming the file, field or
//! tensor at fault, or a report file's.
#![warn(missing_docs)]

pub mod calibration;
pub mod error;
pub mod eval;
pub mod indices_eval;
pub mod predict;
pub mod solve;
pub mod study;
pub mod surrogate;

pub use error::{Error, Result};
