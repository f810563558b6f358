//! Batched inference: the z-scored outputs of prepared samples through a trained model, in
//! batches run side by side on the CPU (each forward pass is parallel inside too) or one after
//! another on another device. What `evaluate`, `predict` and the benchmarks run; the result does
//! not depend on the batch order or the thread count.

use crate::data::{make_batch, Prepared};
use crate::model::Fno;
use crate::Result;
use candle_core::Device;
use std::time::Instant;

/// Predicts the z-scored outputs `[T, O]` of every sample in `idx`, returning them with the
/// wall time of the forward passes.
pub fn predict_samples(
    model: &Fno,
    items: &Prepared,
    idx: &[usize],
    t_points: usize,
    batch_size: usize,
    device: &Device,
) -> Result<(Vec<Vec<f32>>, f64)> {
    use rayon::prelude::*;
    let t0 = Instant::now();
    // Batches are independent: on the CPU they run side by side (each forward pass is
    // parallel inside too); results do not depend on the order or the thread count.
    let chunks: Vec<&[usize]> = idx.chunks(batch_size.max(1)).collect();
    let predictor = model.predictor()?;
    let run = |chunk: &&[usize]| -> Result<Vec<f32>> {
        let batch = make_batch(items, chunk, t_points, device)?;
        let u = predictor.predict(&batch.x)?;
        Ok(u.flatten_all()?.to_vec1()?)
    };
    let flats: Vec<Vec<f32>> = if device.is_cpu() {
        chunks.par_iter().map(run).collect::<Result<_>>()?
    } else {
        chunks.iter().map(run).collect::<Result<_>>()?
    };
    let wall = t0.elapsed().as_secs_f64();
    let out = flats
        .iter()
        .flat_map(|flat| {
            flat.chunks(t_points * items.layout().n_outputs())
                .map(<[f32]>::to_vec)
        })
        .collect();
    Ok((out, wall))
}
