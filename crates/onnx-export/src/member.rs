//! One model of a surrogate in the graph: its network, its prediction in physical units and
//! its rates (`pino_outputs::physical::to_physical`), the channels `predict --out` writes, and the
//! series every index reads (`pino_outputs::indices_eval`), all in double precision after the
//! network, channel-major until the channels are assembled.

use crate::graph::{Graph, Value};
use crate::network::{Network, Spectral, Weights};
use crate::proto::DataType;
use crate::{Error, Result};
use pino_learn::checkpoint::ModelMeta;
use pino_outputs::channels::{prediction_channels, ChannelSource};
use pino_outputs::indices_eval::Source;
use pino_predict::Predictor;

/// A model's prediction in the graph, physical units, f64, channel-major (`[channel, B,
/// time]`: a channel's series is one contiguous block per design).
pub struct Prediction {
    /// Outputs `[O, B, T]` (m, rad, N, and the rate outputs' units).
    pub u: Value,
    /// Central-difference velocities of the rigid DOFs at the interior points `[D, B, T-2]`.
    pub v: Value,
    /// Second differences, the accelerations `[D, B, T-2]`.
    pub a: Value,
    /// The excitation input `[E, B, T]` (m, m/s).
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
    let u_n = net.forward(g, eta, params)?;
    let u_n = g.cast(&u_n, DataType::Double);
    let (o, d) = (meta.layout.n_outputs(), meta.layout.n_dofs());
    let t = meta.grid.t_points;
    let stats = &meta.norm.outputs;
    let std = g.f64s(&[o, 1, 1], &stats.std);
    let mean = g.f64s(&[o, 1, 1], &stats.mean);
    let scaled = g.mul(&u_n, &std);
    let u = g.add(&scaled, &mean);
    // Differences of the z-scored values times the standard deviation (the mean cancels).
    let dofs = g.slice(&u_n, 0, 0, d);
    let prev = g.slice(&dofs, 2, 0, t - 2);
    let mid = g.slice(&dofs, 2, 1, t - 1);
    let next = g.slice(&dofs, 2, 2, t);
    let dt = meta.grid.dt;
    let per = |k: f64| -> Vec<f64> { stats.std[..d].iter().map(|s| s * k).collect() };
    let diff = g.sub(&next, &prev);
    let sv = g.f64s(&[d, 1, 1], &per(0.5 / dt));
    let v = g.mul(&diff, &sv);
    let two = g.scalar(2.0);
    let twice = g.mul(&mid, &two);
    let first = g.sub(&next, &twice);
    let second = g.add(&first, &prev);
    let sa = g.f64s(&[d, 1, 1], &per(1.0 / (dt * dt)));
    let a = g.mul(&second, &sa);
    Ok(Prediction {
        u,
        v,
        a,
        eta: g.transpose(eta, &[2, 0, 1]),
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

/// Where a channel's values lie: row `row` of `of` (`[rows, B, time]`), over the whole
/// window (`whole`: the outputs, cut to the interior points when read) or over the interior
/// points (the differences).
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelAt {
    /// The block.
    pub of: Value,
    /// Its rows.
    pub rows: usize,
    /// The channel's row.
    pub row: usize,
    /// Whether the block spans the whole window.
    pub whole: bool,
}

/// Every channel of a prediction, in [`channels`] order.
pub fn channel_values(meta: &ModelMeta, p: &Prediction) -> Vec<ChannelAt> {
    let (o, d) = (meta.layout.n_outputs(), meta.layout.n_dofs());
    channels(meta)
        .into_iter()
        .map(|(_, k)| {
            let (of, rows, row, whole) = match k {
                k if k < o => (&p.u, o, k, true),
                k if k < o + d => (&p.v, d, k - o, false),
                k => (&p.a, d, k - o - d, false),
            };
            ChannelAt {
                of: of.clone(),
                rows,
                row,
                whole,
            }
        })
        .collect()
}

/// The channels `[B, T-2, C]` of `picked` (each over a `T`-point window): consecutive rows of
/// one block are read by one slice, the blocks joined and turned design-major once.
pub fn assemble_channels(g: &mut Graph, picked: &[&ChannelAt], t: usize) -> Value {
    let mut runs: Vec<(&ChannelAt, usize)> = Vec::new();
    for c in picked {
        match runs.last_mut() {
            Some((first, n)) if first.of == c.of && first.row + *n == c.row => *n += 1,
            _ => runs.push((c, 1)),
        }
    }
    let parts: Vec<Value> = runs
        .iter()
        .map(|&(c, n)| {
            let mut cuts = Vec::new();
            if c.row > 0 || n < c.rows {
                cuts.push((0, c.row, c.row + n));
            }
            if c.whole {
                cuts.push((2, 1, t - 1));
            }
            g.slice_axes(&c.of, &cuts)
        })
        .collect();
    let refs: Vec<&str> = parts.iter().map(String::as_str).collect();
    let all = if refs.len() == 1 {
        parts[0].clone()
    } else {
        g.concat(0, &refs)
    };
    g.transpose(&all, &[1, 2, 0])
}

/// A series by column name, or why the graph cannot give it.
pub type Series = Vec<(String, std::result::Result<Value, String>)>;

/// The series `[B, N]` of every column the indices read, over the window's rows `first..T-1`
/// (`first >= 1`), as `pino_outputs::indices_eval` rebuilds it from a prediction.
pub fn index_series(g: &mut Graph, predictor: &Predictor, p: &Prediction, first: usize) -> Series {
    let meta = &predictor.meta;
    let t = meta.grid.t_points;
    let dt = meta.grid.dt;
    let column = |g: &mut Graph, x: &str, c: usize, from: usize, to: usize| {
        let cut = g.slice_axes(x, &[(0, c, c + 1), (2, from, to)]);
        g.reshape(&cut, &[-1, (to - from) as i64])
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
    let u = g.slice(&p.u, 2, first, t - 1);
    let x = g.slice(&p.eta, 2, first, t - 1);
    let both = g.concat(0, &[&u, &x]);
    let both = g.reshape(&both, &[(o + n_e) as i64, -1]);
    let w = g.f64s(&[1, o + n_e], &c);
    let sum = g.matmul(&w, &both);
    Ok(g.reshape(&sum, &[-1, (t - 1 - first) as i64]))
}
