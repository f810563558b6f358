//! One model of a surrogate in the graph: its network, its prediction in physical units and
//! its rates (`pino_eval::eval::to_physical`), the channels `predict --out` writes, and the
//! series every index reads (`pino_eval::indices_eval`), all in double precision after the
//! network.

use crate::graph::{Graph, Value};
use crate::network::{Network, Spectral, Weights};
use crate::proto::DataType;
use crate::{Error, Result};
use pino_eval::indices_eval::Source;
use pino_eval::predict::{prediction_channels, ChannelSource, Predictor};
use pino_learn::checkpoint::ModelMeta;

/// A model's prediction in the graph, physical units, f64.
pub struct Prediction {
    /// Outputs `[B, T, O]` (m, rad, N, and the rate outputs' units).
    pub u: Value,
    /// Central-difference velocities of the rigid DOFs at the interior points `[B, T-2, D]`.
    pub v: Value,
    /// Second differences, the accelerations `[B, T-2, D]`.
    pub a: Value,
    /// The excitation input `[B, T, E]` (m, m/s).
    pub eta: Value,
}

/// The network of `predictor`'s model (weights `weights`) on the graph inputs, and its
/// prediction in physical units.
pub fn predict(
    g: &mut Graph,
    meta: &ModelMeta,
    weights: &Weights,
    spectral: Spectral,
    eta: &str,
    params: &str,
) -> Result<Prediction> {
    let net = Network {
        meta,
        weights,
        spectral,
    };
    let x = net.input(g, eta, params);
    let u_n = net.forward(g, &x)?;
    let u_n = g.cast(&u_n, DataType::Double);
    let (o, d) = (meta.layout.n_outputs(), meta.layout.n_dofs());
    let t = meta.grid.t_points;
    let stats = &meta.norm.outputs;
    let std = g.f64s(&[o], &stats.std);
    let mean = g.f64s(&[o], &stats.mean);
    let scaled = g.mul(&u_n, &std);
    let u = g.add(&scaled, &mean);
    // Differences of the z-scored values times the standard deviation (the mean cancels).
    let dofs = g.slice(&u_n, 2, 0, d);
    let prev = g.slice(&dofs, 1, 0, t - 2);
    let mid = g.slice(&dofs, 1, 1, t - 1);
    let next = g.slice(&dofs, 1, 2, t);
    let s = g.f64s(&[d], &stats.std[..d]);
    let dt = meta.grid.dt;
    let diff = g.sub(&next, &prev);
    let sv = g.mul(&s, &diff);
    let two_dt = g.scalar(2.0 * dt);
    let v = g.div(&sv, &two_dt);
    let two = g.scalar(2.0);
    let twice = g.mul(&mid, &two);
    let first = g.sub(&next, &twice);
    let second = g.add(&first, &prev);
    let sa = g.mul(&s, &second);
    let dt2 = g.scalar(dt * dt);
    let a = g.div(&sa, &dt2);
    Ok(Prediction {
        u,
        v,
        a,
        eta: eta.to_owned(),
    })
}

/// The channels of a prediction (`predict --out`'s, without the excitations, which are
/// inputs): names and, for each, its column in `[outputs, velocities, accelerations]` (also
/// its band among the calibration's channels).
pub fn channels(meta: &ModelMeta) -> Vec<(String, usize)> {
    let (o, d) = (meta.layout.n_outputs(), meta.layout.n_dofs());
    prediction_channels(&meta.layout)
        .into_iter()
        .filter_map(|(name, source)| match source {
            ChannelSource::Excitation(_) => None,
            s => s.band(o, d).map(|k| (name, k)),
        })
        .collect()
}

/// The channels `[B, T-2, C]` at the interior points, in [`channels`] order.
pub fn channel_values(g: &mut Graph, meta: &ModelMeta, p: &Prediction) -> Value {
    let t = meta.grid.t_points;
    let interior = g.slice(&p.u, 1, 1, t - 1);
    let all = g.concat(2, &[&interior, &p.v, &p.a]);
    let index: Vec<usize> = channels(meta).iter().map(|(_, k)| *k).collect();
    g.pick(&all, 2, &index)
}

/// A series by column name, or why the graph cannot give it.
pub type Series = Vec<(String, std::result::Result<Value, String>)>;

