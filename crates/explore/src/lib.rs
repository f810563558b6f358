//! The design explorer behind the `explore` binary (`docs/explore.md`): a trained model of any
//! described system opened for design work, served as a web page and a JSON API.
//!
//! - [`session`]: the model session: summary, prediction, sweep, exact solve, keyed by the
//!   description's names; [`solve`]: the solver run and its comparison with the prediction;
//! - [`request`]: requests parsed and validated, errors naming the field and the allowed range;
//! - [`download`]: the design and curve files, each with the model's identity and excitation;
//!   [`encoding`]: the compact (float32) curves of an answer;
//! - [`channel`]: the channels of the summary, by family, with where each is predicted;
//! - [`glance`]: the pipeline at a glance and the model found through the orchestrator's record;
//! - [`studies`]: the pipeline's studies and those started from the sweep view; [`tables`]: the
//!   CSV tables of the pipeline's outputs as the page reads them;
//! - [`client`]: the blocking HTTP client of the load benchmark and the tests;
//! - [`server`]: axum routes and the solve gate; [`guard`]: what every request passes (host and
//!   token of [`access`], its body within the deadline) and every answer gets (JSON errors,
//!   [`compress`]ion, security headers); [`serve`]: the accept loop with its timeouts and
//!   connection cap; [`assets`]: the embedded pages.
#![warn(missing_docs)]

pub mod access;
pub mod assets;
pub mod channel;
pub mod client;
pub mod compress;
pub mod download;
pub mod encoding;
pub mod glance;
pub mod guard;
pub mod request;
pub mod serve;
pub mod server;
pub mod session;
pub mod solve;
pub mod studies;
pub mod tables;
