//! The `sensitivity` study: first-order and total Sobol indices of every index over every
//! varying parameter and over the excitation as one grouped factor, by Saltelli's scheme
//! ([`pino_studies::sobol`]).
//!
//! The design: `N` rows of two unit-cube points `A_r`, `B_r` from one Owen-scrambled Sobol'
//! sequence (one coordinate per varying parameter, mapped by its distribution's inverse CDF),
//! and two excitations per row: `A_r` runs under excitation `2r`, `B_r` under `2r + 1` (each
//! the profile the `irregularity` stage would generate for that sample id at the study's
//! seed: every random phase of the track or road, drawn anew, is the grouped factor). Row `r`
//! evaluates, in SALib's order, `A_r`, `A_r` with each factor in turn taken from `B_r` (the
//! excitation last), and `B_r`: `N (g + 2)` evaluations for `g` factors.
//!
//! The solver runs the design's first `solver_check` rows (a balanced prefix of the
//! sequence); the surrogate's indices on the same rows (`surrogate_reduced`) stand beside the
//! solver's, so the two differ only by the model's error, and the full-`N` surrogate's beside
//! both. Rankings compare the three largest total indices of each index.

use super::evaluate::{Evaluator, Solved};
use super::source;
use super::spec::{Study, EXCITATION_FACTOR};
use crate::Result;
use pino_learn::Error as LearnError;
use pino_predict::DesignAnswer;
use pino_studies::sobol::{self, Block, FactorIndices, Indices, SaltelliDesign};
use std::time::Instant;

/// How many of the most influential factors the rankings compare.
pub const RANKED: usize = 3;

/// One evaluation of the design.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Its row `r` of the design.
    pub row: usize,
    /// Its matrix (`A`, `A_B^(i)`, `B`).
    pub block: Block,
    /// Its excitation id (`2r` with `A`'s excitation, `2r + 1` with `B`'s).
    pub excitation: u64,
    /// The design's parameter values (model parameter order).
    pub design: Vec<f64>,
}

/// One source's indices of one index.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexSobol {
    /// The index.
    pub index: String,
    /// `surrogate` (all rows), `surrogate_reduced` (the solver's rows) or `solver`.
    pub source: &'static str,
    /// Rows of the design the estimate used.
    pub rows: usize,
    /// Each factor's indices with their bootstrap intervals (factor order); empty when an
    /// output is missing (a solver failure).
    pub factors: Vec<FactorIndices>,
}

impl IndexSobol {
    /// The positions of the [`RANKED`] largest total indices, largest first.
    pub fn top(&self) -> Vec<usize> {
        let mut order = self.order();
        order.truncate(RANKED);
        order
    }

    /// Every factor, the largest total index first (a stable sort: ties keep factor order).
    pub fn order(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.factors.len()).collect();
        order.sort_by(|&a, &b| self.factors[b].total.total_cmp(&self.factors[a].total));
        order
    }
}

/// A sensitivity study's results.
#[derive(Debug, Clone)]
pub struct Sensitivity {
    /// Rows `N` of the design.
    pub n: usize,
    /// The factors' names: the varying parameters (model order), then the excitation.
    pub factors: Vec<String>,
    /// Every evaluation, in SALib's order (`N (g + 2)`).
    pub evaluations: Vec<Evaluation>,
    /// The surrogate's answers, one per evaluation.
    pub answers: Vec<DesignAnswer>,
    /// Rows the solver ran (the design's first).
    pub solver_rows: usize,
    /// The solver's answers of the first `solver_rows (g + 2)` evaluations.
    pub solved: Vec<Solved>,
    /// The indices, index by index: `surrogate`, then (with a solver check)
    /// `surrogate_reduced` and `solver`.
    pub sobol: Vec<IndexSobol>,
    /// The surrogate's estimates on the first `2^m` rows, index by index: `(index, rows,
    /// indices)`.
    pub convergence: Vec<(String, usize, Indices)>,
    /// Wall time of the surrogate's evaluations (s).
    pub surrogate_s: f64,
    /// Wall time of the solver's (s).
    pub solver_s: f64,
}

impl Sensitivity {
    /// Evaluations per row (`g + 2`).
    pub fn per_row(&self) -> usize {
        self.factors.len() + 2
    }

