//! Reference problems of the physics tests, kept once and shared by every test that needs them
//! (the engine's, the residuals', the pipeline's): closed forms and an independent reference
//! solver, each written from public textbook mathematics, none from this project's engine code.
//!
//! - [`complex`]: a minimal complex number for the frequency responses.
//! - [`quarter_car`]: the two-mass quarter car's frequency response to a road (a 2x2 complex
//!   solve): sprung and unsprung displacement, sprung acceleration, suspension travel, dynamic
//!   tyre force.
//! - [`road`]: the ISO 8608 displacement PSD, its band power, the discrete spectral sum of a
//!   random-phase generator's own bins through a response, the gain of linear interpolation.
//! - [`beam`]: the simply supported Euler-Bernoulli beam: natural frequencies, Fryba's series for
//!   a constant force crossing it, the static deflection `P L^3 / (48 E I)`.
//! - [`ode`]: an adaptive Dormand-Prince 5(4) Runge-Kutta integrator.
//! - [`moving_mass`]: a sprung mass crossing a modal beam (Biggs 1964; Yang and Yau 1997), its
//!   modal ODEs written out and solved by [`ode`] to a tight tolerance.
//! - [`vehicle_track`]: the railway half vehicle's ten equations of motion written out by hand,
//!   its static wheel load and Hertz's wheel-rail contact.
//!
//! Units are SI throughout. Each module states its sign convention.
//!
//! ```
//! use mbd_test_models::beam::{static_midspan, SimpleBeam};
//! let beam = SimpleBeam { length: 25.0, mass_per_length: 2303.0, bending_stiffness: 8.323e9 };
//! // P L^3 / (48 E I) for 56.4 kN at mid-span of the 25 m bridge: about 2.2 mm.
//! let w = static_midspan(56_407.5, beam.length, beam.bending_stiffness);
//! assert!((w - 2.206e-3).abs() < 1e-6);
//! ```
#![warn(missing_docs)]

pub mod beam;
pub mod complex;
pub mod moving_mass;
pub mod ode;
pub mod quarter_car;
pub mod road;
pub mod vehicle_track;