/// The series `[B, N]` of every column the indices read, over the window's rows `first..T-1`
/// (`first >= 1`), as `pino_eval::indices_eval` rebuilds it from a prediction.
pub fn index_series(g: &mut Graph, predictor: &Predictor, p: &Prediction, first: usize) -> Series {
    let meta = &predictor.meta;
    let t = meta.grid.t_points;
    let dt = meta.grid.dt;
    let column = |g: &mut Graph, x: &str, c: usize, from: usize, to: usize| {
        let col = g.slice(x, 2, c, c + 1);
        let rows = g.slice(&col, 1, from, to);
        g.reshape(&rows, &[0, -1])
    };
    let mut out = Vec::new();
    for (name, source) in predictor.index_inputs().sources() {
        let series = match *source {
            Source::Output(c) => column(g, &p.u, c, first, t - 1),
            Source::Excitation(j) => column(g, &p.eta, j, first, t - 1),
            Source::DofRate(j, order) => {
                let x = if order == 1 { &p.v } else { &p.a };
                column(g, x, j, first - 1, t - 2)
            }
            Source::OutputRate(c, order) => {
                let prev = column(g, &p.u, c, first - 1, t - 2);
                let mid = column(g, &p.u, c, first, t - 1);
                let next = column(g, &p.u, c, first + 1, t);
                if order == 1 {
                    let d = g.sub(&next, &prev);
                    let h = g.scalar(2.0 * dt);
                    g.div(&d, &h)
                } else {
                    let two = g.scalar(2.0);
                    let twice = g.mul(&mid, &two);
                    let f = g.sub(&next, &twice);
                    let s = g.add(&f, &prev);
                    let h = g.scalar(dt * dt);
                    g.div(&s, &h)
                }
            }
            Source::Deflection(e) => match deflection(g, predictor, p, e, name, first) {
                Ok(v) => v,
                Err(e) => {
                    out.push((name.clone(), Err(e.to_string())));
                    continue;
                }
            },
        };
        out.push((name.clone(), Ok(series)));
    }
    out
}

/// Element `e`'s deflection over the window: the sum of its terms over the predicted outputs
/// and the exact profile. The terms' coefficients are read at the nominal design and at the
/// corners of the training box; one that differs between them (a lever arm that is a
/// design parameter) is refused, naming the column.
fn deflection(
    g: &mut Graph,
    predictor: &Predictor,
    p: &Prediction,
    e: usize,
    name: &str,
    first: usize,
) -> Result<Value> {
    let meta = &predictor.meta;
    let system = predictor.system();
    let layout = &meta.layout;
    let (o, n_e) = (layout.n_outputs(), layout.n_excitations());
    let map = pino_learn::residual::ChannelMap::new(system, layout);
    let ranges = &meta.training_ranges;
    let designs = [
        system.nominal().into_values(),
        ranges.min.clone(),
        ranges.max.clone(),
    ];
    let mut coefficients: Option<Vec<f64>> = None;
    for d in designs {
        let design = system
            .sampled_values(d)
            .map_err(|e| Error::Unsupported(e.to_string()))?;
        let eq = pino_learn::residual::sample_equations(system, &design, Vec::new())
            .map_err(|e| Error::Unsupported(format!("`{name}`: {e}")))?;
        let reader = map
            .deflection(&eq, e)
            .ok_or_else(|| Error::Unsupported(format!("`{name}`: not derivable")))?;
        // The reader is linear in the outputs and the excitations: its coefficients are its
        // values on unit rows.
        let unit = |k: usize| {
            let mut u = vec![0.0; o];
            let mut x = vec![0.0; n_e];
            if k < o {
                u[k] = 1.0;
            } else {
                x[k - o] = 1.0;
            }
            reader.at(&u, &x)
        };
        let c: Vec<f64> = (0..o + n_e).map(unit).collect();
        match &coefficients {
            Some(prev) if *prev != c => {
                return Err(Error::Unsupported(format!(
                    "index input `{name}`: the element's deflection reads the outputs with coefficients that depend on the design (lever arms that are sampled parameters)"
                )))
            }
            _ => coefficients = Some(c),
        }
    }
    let c = coefficients.unwrap_or_default();
    let t = meta.grid.t_points;
    let u = g.slice(&p.u, 1, first, t - 1);
    let x = g.slice(&p.eta, 1, first, t - 1);
    let both = g.concat(2, &[&u, &x]);
    let w = g.f64s(&[o + n_e, 1], &c);
    let sum = g.matmul(&both, &w);
    Ok(g.reshape(&sum, &[0, -1]))
}
