//! The `optimise` study: the design in a box that minimises (or maximises) a weighted sum of
//! indices while every limited index stays under its limit, robustly over excitations.
//!
//! - **Box**: each sampled parameter's `uniform: [lo, hi]` (a sub-box), its training range
//!   when not declared, or a `fixed` value held. The search runs in the unit cube of the
//!   varying parameters (`pino_studies::optimise`: Nelder-Mead from `argmin`, restarted, an
//!   exact L1 penalty).
//! - **Robustness**: every candidate runs under the same excitations `0..M` (common random
//!   numbers: two candidates differ by their parameters, not by their tracks); the objective
//!   and each constraint are a statistic over the M answers (mean or a quantile).
//! - **Constraints** (upper limits, the description's where not declared) are judged on the
//!   upper end of the calibrated interval where the model has a calibration, so a design the
//!   surrogate calls feasible is feasible within the surrogate's error at the stated coverage.
//! - **Normalisation**: the optimiser sees the objective divided by its magnitude at the box's
//!   centre and each constraint as `(statistic - limit) / |limit|`.
//! - **Starts**: the box's centre, then points drawn from `(seed, StudyDesigns, start)`.
//! - **The solver beside it**: the optimum, the best points of `runners_up` other starts and
//!   `solver_check` candidates spread over the history run through the solver under the same
//!   M excitations and are judged the same way (on the solver's point values).
//!
//! When no candidate meets every limit the study says so and reports the least-violating one.

use super::evaluate::{spread, Evaluator, Solved};
use super::spec::{Optimise, Robust, Study};
use crate::Result;
use mbd_dataset::{Purpose, SampleStream};
use pino_learn::Error as LearnError;
use pino_predict::DesignAnswer;
use pino_studies::optimise::{better, minimise, Evaluation, Settings, Step};
use pino_studies::Distribution;
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Instant;

/// Why a candidate was run through the solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The best candidate of the search.
    Optimum,
    /// The best candidate of another start.
    RunnerUp,
    /// One of the candidates spread over the history.
    Spread,
}

impl Role {
    /// Its name in tables.
    pub fn label(self) -> &'static str {
        match self {
            Self::Optimum => "optimum",
            Self::RunnerUp => "runner_up",
            Self::Spread => "spread",
        }
    }
}

/// A candidate judged by one source: the objective's statistic, each constraint's, and
/// whether every limit is met.
#[derive(Debug, Clone, PartialEq)]
pub struct Judged {
    /// The statistic of the objective over the excitations (the objective's units).
    pub objective: f64,
    /// The statistic of each constrained index (constraint order).
    pub constraints: Vec<f64>,
    /// Whether every constraint is at most its limit.
    pub feasible: bool,
}

/// One evaluated candidate of the search.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The start it belongs to.
    pub start: usize,
    /// Its number within the start.
    pub evaluation: usize,
    /// The design (model parameter order).
    pub design: Vec<f64>,
    /// The surrogate's judgement.
    pub judged: Judged,
    /// The score the optimiser minimised (normalised objective plus the penalty).
    pub penalised: f64,
}

/// A candidate the solver also ran.
#[derive(Debug, Clone, PartialEq)]
pub struct Checked {
    /// Its position in the history.
    pub candidate: usize,
    /// Why it was checked.
    pub role: Role,
    /// The solver's answers, one per excitation.
    pub solved: Vec<Solved>,
    /// The solver's judgement.
    pub solver: Judged,
}

/// An optimisation's results.
#[derive(Debug, Clone)]
pub struct Optimisation {
    /// The box of every parameter (model order; a fixed one has `lo == hi`).
    pub bounds: Vec<[f64; 2]>,
    /// The constrained indices: index column and limit.
    pub constraints: Vec<(usize, f64)>,
    /// Every evaluation of the search, start by start.
    pub history: Vec<Candidate>,
    /// The surrogate's answers of each candidate, one per excitation.
    pub answers: Vec<Vec<DesignAnswer>>,
    /// The best candidate (position in the history).
    pub best: usize,
    /// Whether it meets every limit.
    pub feasible: bool,
    /// The candidates the solver checked (the optimum first).
    pub checked: Vec<Checked>,
    /// The excitation ids every candidate ran under.
    pub excitation: Vec<u64>,
    /// Distinct designs the surrogate evaluated (each under every excitation).
    pub distinct: usize,
    /// Wall time of the search (s).
    pub surrogate_s: f64,
    /// Wall time of the solver's checks (s).
    pub solver_s: f64,
}

