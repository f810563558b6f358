//! Checked engines and their runs: an [`Engine`] built with its checks (run controls, coverage
//! of beams and profiles, the time step against the stability bound of [`crate::stability`]),
//! started at rest or in the static equilibrium of [`crate::statics`], run to its stored rows,
//! and many samples prepared and run in parallel.

use crate::config::{RunConfig, StartMode};
use crate::engine::{Engine, Failure, Route, StepView};
use crate::profile::Profile;
use crate::{Error, Result};
use mbd_system::model::Model;
use mbd_system::System;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Stored rows of one sample: `t` and one column per stored channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Output times (s).
    pub t: Vec<f64>,
    /// Channel columns in [`System::channels`] order, each `t.len()` long.
    pub columns: Vec<Vec<f64>>,
}

impl Engine {
    /// Assembles one sample's model on the fast path; see [`Engine::with_route`].
    pub fn new(
        system: Arc<System>,
        model: Model,
        config: &RunConfig,
        profiles: Vec<Option<Profile>>,
    ) -> Result<Self> {
        Self::with_route(system, model, config, profiles, Route::Fast)
    }

    /// Assembles one sample's model. `profiles[p]` supplies the points of generated profile
    /// `p` (`None`: a level profile). Checks the run controls, that the moving points stay on
    /// the beams that refuse leavers and, while the profiles are on, on their profiles, and the
    /// time step against the stability bound ([`crate::stability`]).
    pub fn with_route(
        system: Arc<System>,
        model: Model,
        config: &RunConfig,
        profiles: Vec<Option<Profile>>,
        route: Route,
    ) -> Result<Self> {
        let engine = Self::assemble(system, model, config, profiles, route)?;
        crate::stability::Bound::of(&engine).check(config.dt)?;
        Ok(engine)
    }

    /// Displacements at `t = 0`: zero for [`StartMode::Rest`], the static equilibrium
    /// ([`crate::statics`]) for [`StartMode::Equilibrium`].
    pub fn initial_state(&self) -> Result<Vec<f64>> {
        match self.config.start {
            StartMode::Rest => Ok(vec![0.0; self.layout.len]),
            StartMode::Equilibrium => crate::statics::equilibrium(self),
        }
    }

    /// Runs from [`Engine::initial_state`] for `steps` steps, calling `observe` at every step
    /// (including step 0). Stops with a [`Failure`] on a non-finite element force or rigid
    /// acceleration (every step) or state (every output step), or when `cancel` is set (checked
    /// every output step; the failure then says so).
    pub fn run_observed(
        &self,
        steps: usize,
        cancel: Option<&AtomicBool>,
        observe: impl FnMut(&StepView),
    ) -> std::result::Result<(), Failure> {
        let x = self.initial_state().map_err(|e| Failure {
            t: 0.0,
            reason: format!("initial state: {e}"),
        })?;
        let v = vec![0.0; self.layout.len];
        self.run_observed_from(x, v, steps, cancel, observe)
    }

    /// Runs the configured duration and returns the stored rows.
    pub fn run(&self) -> std::result::Result<Trajectory, Failure> {
        self.run_cancellable(None)
    }

    /// As [`Engine::run`], stopping early when `cancel` is set.
    pub fn run_cancellable(
        &self,
        cancel: Option<&AtomicBool>,
    ) -> std::result::Result<Trajectory, Failure> {
        let n_out = self.config.n_outputs();
        let every = self.config.output_every;
        let channels = &self.system.channels;
        let mut t_col = Vec::with_capacity(n_out);
        let mut columns: Vec<Vec<f64>> = (0..channels.len())
            .map(|_| Vec::with_capacity(n_out))
            .collect();
        self.run_observed((n_out - 1) * every, cancel, |s| {
            if s.step % every != 0 {
                return;
            }
            t_col.push(s.t);
            for (col, ch) in columns.iter_mut().zip(channels) {
                col.push(self.channel_value(ch.quantity, s));
            }
        })?;
        Ok(Trajectory { t: t_col, columns })
    }
}

/// One sample to simulate.
#[derive(Debug, Clone)]
pub struct SampleInput {
    /// Sample id.
    pub id: u64,
    /// The design: the values of the system's sampled parameters.
    pub params: mbd_system::Sampled,
    /// Points of each generated profile (`None`: level).
    pub profiles: Vec<Option<Profile>>,
}

/// Builds every sample's engine in parallel, checking each before anything runs; the error of
/// the first bad sample (in input order) is returned with its id.
pub fn prepare(
    system: &Arc<System>,
    config: &RunConfig,
    inputs: Vec<SampleInput>,
) -> std::result::Result<Vec<(u64, Engine)>, (u64, Error)> {
    use rayon::prelude::*;
    config
        .validate()
        .map_err(|e| (inputs.first().map_or(0, |s| s.id), e))?;
    inputs
        .into_par_iter()
        .map(|s| {
            let model = system
                .instantiate(&s.params)
                .map_err(|e| (s.id, Error::Field(e)))?;
            Engine::new(system.clone(), model, config, s.profiles)
                .map(|e| (s.id, e))
                .map_err(|e| (s.id, e))
        })
        .collect()
}

/// Runs prepared samples in parallel (rayon), `chunk` at a time, handing each outcome to
/// `sink` in input order (the output never depends on the thread count); `done` is called once
/// per finished sample from the worker threads. Memory holds at most `chunk` trajectories.
pub fn run_all<E>(
    engines: &[(u64, Engine)],
    chunk: usize,
    done: &(dyn Fn() + Sync),
    mut sink: impl FnMut(u64, std::result::Result<Trajectory, Failure>) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    use rayon::prelude::*;
    for block in engines.chunks(chunk.max(1)) {
        let outcomes: Vec<_> = block
            .par_iter()
            .map(|(id, engine)| {
                let out = engine.run();
                done();
                (*id, out)
            })
            .collect();
        for (id, out) in outcomes {
            sink(id, out)?;
        }
    }
    Ok(())
}
