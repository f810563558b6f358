//! A split of the dataset through one model, sample by sample: each sample's predicted indices
//! and channels beside the solver's, and its physics residual. What the calibration is fitted
//! on ([`super::build`]) and what its coverage is checked on ([`super::coverage`]).
//!
//! Channels are the predicted outputs, then the rigid DOFs' velocities and accelerations
//! (central differences of the prediction, the solver's exact `_v` / `_a` on the other side),
//! at the interior window points `1..T-1` a prediction is written at. Samples are predicted in
//! chunks and handed over in split order, so memory stays bounded by a chunk and the results
//! do not depend on the thread count.

use super::difficulty::ResidualProbe;
use crate::Result;
use candle_core::Device;
use mbd_system::System;
use pino_indices::IndexConfig;
use pino_learn::checkpoint::ModelMeta;
use pino_learn::data::Prepared;
use pino_learn::infer::predict_samples;
use pino_learn::layout::Layout;
use pino_learn::model::Fno;
use pino_outputs::indices_eval::{eval_config, IndexInputs, StoredColumns};
use pino_outputs::physical::{exact_physical, to_physical, Physical};

/// Samples predicted per chunk.
const CHUNK: usize = 32;

/// A named quantity with its unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Named {
    /// Column name.
    pub name: String,
    /// Unit.
    pub unit: String,
}

/// The predicted channels of a layout that get bands: outputs, velocities, accelerations,
/// each under a name of its own (a rate output beside the difference of its displacement is
/// [`Layout::output_label`]'s `NAME (output)`).
pub fn band_channels(layout: &Layout) -> Vec<Named> {
    let outputs = layout.outputs.iter().enumerate().map(|(k, name)| Named {
        name: layout.output_label(k),
        unit: layout.unit(name).to_owned(),
    });
    let rates = layout
        .velocities()
        .into_iter()
        .chain(layout.accelerations())
        .map(|name| Named {
            unit: layout.unit(&name).to_owned(),
            name,
        });
    outputs.chain(rates).collect()
}

/// The curves of `side` per band channel at the interior points: the prediction's rates are
/// interior already ([`to_physical`]); the solver's (`exact`) are at every window point.
pub fn curves(side: &Physical, layout: &Layout, exact: bool) -> Vec<Vec<f64>> {
    let (o, d) = (layout.n_outputs(), layout.n_dofs());
    let t = side.u.len() / o;
    let interior = 1..t.saturating_sub(1);
    let mut out = Vec::with_capacity(o + 2 * d);
    for c in 0..o {
        out.push(interior.clone().map(|n| side.u[n * o + c]).collect());
    }
    for rates in [&side.v, &side.a] {
        for c in 0..d {
            out.push(if exact {
                interior.clone().map(|n| rates[n * d + c]).collect()
            } else {
                rates.chunks_exact(d).map(|row| row[c]).collect()
            });
        }
    }
    out
}

/// One sample's prediction beside the solver's.
#[derive(Debug, Clone)]
pub struct ScoredSample {
    /// `sample_id`.
    pub id: i64,
    /// Its sampled parameters.
    pub params: Vec<f64>,
    /// Predicted index values ([`IndexInputs::columns`] order; empty without indices).
    pub predicted_indices: Vec<f64>,
    /// The solver's index values.
    pub exact_indices: Vec<f64>,
    /// Predicted curves per band channel ([`band_channels`] order), interior points.
    pub predicted: Vec<Vec<f64>>,
    /// The solver's curves.
    pub exact: Vec<Vec<f64>>,
    /// `rms_q` of the prediction's residual per equation, when the model has equations.
    pub residual_rms: Option<Vec<f64>>,
}

/// How a model is run on a split: batches of `batch` samples on `device`.
#[derive(Debug, Clone, Copy)]
pub struct Run<'a> {
    /// The network.
    pub model: &'a Fno,
    /// Its metadata.
    pub meta: &'a ModelMeta,
    /// Samples per forward pass.
    pub batch: usize,
    /// Where it runs.
    pub device: &'a Device,
}

/// Scores samples of a split through one model.
pub struct Scorer<'a> {
    system: &'a System,
    run: Run<'a>,
    meta: &'a ModelMeta,
    inputs: &'a IndexInputs,
    probe: Option<ResidualProbe>,
    cfg: IndexConfig,
}