/// The objective of one answer: the weighted sum of its index values.
fn objective_of(terms: &[(usize, f64)], values: &[f64]) -> f64 {
    terms.iter().map(|&(j, w)| w * values[j]).sum()
}

/// Judges one candidate from its per-excitation index values and, for the constraints, the
/// per-excitation values they are judged on.
fn judge(
    o: &Optimise,
    terms: &[(usize, f64)],
    constraints: &[(usize, f64)],
    values: &[&[f64]],
    judged_on: &[&[f64]],
) -> Judged {
    let objective = o.statistic.of(&values
        .iter()
        .map(|v| objective_of(terms, v))
        .collect::<Vec<_>>());
    let stats: Vec<f64> = constraints
        .iter()
        .map(|&(j, _)| {
            o.statistic
                .of(&judged_on.iter().map(|v| v[j]).collect::<Vec<_>>())
        })
        .collect();
    let feasible = stats
        .iter()
        .zip(constraints)
        .all(|(s, &(_, limit))| *s <= limit);
    Judged {
        objective,
        constraints: stats,
        feasible,
    }
}

/// The surrogate's values a constraint is judged on: the calibrated interval's upper end
/// where there is one, else the point value.
fn upper_ends(a: &DesignAnswer) -> Vec<f64> {
    match &a.calibrated {
        Some(c) => c.indices.iter().map(|i| i.hi).collect(),
        None => a.indices.values.clone(),
    }
}

/// The normalised problem the optimiser sees.
fn normalised(j: &Judged, maximise: bool, scale: f64, constraints: &[(usize, f64)]) -> Evaluation {
    let sign = if maximise { -1.0 } else { 1.0 };
    Evaluation {
        objective: sign * j.objective / scale,
        constraints: j
            .constraints
            .iter()
            .zip(constraints)
            .map(|(s, &(_, limit))| (s - limit) / limit.abs().max(f64::MIN_POSITIVE))
            .collect(),
    }
}

/// The starts of the search in the unit cube: its centre, then points drawn from the study's
/// stream (purpose study designs, start number).
fn search_starts(n: usize, centre: &[f64], seed: u64) -> Vec<Vec<f64>> {
    (0..n as u64)
        .map(|s| {
            if s == 0 {
                centre.to_vec()
            } else {
                let mut r = SampleStream::new(seed, Purpose::StudyDesigns, s);
                centre.iter().map(|_| r.uniform()).collect()
            }
        })
        .collect()
}

/// The search's steps as candidates, each judged on its recorded answers (`cache`, by design).
fn replay(
    outcome: &pino_studies::optimise::Outcome,
    cache: &HashMap<Vec<u64>, Vec<DesignAnswer>>,
    to_design: &dyn Fn(&[f64]) -> Vec<f64>,
    surrogate_judged: &dyn Fn(&[DesignAnswer]) -> Judged,
    study: &Study,
) -> Result<(Vec<Candidate>, Vec<Vec<DesignAnswer>>)> {
    let mut history = Vec::with_capacity(outcome.history.len());
    let mut answers = Vec::with_capacity(outcome.history.len());
    for step in &outcome.history {
        let design = to_design(&step.u);
        let key = design_key(&design);
        let a = cache.get(&key).cloned().ok_or_else(|| LearnError::Format {
            path: format!("study.{}", study.name).into(),
            message: "a candidate of the search has no recorded answers".into(),
        })?;
        history.push(Candidate {
            start: step.start,
            evaluation: step.evaluation,
            design,
            judged: surrogate_judged(&a),
            penalised: step.penalised,
        });
        answers.push(a);
    }
    Ok((history, answers))
}

