//! Derivative-free minimisation on a box under upper limits.
//!
//! The search runs in the unit cube `[0, 1]^d` of the box (the caller maps it to parameter
//! values). A candidate is scored by an exact L1 penalty,
//! `F(u) = f(u) + PENALTY (sum_j max(0, c_j(u)) + |u - clamp(u)|_1)`, where `f` is the
//! (normalised) objective and `c_j <= 0` the (normalised) constraints: for a weight above the
//! constraints' Lagrange multipliers the constrained minimiser minimises `F`, and any feasible
//! point beats any point that violates a constraint by more than `|f|` range / `PENALTY`.
//! Points outside the cube are evaluated at their projection.
//!
//! Nelder-Mead (`argmin`'s, deterministic, no gradients: the objective is a statistic over
//! excitations of a surrogate or of the solver) runs from each starting point, then once more
//! from its best point with a smaller simplex (a restart that escapes the collapsed simplices
//! Nelder-Mead is known for). Starts are independent and run side by side; each keeps its own
//! history, so the result does not depend on the thread count.

use crate::{out_of_range, Error, Result};
use argmin::core::{CostFunction, Executor, State};
use argmin::solver::neldermead::NelderMead;
use rayon::prelude::*;
use std::sync::Mutex;

/// Weight of a unit of normalised constraint violation against a unit of the normalised
/// objective.
pub const PENALTY: f64 = 1.0e3;

/// A violation at most this large counts as feasible (normalised units).
pub const FEASIBLE_TOLERANCE: f64 = 1.0e-9;

/// The edge of the first simplex of a start, in unit-cube units.
pub const FIRST_STEP: f64 = 0.25;

/// The edge of the restart's simplex.
pub const RESTART_STEP: f64 = 0.05;

/// One evaluation of the problem at a point.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// The normalised objective (to minimise).
    pub objective: f64,
    /// The normalised constraints, each `<= 0` when met.
    pub constraints: Vec<f64>,
}

impl Evaluation {
    /// `sum_j max(0, c_j)` (non-finite constraints count as infinite).
    pub fn violation(&self) -> f64 {
        self.constraints
            .iter()
            .map(|&c| {
                if c.is_finite() {
                    c.max(0.0)
                } else {
                    f64::INFINITY
                }
            })
            .sum()
    }

    /// Whether every constraint is met.
    pub fn feasible(&self) -> bool {
        self.violation() <= FEASIBLE_TOLERANCE
    }
}

/// One recorded evaluation of the search.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// The start it belongs to.
    pub start: usize,
    /// Its number within the start.
    pub evaluation: usize,
    /// The point (unit cube, projected).
    pub u: Vec<f64>,
    /// What the problem returned.
    pub value: Evaluation,
    /// The penalised score.
    pub penalised: f64,
}

/// Settings of a search.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Nelder-Mead iterations per run (a start runs twice: first and restart).
    pub max_iterations: u64,
    /// Starting points in the unit cube.
    pub starts: Vec<Vec<f64>>,
}

/// The outcome: every start's best point, the overall best, the whole history.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The best step of each start (start order).
    pub best_of_start: Vec<Step>,
    /// The best step: the lowest objective among feasible ones, else the least violating.
    pub best: Step,
    /// Whether [`Outcome::best`] meets every constraint.
    pub feasible: bool,
    /// Every evaluation, start by start.
    pub history: Vec<Step>,
}

struct Penalised<'a, F> {
    f: &'a F,
    start: usize,
    log: Mutex<Vec<Step>>,
}

impl<F> CostFunction for Penalised<'_, F>
where
    F: Fn(&[f64]) -> Result<Evaluation> + Sync,
{
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, u: &Vec<f64>) -> std::result::Result<f64, argmin::core::Error> {
        let projected: Vec<f64> = u.iter().map(|x| x.clamp(0.0, 1.0)).collect();
        let outside: f64 = u.iter().zip(&projected).map(|(a, b)| (a - b).abs()).sum();
        let value = (self.f)(&projected).map_err(|e| argmin::core::Error::msg(e.to_string()))?;
        let mut penalised = value.objective + PENALTY * (value.violation() + outside);
        if !penalised.is_finite() {
            penalised = f64::MAX;
        }
        let mut log = self
            .log
            .lock()
            .expect("a start's log is used by one thread");
        let evaluation = log.len();
        log.push(Step {
            start: self.start,
            evaluation,
            u: projected,
            value,
            penalised,
        });
        Ok(penalised)
    }
}

/// The simplex of `d + 1` points around `u0` with edge `step` (stepping inward at the cube's
/// upper faces).
fn simplex(u0: &[f64], step: f64) -> Vec<Vec<f64>> {
    let mut out = vec![u0.to_vec()];
    for i in 0..u0.len() {
        let mut p = u0.to_vec();
        p[i] = if p[i] + step <= 1.0 {
            p[i] + step
        } else {
            p[i] - step
        };
        out.push(p);
    }
    out
}

/// Whether `a` ranks before `b`: feasible before infeasible, then the lower objective
/// (feasible) or the smaller violation (infeasible). A step is the design at its projected
/// point, so the penalty the optimiser saw for stepping outside the cube does not count here.
pub fn better(a: &Step, b: &Step) -> bool {
    match (a.value.feasible(), b.value.feasible()) {
        (true, false) => true,
        (false, true) => false,
        (true, true) => a.value.objective < b.value.objective,
        (false, false) => a.value.violation() < b.value.violation(),
    }
}