    /// The indices of `index` from `source`, when estimated.
    pub fn of(&self, index: &str, source: &str) -> Option<&IndexSobol> {
        self.sobol
            .iter()
            .find(|s| s.index == index && s.source == source)
    }
}

fn estimator_error(study: &Study, e: pino_studies::Error) -> LearnError {
    LearnError::Format {
        path: format!("study.{}", study.name).into(),
        message: e.to_string(),
    }
}

/// The design of `study` with `n` rows: the factor names and every evaluation.
pub fn design(
    study: &Study,
    n: usize,
    seed: u64,
    parameters: &[(String, [f64; 2])],
) -> Result<(Vec<String>, Vec<Evaluation>)> {
    let dists = study.distributions(parameters);
    let varying: Vec<usize> = (0..dists.len()).filter(|&k| dists[k].varies()).collect();
    let mut factors: Vec<String> = varying.iter().map(|&k| parameters[k].0.clone()).collect();
    factors.push(EXCITATION_FACTOR.to_owned());
    let g = factors.len();
    let excitation = g - 1;
    // The scrambling seed: the study seed's two halves folded into the sequence's 32 bits.
    let scramble = (seed ^ (seed >> 32)) as u32;
    let sd =
        SaltelliDesign::new(n, varying.len(), scramble).map_err(|e| estimator_error(study, e))?;
    let map = |u: &[f64]| -> Vec<f64> {
        let mut coordinate = u.iter();
        dists
            .iter()
            .map(|d| {
                if d.varies() {
                    d.at(*coordinate
                        .next()
                        .expect("one coordinate per varying parameter"))
                } else {
                    d.at(0.5)
                }
            })
            .collect()
    };
    let mut evaluations = Vec::with_capacity(n * (g + 2));
    for row in 0..n {
        let (a, b) = (sd.a(row), sd.b(row));
        let (from_a, from_b) = (2 * row as u64, 2 * row as u64 + 1);
        for position in 0..g + 2 {
            let block = Block::at(position, g);
            let (u, excitation_id) = match block {
                Block::A => (a.clone(), from_a),
                Block::B => (b.clone(), from_b),
                Block::AB(i) if i == excitation => (a.clone(), from_b),
                Block::AB(i) => (sobol::swap(&a, &b, &[i]), from_a),
            };
            evaluations.push(Evaluation {
                row,
                block,
                excitation: excitation_id,
                design: map(&u),
            });
        }
    }
    Ok((factors, evaluations))
}