/// The candidates of `roles` through the solver under every excitation, each judged on the
/// solver's values (against the study's objective terms and constraints).
fn check_by_solver(
    ev: &Evaluator<'_>,
    o: &Optimise,
    terms: &[(usize, f64)],
    constraints: &[(usize, f64)],
    roles: &[(usize, Role)],
    history: &[Candidate],
    excitation: &[u64],
) -> Result<Vec<Checked>> {
    let m = excitation.len();
    let designs: Vec<Vec<f64>> = roles
        .iter()
        .flat_map(|&(c, _)| std::iter::repeat_n(history[c].design.clone(), m))
        .collect();
    let ids: Vec<u64> = roles.iter().flat_map(|_| excitation.to_vec()).collect();
    let solved = ev.solver(&designs, &ids)?;
    Ok(roles
        .iter()
        .zip(solved.chunks(m))
        .map(|(&(candidate, role), s)| {
            let values: Vec<&[f64]> = s.iter().map(|x| x.indices.as_slice()).collect();
            Checked {
                candidate,
                role,
                solver: judge(o, terms, constraints, &values, &values),
                solved: s.to_vec(),
            }
        })
        .collect())
}

/// The key of a design in the cache of answers: its values' bit patterns (a design evaluated
/// twice is the same design only when every value is the same number).
fn design_key(design: &[f64]) -> Vec<u64> {
    design.iter().map(|x| x.to_bits()).collect()
}

/// The objective's terms and the upper limits as (index column, weight or limit): the
/// study's limits over the description's.
#[allow(clippy::type_complexity)]
fn objective_and_limits(
    ev: &Evaluator<'_>,
    study: &Study,
    o: &Optimise,
) -> Result<(Vec<(usize, f64)>, Vec<(usize, f64)>)> {
    let columns = ev.predictor.index_inputs().columns();
    let column = |name: &str| {
        columns
            .iter()
            .position(|c| c.name == name)
            .ok_or_else(|| LearnError::OutOfRange {
                field: format!("study.{}", study.name),
                value: name.to_owned(),
                allowed: "an index of the model".into(),
            })
    };
    let terms: Vec<(usize, f64)> = o
        .objective
        .iter()
        .map(|(i, w)| Ok((column(i)?, *w)))
        .collect::<Result<_>>()?;
    let described = ev
        .predictor
        .index_inputs()
        .limits(ev.predictor.system(), &ev.cfg);
    let constraints = columns
        .iter()
        .zip(described)
        .enumerate()
        .filter_map(|(j, (c, d))| o.limits.get(&c.name).copied().or(d).map(|l| (j, l)))
        .collect();
    Ok((terms, constraints))
}

/// The box searched: every sampled parameter's bounds (equal for a fixed one) and the
/// positions of those that vary, the unit cube's axes.
struct SearchBox {
    bounds: Vec<[f64; 2]>,
    varying: Vec<usize>,
}

impl SearchBox {
    fn of(study: &Study, parameters: &[(String, [f64; 2])]) -> Self {
        let bounds: Vec<[f64; 2]> = study
            .distributions(parameters)
            .iter()
            .map(|d| match *d {
                Distribution::Fixed(v) => [v, v],
                other => {
                    let (lo, hi) = other.support();
                    [lo, hi]
                }
            })
            .collect();
        let varying = (0..bounds.len())
            .filter(|&k| bounds[k][0] < bounds[k][1])
            .collect();
        Self { bounds, varying }
    }

    /// The design at the point `u` of the unit cube.
    fn design(&self, u: &[f64]) -> Vec<f64> {
        let mut d: Vec<f64> = self.bounds.iter().map(|b| b[0]).collect();
        for (&k, &x) in self.varying.iter().zip(u) {
            d[k] = self.bounds[k][0] + x * (self.bounds[k][1] - self.bounds[k][0]);
        }
        d
    }
}

