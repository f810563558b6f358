//! The calibrated intervals in the graph (`docs/uncertainty.md`), and the training-range flag.
//!
//! An index's interval at level `c` is `f +- q_c sigma`, a channel's band `f(t) +- q_c sigma
//! scale(t)`, with `q_c` the conformal quantile of the calibration's scores under the
//! exported normaliser. A graph cannot compute the physics residual `g` (it is the engine's
//! element code over the prediction), so the normalisers it carries are `none` (`sigma = 1`,
//! constant width) and `error_head` when the calibration's heads read the design's parameters
//! only (`sigma = exp(clamp(w_0 + sum_j w_j (x_j - mean_j) / std_j))`).

use crate::graph::{Graph, Value};
use crate::proto::DataType;
use crate::{Error, Result};
use pino_calibration::{Calibration, HeadInput, Normaliser, QuantityScores};
use pino_conformal::ErrorHead;
use pino_learn::checkpoint::TrainingRanges;

/// Which normaliser the graph's intervals use.
pub fn graph_normaliser(cal: &Calibration, asked: Option<Normaliser>) -> Result<Normaliser> {
    let heads_on_parameters = cal.head_inputs == [HeadInput::Parameters];
    match asked {
        Some(Normaliser::None) => Ok(Normaliser::None),
        Some(Normaliser::ErrorHead) if heads_on_parameters => Ok(Normaliser::ErrorHead),
        Some(n) => Err(Error::Unsupported(format!(
            "normaliser `{}`: a graph computes `none`, and `error_head` only when the calibration's heads read the parameters alone (`calibrate.head_inputs: [parameters]`; this calibration's read {:?}); the physics residual is the engine's element code over the prediction",
            n.as_str(),
            cal.head_inputs
        ))),
        None if cal.normaliser == Normaliser::ErrorHead && heads_on_parameters => {
            Ok(Normaliser::ErrorHead)
        }
        None => Ok(Normaliser::None),
    }
}

/// The quantile of quantity `q` under `normaliser` at each of `levels`.
pub fn quantiles(q: &QuantityScores, normaliser: Normaliser, levels: &[f64]) -> Result<Vec<f64>> {
    let scores = q.scores.get(&normaliser).ok_or_else(|| {
        Error::Unsupported(format!(
            "calibration quantity `{}` has no scores under `{}`",
            q.name,
            normaliser.as_str()
        ))
    })?;
    levels
        .iter()
        .map(|&l| {
            scores
                .quantile(l)
                .map_err(|e| Error::Unsupported(format!("level {l}: {e}")))
        })
        .collect()
}

/// `sigma` `[B, Q]` of quantities `qs` for the designs `params [B, P]` under the error heads.
pub fn head_sigma(g: &mut Graph, qs: &[&QuantityScores], params: &str) -> Result<Value> {
    let heads: Vec<&ErrorHead> = qs
        .iter()
        .map(|q| {
            q.head
                .as_ref()
                .ok_or_else(|| Error::Unsupported(format!("`{}` has no error head", q.name)))
        })
        .collect::<Result<_>>()?;
    let mut columns = Vec::new();
    for h in heads {
        let p = h.mean.len();
        let mean = g.f64s(&[p], &h.mean);
        let std = g.f64s(&[p], &h.std);
        let c = g.sub(params, &mean);
        let z = g.div(&c, &std);
        let w = g.f64s(&[p, 1], &h.weights[1..]);
        let dot = g.matmul(&z, &w);
        let w0 = g.scalar(h.weights[0]);
        let lin = g.add(&dot, &w0);
        let (lo, hi) = (g.scalar(h.log_range[0]), g.scalar(h.log_range[1]));
        let clipped = g.op("Clip", &[&lin, &lo, &hi], &[]);
        columns.push(g.unary("Exp", &clipped));
    }
    let refs: Vec<&str> = columns.iter().map(String::as_str).collect();
    Ok(g.concat(1, &refs))
}

/// The flag of each parameter of each design outside its training range `[B, P]` (bool),
/// as `TrainingRanges::outside` judges it (inclusive bounds with a relative slack of 1e-9; a
/// NaN is outside), and whether any is `[B]`.
pub fn outside(g: &mut Graph, ranges: &TrainingRanges, params: &str) -> (Value, Value) {
    let (lo, hi): (Vec<f64>, Vec<f64>) = ranges
        .min
        .iter()
        .zip(&ranges.max)
        .map(|(&lo, &hi)| {
            let slack = 1e-9 * lo.abs().max(hi.abs());
            (lo - slack, hi + slack)
        })
        .unzip();
    let p = lo.len();
    let (lo, hi) = (g.f64s(&[p], &lo), g.f64s(&[p], &hi));
    let above = g.op("GreaterOrEqual", &[params, &lo], &[]);
    let below = g.op("LessOrEqual", &[params, &hi], &[]);
    let inside = g.op("And", &[&above, &below], &[]);
    let out = g.unary("Not", &inside);
    let count = g.cast(&out, DataType::Int32);
    let any = g.reduce("ReduceMax", &count, &[1], false);
    let any = g.cast(&any, DataType::Bool);
    (out, any)
}

/// Verdict codes `[B, L, I]` (int32) of the intervals `lo`, `hi` `[B, L, I]` against the
/// upper `limits` (`None`: no limit, code -1): 0 pass (`hi <= limit`), 2 fail (`lo >
/// limit`), 1 uncertain otherwise; an `extrapolated` `[B]` design is never better than 1.
pub fn verdicts(
    g: &mut Graph,
    lo: &str,
    hi: &str,
    limits: &[Option<f64>],
    extrapolated: &str,
) -> Value {
    let n = limits.len();
    let lim: Vec<f64> = limits.iter().map(|l| l.unwrap_or(f64::INFINITY)).collect();
    let has: Vec<i32> = limits.iter().map(|l| l.is_some() as i32).collect();
    let lim = g.f64s(&[n], &lim);
    let pass = g.op("LessOrEqual", &[hi, &lim], &[]);
    let fail = g.op("Greater", &[lo, &lim], &[]);
    let pass = g.cast(&pass, DataType::Int32);
    let fail = g.cast(&fail, DataType::Int32);
    let ones = g.i32s(&[1]);
    let not_pass = g.sub(&ones, &pass);
    let code = g.add(&not_pass, &fail);
    let ex = g.cast(extrapolated, DataType::Int32);
    let ex = g.reshape(&ex, &[-1, 1, 1]);
    let code = g.op("Max", &[&code, &ex], &[]);
    let has_limit = g.i32s(&has);
    let coded = g.mul(&code, &has_limit);
    let minus = g.sub(&has_limit, &ones);
    g.add(&coded, &minus)
}
