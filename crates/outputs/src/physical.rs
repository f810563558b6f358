//! Predictions and exact series in physical units: the network's z-scored outputs back to
//! SI, the rigid DOFs' rates by central differences, the display units of each channel.

use crate::Result;
use pino_learn::checkpoint::ModelMeta;
use pino_learn::data::Prepared;
use pino_learn::norm::Normalisation;

/// Physical prediction of one sample: outputs `[T, O]` (m, rad, N), and interior
/// velocities and accelerations `[T-2, D]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Physical {
    /// Outputs (displacements, then contact forces).
    pub u: Vec<f64>,
    /// Velocities (interior points).
    pub v: Vec<f64>,
    /// Accelerations (interior points).
    pub a: Vec<f64>,
}

/// De-normalises a z-scored prediction `[T, O]` and differentiates its rigid DOFs (central
/// differences).
pub fn to_physical(u_n: &[f32], meta: &ModelMeta) -> Physical {
    let (o, d) = (meta.layout.n_outputs(), meta.layout.n_dofs());
    let t = u_n.len() / o;
    let dt = meta.grid.dt;
    let u = meta.norm.outputs.denormalise(u_n);
    let mut v = Vec::with_capacity((t - 2) * d);
    let mut a = Vec::with_capacity((t - 2) * d);
    for n in 1..t - 1 {
        for c in 0..d {
            // Differences of z-scored values times std: the mean cancels exactly.
            let s = meta.norm.outputs.std[c];
            let (p, m, x) = (
                u_n[(n - 1) * o + c] as f64,
                u_n[n * o + c] as f64,
                u_n[(n + 1) * o + c] as f64,
            );
            v.push(s * (x - p) / (2.0 * dt));
            a.push(s * (x - 2.0 * m + p) / (dt * dt));
        }
    }
    Physical { u, v, a }
}

/// The exact (solver) values of prepared sample `i` in physical units: outputs `[T, O]`,
/// velocities and accelerations `[T, D]` at every window point; and its excitations
/// `[T, E]`.
pub fn exact_physical(
    items: &Prepared,
    i: usize,
    norm: &Normalisation,
) -> Result<(Physical, Vec<f64>)> {
    let s = items.series(i)?;
    Ok((
        Physical {
            u: norm.outputs.denormalise(&s.u),
            v: norm.velocities.denormalise(&s.v),
            a: norm.accelerations.denormalise(&s.a),
        },
        s.eta,
    ))
}