/// The candidates the solver runs, as (history position, role): the optimum first, then the
/// best of up to `runners_up` other starts (distinct designs, best first), then `spread`
/// candidates over the history.
fn solver_candidates(
    outcome: &pino_studies::optimise::Outcome,
    history: &[Candidate],
    runners_up: usize,
    spread_count: usize,
) -> Vec<(usize, Role)> {
    let position = |s: &Step| {
        outcome
            .history
            .iter()
            .position(|h| h.start == s.start && h.evaluation == s.evaluation)
            .expect("a best step is one of the history's")
    };
    let mut roles: Vec<(usize, Role)> = vec![(position(&outcome.best), Role::Optimum)];
    let mut others: Vec<&Step> = outcome
        .best_of_start
        .iter()
        .filter(|s| s.start != outcome.best.start)
        .collect();
    others.sort_by(|a, b| {
        if better(a, b) {
            std::cmp::Ordering::Less
        } else if better(b, a) {
            std::cmp::Ordering::Greater
        } else {
            a.start.cmp(&b.start)
        }
    });
    for s in others {
        if roles.iter().filter(|r| r.1 == Role::RunnerUp).count() == runners_up {
            break;
        }
        let k = position(s);
        if roles
            .iter()
            .all(|&(c, _)| history[c].design != history[k].design)
        {
            roles.push((k, Role::RunnerUp));
        }
    }
    for k in spread(history.len(), spread_count) {
        if roles.iter().all(|&(c, _)| c != k) {
            roles.push((k, Role::Spread));
        }
    }
    roles
}

/// Runs `study` (an optimisation `o`); `parameters` are the model's sampled parameters with
/// their training ranges.
pub fn run(
    ev: &Evaluator<'_>,
    study: &Study,
    o: &Optimise,
    parameters: &[(String, [f64; 2])],
) -> Result<Optimisation> {
    let (terms, constraints) = objective_and_limits(ev, study, o)?;
    let search_box = SearchBox::of(study, parameters);
    let varying = &search_box.varying;
    let to_design = |u: &[f64]| search_box.design(u);
    let excitation: Vec<u64> = (0..o.excitations as u64).collect();
    // Each distinct design's answers, kept for the tables (Nelder-Mead revisits points).
    let cache: Mutex<HashMap<Vec<u64>, Vec<DesignAnswer>>> = Mutex::new(HashMap::new());
    let answers_of = |design: &[f64]| -> Result<Vec<DesignAnswer>> {
        let key = design_key(design);
        if let Some(a) = cache.lock().expect("no thread panicked").get(&key) {
            return Ok(a.clone());
        }
        let a = ev.surrogate(&vec![design.to_vec(); excitation.len()], &excitation)?;
        cache
            .lock()
            .expect("no thread panicked")
            .insert(key, a.clone());
        Ok(a)
    };
    let surrogate_judged = |answers: &[DesignAnswer]| -> Judged {
        let values: Vec<&[f64]> = answers
            .iter()
            .map(|a| a.indices.values.as_slice())
            .collect();
        let upper: Vec<Vec<f64>> = answers.iter().map(upper_ends).collect();
        let upper: Vec<&[f64]> = upper.iter().map(Vec::as_slice).collect();
        judge(o, &terms, &constraints, &values, &upper)
    };
    let t0 = Instant::now();
    let centre = vec![0.5; varying.len()];
    let at_centre = surrogate_judged(&answers_of(&to_design(&centre))?);
    let scale = if at_centre.objective.is_finite() && at_centre.objective != 0.0 {
        at_centre.objective.abs()
    } else {
        1.0
    };
    let starts = search_starts(o.starts, &centre, ev.params.seed);
    let problem = |u: &[f64]| -> pino_studies::Result<Evaluation> {
        let answers =
            answers_of(&to_design(u)).map_err(|e| pino_studies::Error::Optimiser(e.to_string()))?;
        Ok(normalised(
            &surrogate_judged(&answers),
            o.maximise,
            scale,
            &constraints,
        ))
    };
    let outcome = minimise(
        &problem,
        &Settings {
            max_iterations: o.iterations,
            starts,
        },
    )
    .map_err(|e| LearnError::OutOfRange {
        field: format!("study.{}", study.name),
        value: "the search".into(),
        allowed: e.to_string(),
    })?;
    let surrogate_s = t0.elapsed().as_secs_f64();
    let cache = cache.into_inner().expect("no thread panicked");
    let distinct = cache.len();
    let (history, answers) = replay(&outcome, &cache, &to_design, &surrogate_judged, study)?;
    let roles = solver_candidates(&outcome, &history, o.runners_up, study.solver_check);
    let best = roles[0].0;
    let t1 = Instant::now();
    let checked = check_by_solver(ev, o, &terms, &constraints, &roles, &history, &excitation)?;
    let solver_s = t1.elapsed().as_secs_f64();
    Ok(Optimisation {
        bounds: search_box.bounds,
        constraints,
        feasible: outcome.feasible,
        history,
        answers,
        best,
        checked,
        excitation,
        distinct,
        surrogate_s,
        solver_s,
    })
}