impl<'a> Scorer<'a> {
    /// The scorer of the model `run` on `system` with the description's `inputs`.
    pub fn new(system: &'a System, run: Run<'a>, inputs: &'a IndexInputs) -> Result<Self> {
        Ok(Self {
            system,
            run,
            meta: run.meta,
            inputs,
            probe: ResidualProbe::new(system, &run.meta.layout),
            cfg: eval_config(system)?,
        })
    }

    /// Whether the model's predictions have a physics residual.
    pub fn has_residual(&self) -> bool {
        self.probe.is_some()
    }

    /// Sample `i` of `items` with its z-scored prediction `u_n [T, O]`.
    pub fn score(
        &self,
        items: &Prepared,
        i: usize,
        u_n: &[f32],
        stored: &StoredColumns,
    ) -> Result<ScoredSample> {
        let meta = self.meta;
        let (layout, dt) = (&meta.layout, meta.grid.dt);
        let pred = to_physical(u_n, meta);
        let (exact, eta) = exact_physical(items, i, &meta.norm)?;
        let (params, id) = (items.params(i), items.id(i));
        let (mut predicted_indices, mut exact_indices) = (Vec::new(), Vec::new());
        if self.inputs.computable() {
            let side = |phys: &Physical, stored: Option<&StoredColumns>| {
                self.inputs.sample(
                    self.system,
                    layout,
                    params,
                    id,
                    phys,
                    stored,
                    &eta,
                    &meta.grid,
                    &self.cfg,
                )
            };
            predicted_indices = side(&pred, None)?.values;
            exact_indices = side(&exact, Some(stored))?.values;
        }
        let residual_rms = match &self.probe {
            Some(p) => Some(p.rms(self.system, params, &pred, &eta, dt)?),
            None => None,
        };
        Ok(ScoredSample {
            id,
            params: params.to_vec(),
            predicted_indices,
            exact_indices,
            predicted: curves(&pred, layout, false),
            exact: curves(&exact, layout, true),
            residual_rms,
        })
    }

    /// Predicts samples `idx` of `items` and hands each [`ScoredSample`] to `f`, in `idx`
    /// order.
    pub fn for_each(
        &self,
        items: &Prepared,
        idx: &[usize],
        stored: &StoredColumns,
        f: &mut dyn FnMut(&ScoredSample) -> Result<()>,
    ) -> Result<()> {
        use rayon::prelude::*;
        let t = items.t_points();
        let Run {
            model,
            batch,
            device,
            ..
        } = self.run;
        for chunk in idx.chunks(CHUNK) {
            let (preds, _) = predict_samples(model, items, chunk, t, batch, device)?;
            let scored: Vec<ScoredSample> = chunk
                .par_iter()
                .zip(&preds)
                .map(|(&i, u)| self.score(items, i, u, stored))
                .collect::<Result<_>>()?;
            for s in &scored {
                f(s)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use learn_fixtures::synthetic::vehicle_track_system;
    use pino_outputs::channels::prediction_channels;

    /// Every band has a name of its own, a rate output told from the difference of its
    /// displacement; each column `predict` writes reads the band of its own name.
    #[test]
    fn bands_are_named_apart_and_predict_reads_its_own() {
        let system = vehicle_track_system();
        let layout = Layout::of(&system)
            .with_rate_outputs(&system, &["z_c_a".to_owned(), "z_t1_v".to_owned()])
            .unwrap();
        let bands = band_channels(&layout);
        let names: Vec<&str> = bands.iter().map(|b| b.name.as_str()).collect();
        let mut unique = names.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "{names:?}");
        assert!(names.contains(&"z_c_a (output)") && names.contains(&"z_c_a"));
        assert_eq!(
            bands[names.iter().position(|&n| n == "z_c_a").unwrap()].unit,
            "m/s^2"
        );
        let (o, d) = (layout.n_outputs(), layout.n_dofs());
        for (column, source) in prediction_channels(&layout) {
            let Some(band) = source.band(o, d) else {
                continue;
            };
            // The network's own rate answers under the plain column name.
            let plain = names[band].trim_end_matches(" (output)");
            assert_eq!(plain, column, "{column} reads band {}", names[band]);
        }
    }
}
