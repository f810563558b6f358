//! System descriptions: a multibody model written in YAML (`systems/*.yaml`, format in
//! `docs/systems.md`), read in three steps.
//!
//! 1. **Parse** ([`yaml`], [`schema`]): the text becomes typed records that keep their line and
//!    column; shapes are checked (a mass is a number or an expression, a DOF is `z` or
//!    `pitch`, unknown fields are named with the allowed ones).
//! 2. **Validate and compile** ([`compile`]): every name is resolved once to an index
//!    (parameters, bodies, points, beams, profiles, elements), every problem is reported with
//!    its line, and the result is a [`System`]: flat tables of expressions over the parameter
//!    table, the generalised-force assembly of every DOF, and the stored column layout.
//! 3. **Instantiate** ([`System::instantiate`]): one design's sampled values (a [`Sampled`],
//!    made by the system with its count and names checked) give a [`model::Model`] of
//!    numbers, every field checked against its domain.
//!
//! Conventions of every description: SI units; vertical displacements positive **downward**,
//! measured from the static equilibrium on rigid supports (gravity enters as the declared
//! `loads`); pitch positive **nose-up**; `x` positive **forward**, so a body point at `x`
//! moves down by `z - x beta`.
//!
//! ```
//! let text = "format: 1\nname: one mass\nparameters:\n  m: {unit: kg, nominal: 2, range: [1, 3]}\n  k: {unit: N/m, value: 800}\nbodies:\n  b: {mass: m, dofs: [z]}\nelements:\n  spring: {kind: spring_damper, from: b, to: ground, k: k}\n";
//! let system = mbd_system::load_str(text, "one.yaml", &Default::default()).unwrap();
//! assert_eq!(system.sampled_names(), ["m"]);
//! let model = system.instantiate(&system.sampled_values([2.0]).unwrap()).unwrap();
//! assert_eq!(model.dof_mass, [2.0]);
//! ```
#![warn(missing_docs)]

pub mod checks;
pub mod compile;
pub mod diag;
pub mod expr;
pub mod model;
pub mod reader;
pub mod sampled;
pub mod schema;
pub mod source;
pub mod system;
pub mod yaml;

pub use compile::{load_str, load_with_overrides, LoadError, Override, OverrideError};
pub use diag::Diagnostics;
pub use sampled::{Sampled, SampledError};
pub use source::{SourceError, SystemSource, SYSTEM_FILE};
pub use system::System;