/// The statistic's name and the sense, for reports (`minimise the mean of ...`).
pub fn describe(o: &Optimise) -> String {
    let terms: Vec<String> = o
        .objective
        .iter()
        .map(|(i, w)| {
            if *w == 1.0 {
                i.clone()
            } else {
                format!("{w} {i}")
            }
        })
        .collect();
    format!(
        "{} the {} over {} excitations of {}",
        if o.maximise { "maximise" } else { "minimise" },
        match o.statistic {
            Robust::Mean => "mean".to_owned(),
            Robust::Quantile(q) => format!("{q}-quantile"),
        },
        o.excitations,
        terms.join(" + ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(statistic: Robust) -> Optimise {
        Optimise {
            objective: vec![("a".into(), 2.0), ("b".into(), -1.0)],
            maximise: false,
            limits: Default::default(),
            excitations: 3,
            statistic,
            starts: 2,
            iterations: 10,
            runners_up: 1,
        }
    }

    #[test]
    fn a_candidate_is_judged_by_its_statistic_over_the_excitations() {
        // Indices (a, b, c); objective 2a - b; c limited to 1.0.
        let rows = [[1.0, 0.0, 0.5], [2.0, 1.0, 0.9], [3.0, 1.0, 1.6]];
        let values: Vec<&[f64]> = rows.iter().map(|r| r.as_slice()).collect();
        let terms = [(0, 2.0), (1, -1.0)];
        let constraints = [(2, 1.0)];
        let mean = judge(&spec(Robust::Mean), &terms, &constraints, &values, &values);
        // Objectives 2, 3, 5: mean 10/3; c's mean 1.0 meets the limit exactly.
        assert!((mean.objective - 10.0 / 3.0).abs() < 1e-12);
        assert!((mean.constraints[0] - 1.0).abs() < 1e-12);
        assert!(mean.feasible);
        // The 0.75-quantile: h = 1.5, between the 2nd and 3rd sorted values.
        let q = judge(
            &spec(Robust::Quantile(0.75)),
            &terms,
            &constraints,
            &values,
            &values,
        );
        assert!((q.objective - 4.0).abs() < 1e-12);
        assert!((q.constraints[0] - 1.25).abs() < 1e-12);
        assert!(!q.feasible);
        // A constraint judged on upper ends above the points turns a feasible design down.
        let upper = [[0.0, 0.0, 1.2]; 3];
        let upper: Vec<&[f64]> = upper.iter().map(|r| r.as_slice()).collect();
        assert!(!judge(&spec(Robust::Mean), &terms, &constraints, &values, &upper).feasible);
    }

    #[test]
    fn the_optimiser_sees_normalised_values_with_the_sense() {
        let j = Judged {
            objective: 4.0,
            constraints: vec![180.0, -0.5],
            feasible: false,
        };
        let e = normalised(&j, true, 2.0, &[(0, 170.0), (1, -1.0)]);
        assert_eq!(e.objective, -2.0);
        assert!((e.constraints[0] - 10.0 / 170.0).abs() < 1e-15);
        assert_eq!(e.constraints[1], 0.5);
        assert!(!e.feasible());
    }

    #[test]
    fn a_statistic_with_a_failed_answer_is_not_finite() {
        assert!(Robust::Mean.of(&[1.0, f64::NAN]).is_nan());
        assert_eq!(Robust::Quantile(0.5).of(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(Robust::Quantile(0.9).label(), "q90");
    }
}