/// Runs `study` with `n` rows; `parameters` are the model's sampled parameters with their
/// training ranges.
pub fn run(
    ev: &Evaluator<'_>,
    study: &Study,
    n: usize,
    parameters: &[(String, [f64; 2])],
) -> Result<Sensitivity> {
    let p = ev.params;
    let (factors, evaluations) = design(study, n, p.seed, parameters)?;
    let g = factors.len();
    let designs: Vec<Vec<f64>> = evaluations.iter().map(|e| e.design.clone()).collect();
    let excitation: Vec<u64> = evaluations.iter().map(|e| e.excitation).collect();
    let t0 = Instant::now();
    let answers = ev.surrogate(&designs, &excitation)?;
    let surrogate_s = t0.elapsed().as_secs_f64();
    let solver_rows = study.solver_check.min(n);
    let checked = solver_rows * (g + 2);
    let t1 = Instant::now();
    let solved = ev.solver(&designs[..checked], &excitation[..checked])?;
    let solver_s = t1.elapsed().as_secs_f64();

    let columns = ev.predictor.index_inputs().columns();
    let mut sobol_rows = Vec::new();
    let mut convergence = Vec::new();
    for (j, c) in columns.iter().enumerate() {
        let surrogate: Vec<f64> = answers.iter().map(|a| a.indices.values[j]).collect();
        let solver: Vec<f64> = solved.iter().map(|s| s.indices[j]).collect();
        let mut sources: Vec<(&'static str, &[f64], usize)> =
            vec![(source::SURROGATE, &surrogate, n)];
        if solver_rows > 0 {
            sources.push((
                source::SURROGATE_REDUCED,
                &surrogate[..checked],
                solver_rows,
            ));
            sources.push((source::SOLVER, &solver, solver_rows));
        }
        for (k, (source, y, rows)) in sources.into_iter().enumerate() {
            let seed = p.seed ^ ((j as u64) << 32) ^ ((k as u64) << 48);
            let factors = if y.iter().all(|v| v.is_finite()) {
                sobol::estimate_with_intervals(y, rows, g, p.bootstrap, seed, p.confidence)
                    .map_err(|e| estimator_error(study, e))?
            } else {
                Vec::new()
            };
            sobol_rows.push(IndexSobol {
                index: c.name.clone(),
                source,
                rows,
                factors,
            });
        }
        if surrogate.iter().all(|v| v.is_finite()) {
            for (rows, est) in
                sobol::convergence(&surrogate, n, g).map_err(|e| estimator_error(study, e))?
            {
                convergence.push((c.name.clone(), rows, est));
            }
        }
    }
    Ok(Sensitivity {
        n,
        factors,
        evaluations,
        answers,
        solver_rows,
        solved,
        sobol: sobol_rows,
        convergence,
        surrogate_s,
        solver_s,
    })
}

/// How two sources rank the most influential factors of one index.
#[derive(Debug, Clone, PartialEq)]
pub struct Ranking {
    /// The index.
    pub index: String,
    /// The surrogate's top factors (full `N`), largest total index first.
    pub surrogate: Vec<String>,
    /// The surrogate's on the solver's rows.
    pub surrogate_reduced: Vec<String>,
    /// The solver's, on its rows.
    pub solver: Vec<String>,
    /// Whether they are the same in the same order.
    pub same: bool,
    /// Why they differ, when they do.
    pub why: Option<String>,
}

/// Compares the surrogate's ranking of every index with the solver's (none without a solver
/// check). Where they differ, says whether the solver's own intervals separate the factors
/// concerned (a real disagreement of the model) or not (the reduced `N` cannot tell them
/// apart).
pub fn rankings(s: &Sensitivity) -> Vec<Ranking> {
    let mut out = Vec::new();
    for sur in s.sobol.iter().filter(|x| x.source == source::SURROGATE) {
        let Some(sol) = s.of(&sur.index, source::SOLVER) else {
            continue;
        };
        let names = |v: Vec<usize>| -> Vec<String> {
            v.into_iter().map(|k| s.factors[k].clone()).collect()
        };
        let surrogate_reduced = s
            .of(&sur.index, source::SURROGATE_REDUCED)
            .filter(|r| !r.factors.is_empty())
            .map_or_else(Vec::new, |r| names(r.top()));
        if sol.factors.is_empty() || sur.factors.is_empty() {
            out.push(Ranking {
                index: sur.index.clone(),
                surrogate: names(sur.top()),
                surrogate_reduced,
                solver: Vec::new(),
                same: false,
                why: Some("the solver failed on some of its evaluations".into()),
            });
            continue;
        }
        let (a, b) = (sur.top(), sol.top());
        let same = a == b;
        let why = (!same).then(|| {
            // The first place where they differ: the two factors there, by the solver.
            let k = a.iter().zip(&b).position(|(x, y)| x != y).unwrap_or(0);
            let (x, y) = (a[k], b[k]);
            let (fx, fy) = (sol.factors[x].total_ci, sol.factors[y].total_ci);
            if fx.hi >= fy.lo && fy.hi >= fx.lo {
                format!(
                    "at place {}: the solver's total-index intervals of {} and {} overlap at N = {}: the reduced design cannot order them",
                    k + 1,
                    s.factors[x],
                    s.factors[y],
                    sol.rows
                )
            } else {
                format!(
                    "at place {}: the solver separates {} from {} beyond its intervals at N = {}: the surrogate's error changes the ranking",
                    k + 1,
                    s.factors[y],
                    s.factors[x],
                    sol.rows
                )
            }
        });
        out.push(Ranking {
            index: sur.index.clone(),
            surrogate: names(a),
            surrogate_reduced,
            solver: names(b),
            same,
            why,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::spec::StudyKind;
    use super::*;
    use pino_studies::Distribution;
    use std::collections::BTreeMap;

    fn study() -> Study {
        let mut parameters = BTreeMap::new();
        parameters.insert("m".to_owned(), Distribution::Fixed(3.0));
        Study {
            name: "s".into(),
            kind: StudyKind::Sensitivity { n: 8 },
            parameters,
            solver_check: 0,
        }
    }

    fn parameters() -> Vec<(String, [f64; 2])> {
        vec![
            ("c".into(), [1.0, 2.0]),
            ("m".into(), [2.0, 4.0]),
            ("k".into(), [10.0, 20.0]),
        ]
    }

    /// Rows in SALib's order; `A_B^(i)` equals `A` but in factor `i` (or, for the excitation,
    /// its excitation id); fixed parameters are not factors and keep their value.
    #[test]
    fn the_design_swaps_one_factor_at_a_time() {
        let (factors, ev) = design(&study(), 8, 7, &parameters()).unwrap();
        assert_eq!(factors, ["c", "k", "excitation"]);
        assert_eq!(ev.len(), 8 * 5);
        for row in ev.chunks(5) {
            let (a, b) = (&row[0], &row[4]);
            assert_eq!((a.block, b.block), (Block::A, Block::B));
            assert_eq!(b.excitation, a.excitation + 1);
            assert!(ev.iter().all(|e| e.design[1] == 3.0));
            assert!(a.design[0] != b.design[0] && a.design[2] != b.design[2]);
            // c from B
            assert_eq!(row[1].design, vec![b.design[0], 3.0, a.design[2]]);
            assert_eq!(row[1].excitation, a.excitation);
            // k from B
            assert_eq!(row[2].design, vec![a.design[0], 3.0, b.design[2]]);
            // the excitation from B
            assert_eq!(row[3].design, a.design);
            assert_eq!(row[3].excitation, b.excitation);
            for e in row {
                assert!((1.0..=2.0).contains(&e.design[0]) && (10.0..=20.0).contains(&e.design[2]));
            }
        }
        let (_, again) = design(&study(), 8, 7, &parameters()).unwrap();
        assert_eq!(ev, again);
        let (_, other) = design(&study(), 8, 8, &parameters()).unwrap();
        assert_ne!(ev, other);
    }

    fn indices(totals: &[f64], width: f64) -> Vec<FactorIndices> {
        totals
            .iter()
            .map(|&t| FactorIndices {
                first: t,
                first_ci: pino_studies::stats::Interval {
                    lo: t - width,
                    hi: t + width,
                },
                total: t,
                total_ci: pino_studies::stats::Interval {
                    lo: t - width,
                    hi: t + width,
                },
            })
            .collect()
    }

    fn with(surrogate: &[f64], solver: &[f64], width: f64) -> Sensitivity {
        let mk = |source, t: &[f64]| IndexSobol {
            index: "q".into(),
            source,
            rows: 16,
            factors: indices(t, width),
        };
        Sensitivity {
            n: 16,
            factors: ["a", "b", "c", "excitation"].map(String::from).to_vec(),
            evaluations: Vec::new(),
            answers: Vec::new(),
            solver_rows: 16,
            solved: Vec::new(),
            sobol: vec![mk(source::SURROGATE, surrogate), mk(source::SOLVER, solver)],
            convergence: Vec::new(),
            surrogate_s: 0.0,
            solver_s: 0.0,
        }
    }

    /// Same top three: same; swapped with overlapping intervals: the reduced N cannot tell;
    /// swapped beyond the intervals: the surrogate's error.
    #[test]
    fn rankings_say_whether_and_why_they_differ() {
        let r = rankings(&with(&[0.5, 0.3, 0.1, 0.05], &[0.6, 0.2, 0.15, 0.0], 0.01));
        assert!(r[0].same && r[0].why.is_none());
        assert_eq!(r[0].surrogate, ["a", "b", "c"]);
        let r = rankings(&with(&[0.5, 0.3, 0.1, 0.0], &[0.5, 0.1, 0.3, 0.0], 0.15));
        assert!(!r[0].same);
        assert!(
            r[0].why.as_deref().unwrap().contains("cannot order"),
            "{r:?}"
        );
        let r = rankings(&with(&[0.5, 0.3, 0.1, 0.0], &[0.5, 0.1, 0.3, 0.0], 0.01));
        assert!(
            r[0].why.as_deref().unwrap().contains("surrogate's error"),
            "{r:?}"
        );
    }
}
