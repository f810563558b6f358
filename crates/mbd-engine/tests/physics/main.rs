//! Physics tests of the generic engine, one topic per module, each against mathematics written
//! outside the engine: closed forms and an independent Runge-Kutta reference kept once in
//! `mbd-test-models`, or equations written out in the test from `docs/model.md`. Every test
//! asserts that its setup is meaningful (the quantity compared is far from trivial) and states
//! the origin of each tolerance.
//!
//! - [`quarter_car`]: `systems/quarter-car.yaml` on a harmonic road against the 2x2 frequency
//!   response (1e-4), and on random ISO 8608 roads against the generator's discrete spectral
//!   sum.
//! - [`bridge`]: `systems/bridge.yaml`'s deck under a moving constant force against Fryba's
//!   series (1e-4 of the peak) and, crawling, against `P L^3 / (48 E I)` (1e-4); the sprung
//!   mass entering, crossing and leaving the deck against a Dormand-Prince solution of the same
//!   modal ODEs (~1e-6 of the peak, second order).
//! - [`routes`]: the fast path equals the general route (1e-10 per column) for the dynamics and
//!   the equilibrium of the vehicle-track model.
//! - [`linear`]: symmetric stiffness and damping; the stability bound above the true highest
//!   frequency; a too large step refused.
//! - [`profile_order`]: a damper on a cubic profile keeps the solver's second order (error
//!   ratio >= 3.5 per halving of dt) on the bridge and a two-axle vehicle; on a linear one it
//!   stalls. The vehicle track's wheels, on Hertz contacts with no damper, ring at a linear
//!   profile's point rate (over 4 % of the forces' spread above 300 Hz), a third of that or
//!   less with the cubic spline.
//! - [`energy`]: energy conserved without damping to Zhai's O(dt^2).
//! - [`equilibrium`]: the equilibrium start balances every force; stored rows satisfy the
//!   equations of motion; Hertz compression `G W^(2/3)` under each wheel.
//!
//! The vehicle-track tests run a short-track variant of `systems/vtcd.yaml` (60 supports, 30
//! modes: the full track's modal wavenumbers per metre) so each takes well under a second.

mod bridge;
mod common;
mod energy;
mod equilibrium;
mod hunting;
mod linear;
mod profile_order;
mod quarter_car;
mod routes;
mod spatial;
mod wheelset;
