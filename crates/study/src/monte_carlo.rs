//! The `monte_carlo` study: N designs drawn from the parameter distributions (design `i`'s
//! coordinates from the stream `(seed, StudyDesigns, i)`, one uniform per parameter in the
//! model's parameter order, mapped by each distribution's inverse CDF), design `i` under
//! excitation `i`. Per index: mean, standard deviation and quantiles with bootstrap intervals,
//! and for every index with a limit the probability of exceeding it with its Wilson interval
//! and, where calibrated, the surrogate-uncertainty bounds. The solver answers `solver_check`
//! designs spread over the sample; the same statistics over those designs, surrogate and
//! solver, stand side by side.

use super::evaluate::{spread, Evaluator, Solved};
use super::source;
use super::spec::Study;
use crate::Result;
use mbd_dataset::{Purpose, SampleStream};
use pino_predict::DesignAnswer;
use pino_studies::stats::{exceedance, summarise, Exceedance, Interval, Summary};
use pino_studies::Distribution;
use std::collections::BTreeMap;
use std::time::Instant;

/// One source's values of an index, with the designs' intervals when calibrated.
type Source = (&'static str, Vec<f64>, Option<Vec<Interval>>);

/// One index's statistics from one source.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexSummary {
    /// The index.
    pub index: String,
    /// `surrogate` (all designs), `surrogate_checked` (the solver's designs) or `solver`.
    pub source: &'static str,
    /// Mean, std, quantiles.
    pub summary: Summary,
    /// The exceedance of its limit, when it has one.
    pub exceedance: Option<Exceedance>,
}

/// A Monte Carlo study's results.
#[derive(Debug, Clone)]
pub struct MonteCarlo {
    /// The designs (model parameter order).
    pub designs: Vec<Vec<f64>>,
    /// Their excitation ids.
    pub excitation: Vec<u64>,
    /// The surrogate's answers.
    pub answers: Vec<DesignAnswer>,
    /// The designs the solver checked (positions in `designs`).
    pub checked: Vec<usize>,
    /// The solver's answers of those.
    pub solved: Vec<Solved>,
    /// The statistics, index by index and source by source.
    pub summaries: Vec<IndexSummary>,
    /// The limit of each index (index order).
    pub limits: Vec<Option<f64>>,
    /// Wall time of the surrogate's evaluations (s).
    pub surrogate_s: f64,
    /// Wall time of the solver's (s).
    pub solver_s: f64,
}

/// Design `i`'s parameter values.
pub fn draw(seed: u64, i: u64, dists: &[Distribution]) -> Vec<f64> {
    let mut s = SampleStream::new(seed, Purpose::StudyDesigns, i);
    dists.iter().map(|d| d.at(s.uniform())).collect()
}

/// Runs `study` of `n` designs with upper `limits` by index name (the description's where
/// not given); `parameters` are the model's sampled parameters with their training ranges.
pub fn run(
    ev: &Evaluator<'_>,
    study: &Study,
    n: usize,
    limits: &BTreeMap<String, f64>,
    parameters: &[(String, [f64; 2])],
) -> Result<MonteCarlo> {
    let p = ev.params;
    let dists = study.distributions(parameters);
    let designs: Vec<Vec<f64>> = (0..n as u64).map(|i| draw(p.seed, i, &dists)).collect();
    let excitation: Vec<u64> = (0..n as u64).collect();
    let t0 = Instant::now();
    let answers = ev.surrogate(&designs, &excitation)?;
    let surrogate_s = t0.elapsed().as_secs_f64();
    let checked = spread(n, study.solver_check);
    let t1 = Instant::now();
    let solved = ev.solver(
        &checked
            .iter()
            .map(|&k| designs[k].clone())
            .collect::<Vec<_>>(),
        &checked.iter().map(|&k| excitation[k]).collect::<Vec<_>>(),
    )?;
    let solver_s = t1.elapsed().as_secs_f64();
    let columns = ev.predictor.index_inputs().columns();
    let described = ev
        .predictor
        .index_inputs()
        .limits(ev.predictor.system(), &ev.cfg);
    let limits: Vec<Option<f64>> = columns
        .iter()
        .zip(described)
        .map(|(c, d)| limits.get(&c.name).copied().or(d))
        .collect();
    let mut summaries = Vec::new();
    for (j, c) in columns.iter().enumerate() {
        let bounds = |rows: &[usize]| -> Option<Vec<Interval>> {
            rows.iter()
                .map(|&k| {
                    answers[k].calibrated.as_ref().map(|a| Interval {
                        lo: a.indices[j].lo,
                        hi: a.indices[j].hi,
                    })
                })
                .collect()
        };
        let all: Vec<usize> = (0..n).collect();
        let sources: [Source; 3] = [
            (
                source::SURROGATE,
                answers.iter().map(|a| a.indices.values[j]).collect(),
                bounds(&all),
            ),
            (
                source::SURROGATE_CHECKED,
                checked
                    .iter()
                    .map(|&k| answers[k].indices.values[j])
                    .collect(),
                bounds(&checked),
            ),
            (
                source::SOLVER,
                solved.iter().map(|s| s.indices[j]).collect(),
                None,
            ),
        ];
        for (k, (source, values, b)) in sources.into_iter().enumerate() {
            if values.is_empty() {
                continue;
            }
            let seed = p.seed ^ ((j as u64) << 32) ^ (k as u64) << 48;
            summaries.push(IndexSummary {
                index: c.name.clone(),
                source,
                summary: summarise(&values, p.bootstrap, seed, p.confidence),
                exceedance: limits[j].map(|l| exceedance(&values, b.as_deref(), l, p.confidence)),
            });
        }
    }
    Ok(MonteCarlo {
        designs,
        excitation,
        answers,
        checked,
        solved,
        summaries,
        limits,
        surrogate_s,
        solver_s,
    })
}
