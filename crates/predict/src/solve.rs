//! A design through the exact solver beside its prediction: the `simulate` stage's engine
//! ([`mbd_engine::Engine`]) with the model's run controls and the same profiles as the
//! prediction, cut to the model's window (the rows whose times equal the window's), in a
//! prediction's form, with the stored columns the indices read. The explorer's "Solve
//! exactly" and the studies' solver checks both run designs through here.
//!
//! A run can be cancelled: the engine checks a flag at every output step.

use crate::{Predictor, SetPrediction};
use mbd_engine::{Engine, Profile, RunConfig};
use pino_indices::IndexConfig;
use pino_learn::checkpoint::ModelMeta;
use pino_outputs::indices_eval::{SampleIndices, StoredColumns};
use pino_outputs::physical::Physical;
use std::sync::atomic::{AtomicBool, Ordering};

/// Why a design could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// The description or the solver refuses the design (values out of range, profiles that
    /// do not cover the run).
    #[error("{0}")]
    Refused(String),
    /// The run stopped on its cancel flag.
    #[error("cancelled")]
    Cancelled,
    /// The response did not stay finite.
    #[error("the solver failed for this design: {0}")]
    Failed(String),
    /// The solver's rows do not match the model's window (a model of another run).
    #[error("{0}")]
    Window(String),
    /// Computing the indices failed.
    #[error("{0}")]
    Indices(String),
}

/// The solver's values over the model's window: outputs `[T, O]`, velocities and accelerations
/// `[T, D]` at every window point and excitations `[T, E]` (in a prediction's form), and the
/// stored columns the indices read beside them (each `T` long).
#[derive(Debug, Clone)]
pub struct Exact {
    /// Outputs, exact derivatives, excitations.
    pub values: SetPrediction,
    /// The index inputs' stored columns.
    pub stored: Vec<Vec<f64>>,
}

/// Runs `design` with `profiles` and cuts the trajectory to the model's window; stops early
/// when `cancel` is set.
pub fn exact(
    predictor: &Predictor,
    run: &RunConfig,
    design: &[f64],
    profiles: &[Option<Profile>],
    cancel: Option<&AtomicBool>,
) -> Result<Exact, SolveError> {
    let system = predictor.system().clone();
    let meta = &predictor.meta;
    let model = predictor
        .space
        .check(design, "design")
        .map_err(|e| SolveError::Refused(e.to_string()))?;
    let engine = Engine::new(system.clone(), model, run, profiles.to_vec())
        .map_err(|e| SolveError::Refused(e.to_string()))?;
    let traj = engine.run_cancellable(cancel).map_err(|f| {
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            SolveError::Cancelled
        } else {
            SolveError::Failed(f.reason.to_string())
        }
    })?;
    let rows = window_rows(&traj.t, meta)?;
    let column = |name: &str| -> Result<Vec<f64>, SolveError> {
        let c = system.channel(name).ok_or_else(|| {
            SolveError::Window(format!("`{name}` is not a channel of the system"))
        })?;
        Ok(rows.iter().map(|&r| traj.columns[c][r]).collect())
    };
    let interleave = |names: &[String]| -> Result<Vec<f64>, SolveError> {
        let cols: Vec<Vec<f64>> = names.iter().map(|n| column(n)).collect::<Result<_, _>>()?;
        Ok((0..rows.len())
            .flat_map(|n| cols.iter().map(move |c| c[n]))
            .collect())
    };
    let layout = &meta.layout;
    let stored = predictor
        .index_inputs()
        .stored_columns()
        .into_iter()
        .map(column)
        .collect::<Result<_, _>>()?;
    Ok(Exact {
        values: SetPrediction {
            physical: Physical {
                u: interleave(&layout.outputs)?,
                v: interleave(&layout.velocities())?,
                a: interleave(&layout.accelerations())?,
            },
            eta: interleave(&layout.excitations)?,
        },
        stored,
    })
}

/// The indices of `design` from its exact solution (the solver's rates and stored columns,
/// over the window's interior points as a prediction's).
pub fn exact_indices(
    predictor: &Predictor,
    design: &[f64],
    exact: Exact,
    cfg: &IndexConfig,
) -> Result<SampleIndices, SolveError> {
    let inputs = predictor.index_inputs();
    let stored = StoredColumns::of_sample(inputs, 0, exact.stored);
    inputs
        .sample(
            predictor.system(),
            &predictor.meta.layout,
            design,
            0,
            &exact.values.physical,
            Some(&stored),
            &exact.values.eta,
            &predictor.meta.grid,
            cfg,
        )
        .map_err(|e| SolveError::Indices(e.to_string()))
}

/// The trajectory row of each of the window's times.
fn window_rows(t: &[f64], meta: &ModelMeta) -> Result<Vec<usize>, SolveError> {
    let (first, step) = match t {
        [a, b, ..] => (*a, b - a),
        _ => {
            return Err(SolveError::Window(
                "the solver stored fewer than two rows".into(),
            ))
        }
    };
    meta.grid
        .times()
        .iter()
        .map(|&tw| {
            let r = ((tw - first) / step).round();
            let ok = r >= 0.0 && (r as usize) < t.len() && (t[r as usize] - tw).abs() <= 1e-6 * step;
            ok.then_some(r as usize).ok_or_else(|| {
                SolveError::Window(format!(
                    "the model's window time {tw} s is not an output time of the solver's run (rows every {step} s from {first} s)"
                ))
            })
        })
        .collect()
}