fn run_start<F>(f: &F, start: usize, u0: &[f64], iters: u64) -> Result<Vec<Step>>
where
    F: Fn(&[f64]) -> Result<Evaluation> + Sync,
{
    let problem = Penalised {
        f,
        start,
        log: Mutex::new(Vec::new()),
    };
    let mut from = u0.to_vec();
    for step in [FIRST_STEP, RESTART_STEP] {
        let solver = NelderMead::new(simplex(&from, step))
            .with_sd_tolerance(1e-12)
            .map_err(|e| Error::Optimiser(e.to_string()))?;
        let result = Executor::new(&problem, solver)
            .configure(|s| s.max_iters(iters))
            .run()
            .map_err(|e| Error::Optimiser(e.to_string()))?;
        if let Some(best) = result.state().get_best_param() {
            from = best.iter().map(|x| x.clamp(0.0, 1.0)).collect();
        }
    }
    Ok(problem.log.into_inner().expect("no thread panicked"))
}

impl<F> CostFunction for &Penalised<'_, F>
where
    F: Fn(&[f64]) -> Result<Evaluation> + Sync,
{
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, u: &Vec<f64>) -> std::result::Result<f64, argmin::core::Error> {
        (*self).cost(u)
    }
}

/// Minimises `f` over the unit cube from every start of `settings`.
pub fn minimise<F>(f: &F, settings: &Settings) -> Result<Outcome>
where
    F: Fn(&[f64]) -> Result<Evaluation> + Sync,
{
    if settings.starts.is_empty() {
        return Err(out_of_range("starts", 0, "at least one starting point"));
    }
    if settings.max_iterations == 0 {
        return Err(out_of_range("max_iterations", 0, ">= 1"));
    }
    let histories: Vec<Vec<Step>> = settings
        .starts
        .par_iter()
        .enumerate()
        .map(|(s, u0)| run_start(f, s, u0, settings.max_iterations))
        .collect::<Result<_>>()?;
    let best_of_start: Vec<Step> = histories
        .iter()
        .map(|h| {
            h.iter()
                .fold(None::<&Step>, |acc, s| match acc {
                    Some(a) if !better(s, a) => Some(a),
                    _ => Some(s),
                })
                .cloned()
                .ok_or_else(|| Error::Optimiser("a start made no evaluation".into()))
        })
        .collect::<Result<_>>()?;
    let best = best_of_start
        .iter()
        .fold(&best_of_start[0], |a, s| if better(s, a) { s } else { a })
        .clone();
    Ok(Outcome {
        feasible: best.value.feasible(),
        best,
        best_of_start,
        history: histories.into_iter().flatten().collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Minimise (x - 2)^2 + (y - 1)^2 subject to x^2 - y <= 0 and x + y <= 2 on [-3, 3]^2:
    /// the optimum is (1, 1) with value 1 (both constraints active).
    #[test]
    fn finds_a_known_constrained_optimum() {
        let to_x = |u: &[f64]| (-3.0 + 6.0 * u[0], -3.0 + 6.0 * u[1]);
        let f = |u: &[f64]| {
            let (x, y) = to_x(u);
            Ok(Evaluation {
                objective: (x - 2.0).powi(2) + (y - 1.0).powi(2),
                constraints: vec![x * x - y, x + y - 2.0],
            })
        };
        let settings = Settings {
            max_iterations: 300,
            starts: vec![vec![0.5, 0.5], vec![0.1, 0.9], vec![0.9, 0.1]],
        };
        let out = minimise(&f, &settings).unwrap();
        assert!(out.feasible);
        let (x, y) = to_x(&out.best.u);
        assert!(
            (x - 1.0).abs() < 1e-3 && (y - 1.0).abs() < 1e-3,
            "({x}, {y})"
        );
        assert!((out.best.value.objective - 1.0).abs() < 2e-3);
        assert_eq!(out.best_of_start.len(), 3);
        assert!(out.history.len() > 50);
        // The same search on one thread: the same result.
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert_eq!(one.install(|| minimise(&f, &settings)).unwrap(), out);
    }

    /// An infeasible problem says so and returns the least violating point: x >= 5 on
    /// [-3, 3] is closest at x = 3.
    #[test]
    fn an_infeasible_problem_returns_the_least_violating_point() {
        let f = |u: &[f64]| {
            let x = -3.0 + 6.0 * u[0];
            Ok(Evaluation {
                objective: x * x,
                constraints: vec![5.0 - x],
            })
        };
        let out = minimise(
            &f,
            &Settings {
                max_iterations: 100,
                starts: vec![vec![0.5]],
            },
        )
        .unwrap();
        assert!(!out.feasible);
        assert!((out.best.u[0] - 1.0).abs() < 1e-6, "{:?}", out.best.u);
        assert!((out.best.value.violation() - 2.0).abs() < 1e-5);
    }

    /// A step outside the cube is the design at its projection: ranked by that design's
    /// objective, not by the penalty the optimiser saw for stepping outside.
    #[test]
    fn a_projected_step_ranks_by_its_designs_objective() {
        let step = |objective: f64, penalised: f64| Step {
            start: 0,
            evaluation: 0,
            u: vec![0.0],
            value: Evaluation {
                objective,
                constraints: vec![-1.0],
            },
            penalised,
        };
        let projected = step(0.1, 0.1 + PENALTY * 0.15);
        let inside = step(0.2, 0.2);
        assert!(better(&projected, &inside) && !better(&inside, &projected));
        let infeasible = Step {
            value: Evaluation {
                objective: -5.0,
                constraints: vec![0.5],
            },
            ..inside.clone()
        };
        assert!(better(&inside, &infeasible) && !better(&infeasible, &inside));
    }

    #[test]
    fn bad_settings_are_refused() {
        let f = |_: &[f64]| {
            Ok(Evaluation {
                objective: 0.0,
                constraints: vec![],
            })
        };
        let s = Settings {
            max_iterations: 10,
            starts: vec![],
        };
        assert!(minimise(&f, &s).is_err());
    }
}
