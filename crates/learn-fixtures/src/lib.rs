//! Test fixtures of the learning half, kept once for every test and benchmark that trains,
//! evaluates or predicts (pino-learn's, pino-eval's, the end-to-end tests'): [`synthetic`]
//! simulates small, exactly consistent datasets from a system description (the vehicle-track
//! one by default) and writes the files the physics stages would write. Test-only: a
//! dev-dependency, never shipped in a product crate.
//!
//! pino-learn's own unit tests compile [`synthetic`]'s source into their test build (its
//! `#[path]` module), as a dev-dependency on this crate would link a second copy of
//! pino-learn's types; the module therefore names pino-learn as `pino_learn` throughout.
#![warn(missing_docs)]

pub mod synthetic;
