//! Batches ([`Batch`]): the tensors of a list of prepared samples, inputs assembled here.

use super::Prepared;
use crate::Result;
use candle_core::{DType, Device, Tensor};

/// One batch of tensors (their shapes: the [`crate::data`] module doc).
#[derive(Debug, Clone)]
pub struct Batch {
    /// Inputs `[B, T, 1 + E + P]` f32 z-scored.
    pub x: Tensor,
    /// Target outputs `[B, T, O]` f32 z-scored (solutions, then forces).
    pub u: Tensor,
    /// Target velocities at interior points `[B, T-2, D]` f32 z-scored.
    pub v: Tensor,
    /// Target accelerations at interior points `[B, T-2, D]` f32 z-scored.
    pub a: Tensor,
    /// Parameters `[B, P]` f64 physical.
    pub params: Tensor,
    /// Each sample's `sample_id`.
    pub ids: Vec<i64>,
    /// Each sample's parameters on the host (the rows of `params`): what its equations are
    /// built from.
    pub designs: Vec<Vec<f64>>,
    /// Excitations `[B, T, E]` f64 physical (m).
    pub eta: Tensor,
    /// ODE magnitude weights `[B, Q]` f64 (ones when absent).
    pub phi: Tensor,
    /// The samples' force scales `[B]` f64 (N; 1 when absent).
    pub f_scale: Tensor,
    /// Index of each sample in its [`Prepared`].
    pub index: Vec<usize>,
}

/// Builds the batch of `items[idx]` on `device`; the input blocks are assembled here.
pub fn make_batch(
    items: &Prepared,
    idx: &[usize],
    t_points: usize,
    device: &Device,
) -> Result<Batch> {
    let b = idx.len();
    let t = t_points;
    debug_assert_eq!(t, items.t_points);
    let l = &items.layout;
    let (n_in, n_out, d, e) = (l.n_inputs(), l.n_outputs(), l.n_dofs(), l.n_excitations());
    let mut x = Vec::with_capacity(b * t * n_in);
    let mut u = Vec::with_capacity(b * t * n_out);
    let mut v = Vec::with_capacity(b * (t - 2) * d);
    let mut a = Vec::with_capacity(b * (t - 2) * d);
    let mut eta = Vec::with_capacity(b * t * e);
    for &i in idx {
        let s = items.series(i)?;
        items.push_inputs(i, &s.eta, &mut x);
        u.extend_from_slice(&s.u);
        v.extend_from_slice(&s.v[d..(t - 1) * d]);
        a.extend_from_slice(&s.a[d..(t - 1) * d]);
        eta.extend_from_slice(&s.eta);
    }
    let designs: Vec<Vec<f64>> = idx.iter().map(|&i| items.params[i].clone()).collect();
    let params: Vec<f64> = designs.concat();
    let phi: Vec<f64> = idx
        .iter()
        .flat_map(|&i| items.phi[i].iter().copied())
        .collect();
    let f_scale: Vec<f64> = idx.iter().map(|&i| items.force_scale[i]).collect();
    let n_eq = l.equations.len();
    Ok(Batch {
        x: Tensor::from_vec(x, (b, t, n_in), device)?,
        u: Tensor::from_vec(u, (b, t, n_out), device)?,
        v: Tensor::from_vec(v, (b, t - 2, d), device)?,
        a: Tensor::from_vec(a, (b, t - 2, d), device)?,
        params: Tensor::from_vec(params, (b, l.params.len()), device)?,
        ids: idx.iter().map(|&i| items.id(i)).collect(),
        designs,
        eta: Tensor::from_vec(eta, (b, t, e), device)?,
        phi: Tensor::from_vec(phi, (b, n_eq), device)?.to_dtype(DType::F64)?,
        f_scale: Tensor::from_vec(f_scale, b, device)?,
        index: idx.to_vec(),
    })
}
