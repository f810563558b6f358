//! "Solve exactly": one design through the exact solver ([`pino_predict::solve`])
//! with the dataset's run controls and the same profiles as its prediction, cut to the model's
//! window (the rows whose times equal the window's), and compared with the prediction channel
//! by channel (relative L2 error) and index by index.
//!
//! The run is cancellable: the engine checks a flag at every output step, so a solve whose
//! client went away stops within one output interval.

use crate::channel::Channel;
use crate::request::ApiError;
use mbd_engine::{Profile, RunConfig};
use pino_learn::checkpoint::ModelMeta;
use pino_outputs::channels::ChannelSource;
pub use pino_predict::solve::Exact;
use pino_predict::solve::SolveError;
use pino_predict::{Predictor, SetPrediction};
use std::sync::atomic::AtomicBool;

/// The error of a solve stopped by its cancel flag.
pub const CANCELLED: &str = "cancelled";

/// Runs `design` with `profiles` ([`pino_predict::solve::exact`]), its refusals blamed on the
/// design.
pub fn exact(
    predictor: &Predictor,
    run: &RunConfig,
    design: &[f64],
    profiles: &[Option<Profile>],
    cancel: &AtomicBool,
) -> Result<Exact, ApiError> {
    pino_predict::solve::exact(predictor, run, design, profiles, Some(cancel)).map_err(
        |e| match e {
            SolveError::Refused(why) => ApiError::bad("design", why, "a design the solver accepts"),
            SolveError::Cancelled => {
                ApiError::bad("design", CANCELLED, "a client that waits for its answer")
            }
            e @ SolveError::Failed(_) => ApiError::bad(
                "design",
                e.to_string(),
                "a design whose response stays finite",
            ),
            SolveError::Window(why) | SolveError::Indices(why) => ApiError::internal(why),
        },
    )
}

/// Which window points a [`SetPrediction`]'s velocities and accelerations cover.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Rates {
    /// The interior points `1..T-1` (a prediction's central differences).
    Interior,
    /// Every point (the solver's exact rates).
    EveryPoint,
}

/// The window's interior times (`n = 1..T-2`, s) and, per channel, its values there from
/// `source` of the channel: the prediction holding it (with its model's layout), where, and
/// which points its rates cover; a channel without one is NaN throughout.
pub(crate) fn curves<'a>(
    channels: &[Channel],
    grid: &pino_learn::checkpoint::TimeGrid,
    source: impl Fn(&Channel) -> Option<(&'a SetPrediction, &'a ModelMeta, ChannelSource, Rates)>,
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let times = grid.times();
    let rows = 1..times.len() - 1;
    let curves = channels
        .iter()
        .map(|c| match source(c) {
            Some((p, meta, slot, rates)) => rows
                .clone()
                .map(|n| value(p, meta, slot, rates, n))
                .collect(),
            None => vec![f64::NAN; rows.len()],
        })
        .collect();
    (times[rows].to_vec(), curves)
}

/// The value of `slot` of prediction `p` (laid out as `meta`'s model) at window row `n`.
fn value(p: &SetPrediction, meta: &ModelMeta, slot: ChannelSource, rates: Rates, n: usize) -> f64 {
    let layout = &meta.layout;
    let (o, d, e) = (layout.n_outputs(), layout.n_dofs(), layout.n_excitations());
    let r = match rates {
        Rates::Interior => n - 1,
        Rates::EveryPoint => n,
    };
    let ph = &p.physical;
    match slot {
        ChannelSource::Output(i) => ph.u[n * o + i],
        ChannelSource::Velocity(j) => ph.v[r * d + j],
        ChannelSource::Acceleration(j) => ph.a[r * d + j],
        ChannelSource::Excitation(j) => p.eta[n * e + j],
    }
}

/// `||pred - exact|| / ||exact||` (0 when both vanish, infinite when only the exact does).
pub fn relative_l2(pred: &[f64], exact: &[f64]) -> f64 {
    let num: f64 = pred.iter().zip(exact).map(|(p, e)| (p - e) * (p - e)).sum();
    let den: f64 = exact.iter().map(|e| e * e).sum();
    match (num == 0.0, den == 0.0) {
        (true, _) => 0.0,
        (false, true) => f64::INFINITY,
        _ => (num / den).sqrt(),
    }
}

/// `(pred - exact) / |exact|`.
pub fn relative_error(pred: f64, exact: f64) -> f64 {
    if pred == exact {
        0.0
    } else {
        (pred - exact) / exact.abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_errors_are_scale_free_and_handle_zeros() {
        assert_eq!(relative_l2(&[1.0, 2.0], &[1.0, 2.0]), 0.0);
        let e = relative_l2(&[3.0, 4.0], &[0.0, 5.0]);
        assert!((e - (9.0f64 + 1.0).sqrt() / 5.0).abs() < 1e-15);
        assert_eq!(
            relative_l2(&[2e3, 4e3], &[1e3, 2e3]),
            relative_l2(&[2.0, 4.0], &[1.0, 2.0])
        );
        assert_eq!(relative_l2(&[0.0], &[0.0]), 0.0);
        assert!(relative_l2(&[1.0], &[0.0]).is_infinite());
        assert_eq!(relative_error(110.0, -100.0), 2.1);
        assert_eq!(relative_error(0.0, 0.0), 0.0);
    }
}
