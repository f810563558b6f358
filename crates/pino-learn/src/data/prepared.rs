//! Samples prepared for batching ([`Prepared`]): the second streaming pass z-scores each
//! sample's window once into f32 storage; [`load_split`] reads one split in a single pass.

use super::files::ParamsTable;
use super::{scan, Dataset, DatasetInfo, Sample, Split};
use crate::config::WindowConfig;
use crate::layout::{Layout, Record};
use crate::norm::Normalisation;
use crate::store::{SampleSeries, SeriesStore};
use crate::Result;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Physical input block `[T, 1 + E + P]`: `t`, the excitations (`eta` row-major `[T, E]`),
/// the parameters.
pub fn input_block(t: &[f64], eta: &[f64], params: &[f64]) -> Vec<f64> {
    let e = if t.is_empty() { 0 } else { eta.len() / t.len() };
    let mut out = Vec::with_capacity(t.len() * (1 + e + params.len()));
    for (k, &tk) in t.iter().enumerate() {
        out.push(tk);
        out.extend_from_slice(&eta[e * k..e * k + e]);
        out.extend_from_slice(params);
    }
    out
}

/// Samples prepared for batching, each stored once: z-scored f32 outputs `[T, O]` and
/// derivative targets `[T, D]`, physical f64 excitations `[T, E]` (in a [`SeriesStore`], in
/// memory or spilled to disk), the parameters once per sample (physical f64 and z-scored f32).
/// Index `i` is the `i`-th sample of the dataset (or of the split) it was prepared from.
#[derive(Debug)]
pub struct Prepared {
    pub(super) layout: Layout,
    pub(super) t_points: usize,
    /// z-scored window times `[T]`, shared by every sample.
    t_n: Vec<f32>,
    eta_mean: Vec<f64>,
    eta_std: Vec<f64>,
    ids: Vec<i64>,
    pub(super) params: Vec<Vec<f64>>,
    params_n: Vec<Vec<f32>>,
    pub(super) phi: Vec<Vec<f64>>,
    pub(super) force_scale: Vec<f64>,
    /// Record of each sample in the store.
    slots: Vec<usize>,
    store: SeriesStore,
}

/// Z-scores a window's column-major group into a row-major f32 block.
pub(super) fn zscore(cols: &[Vec<f64>], st: &crate::norm::ChannelStats) -> Vec<f32> {
    let c = cols.len();
    let rows = cols.first().map_or(0, Vec::len);
    let mut out = vec![0.0f32; rows * c];
    for (k, row) in out.chunks_exact_mut(c.max(1)).enumerate().take(rows) {
        for (j, x) in row.iter_mut().enumerate().take(c) {
            *x = ((cols[j][k] - st.mean[j]) / st.std[j]) as f32;
        }
    }
    out
}

/// Builds a [`Prepared`] from streamed windows (any order), then orders it like a dataset.
pub(super) struct Builder<'a> {
    norm: &'a Normalisation,
    record: Record,
    store: SeriesStore,
    by_id: BTreeMap<i64, usize>,
}

impl<'a> Builder<'a> {
    fn new(
        norm: &'a Normalisation,
        layout: &Layout,
        t_points: usize,
        expected: usize,
    ) -> Result<Self> {
        Ok(Self {
            norm,
            record: layout.training_record(),
            store: SeriesStore::new(t_points, layout.series_shape(), expected)?,
            by_id: BTreeMap::new(),
        })
    }

    fn add(&mut self, s: &Sample, w: &[Vec<f64>]) -> Result<()> {
        let (n, r) = (self.norm, &self.record);
        let rows = w[0].len();
        let ne = r.excitations.len();
        let mut eta = vec![0.0; rows * ne];
        for (k, row) in eta
            .chunks_exact_mut(ne.max(1))
            .enumerate()
            .take(if ne == 0 { 0 } else { rows })
        {
            for (i, x) in row.iter_mut().enumerate() {
                *x = w[r.excitations.start + i][k];
            }
        }
        let slot = self.store.push(&SampleSeries {
            u: zscore(&w[r.displacements.clone()], &n.outputs),
            v: zscore(&w[r.velocities.clone()], &n.velocities),
            a: zscore(&w[r.accelerations.clone()], &n.accelerations),
            eta,
        })?;
        self.by_id.insert(s.id, slot);
        Ok(())
    }

    /// The samples of `ds` in its order (its phi replaces the streamed one).
    fn finish(self, ds: &Dataset) -> Prepared {
        let Builder {
            norm,
            store,
            mut by_id,
            ..
        } = self;
        let ins = &norm.inputs;
        let layout = ds.layout.clone();
        let inputs = layout.input_ranges();
        let n_eq = layout.equations.len();
        let mut p = Prepared {
            t_points: ds.t.len(),
            t_n: ds
                .t
                .iter()
                .map(|&x| ((x - ins.mean[inputs.time]) / ins.std[inputs.time]) as f32)
                .collect(),
            eta_mean: ins.mean[inputs.excitations.clone()].to_vec(),
            eta_std: ins.std[inputs.excitations.clone()].to_vec(),
            ids: Vec::with_capacity(ds.samples.len()),
            params: Vec::with_capacity(ds.samples.len()),
            params_n: Vec::with_capacity(ds.samples.len()),
            phi: Vec::with_capacity(ds.samples.len()),
            force_scale: Vec::with_capacity(ds.samples.len()),
            slots: Vec::with_capacity(ds.samples.len()),
            store,
            layout,
        };
        for s in &ds.samples {
            let slot = by_id.remove(&s.id).expect("every indexed sample streamed");
            p.ids.push(s.id);
            p.params.push(s.params.as_slice().to_vec());
            p.params_n.push(
                s.params
                    .as_slice()
                    .iter()
                    .zip(inputs.params.clone())
                    .map(|(v, k)| ((v - ins.mean[k]) / ins.std[k]) as f32)
                    .collect(),
            );
            p.phi.push(s.phi.clone().unwrap_or_else(|| vec![1.0; n_eq]));
            p.force_scale.push(s.force_scale.unwrap_or(1.0));
            p.slots.push(slot);
        }
        p
    }
}

impl Prepared {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// `sample_id` of sample `i`.
    pub fn id(&self, i: usize) -> i64 {
        self.ids[i]
    }

    /// Window length `T`.
    pub fn t_points(&self) -> usize {
        self.t_points
    }

    /// The layout.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The series of sample `i`: z-scored `u [T, O]`, `v, a [T, D]`, physical `eta [T, E]`.
    pub fn series(&self, i: usize) -> Result<SampleSeries> {
        self.store.get(self.slots[i])
    }

    /// Parameters of sample `i`.
    pub fn params(&self, i: usize) -> &[f64] {
        &self.params[i]
    }

    /// Force scale of sample `i` (N): its mean static contact force (1 when it has none).
    pub fn force_scale(&self, i: usize) -> f64 {
        self.force_scale[i]
    }

    /// Whether the series were spilled to disk (over the memory budget).
    pub fn spilled(&self) -> bool {
        self.store.spilled()
    }

    /// z-scored input block `[T, 1 + E + P]` of a sample with excitations `eta` and index `i`,
    /// appended to `out`: the same values as `norm.inputs.normalise(&input_block(..))`.
    pub(super) fn push_inputs(&self, i: usize, eta: &[f64], out: &mut Vec<f32>) {
        let pn = &self.params_n[i];
        let ne = self.eta_mean.len();
        for (k, &tn) in self.t_n.iter().enumerate() {
            out.push(tn);
            for j in 0..ne {
                out.push(((eta[ne * k + j] - self.eta_mean[j]) / self.eta_std[j]) as f32);
            }
            out.extend_from_slice(pn);
        }
    }

    /// Bytes held in memory by the samples (series in memory plus per-sample values).
    pub fn heap_bytes(&self) -> usize {
        let p = self.layout.params.len();
        self.store.memory_bytes()
            + 4 * self.t_n.len()
            + self.ids.len() * (8 + p * 8 + p * 4 + self.layout.equations.len() * 8 + 16)
    }
}

/// Loads and z-scores every sample of `ds` (a second streaming pass over its simulation
/// files; the parameters are those the index pass read).
pub fn prepare(ds: &Dataset, norm: &Normalisation) -> Result<Prepared> {
    let mut b = Builder::new(norm, &ds.layout, ds.t.len(), ds.samples.len())?;
    let wanted: BTreeSet<i64> = ds.samples.iter().map(|s| s.id).collect();
    scan(
        &ds.info,
        &ds.params,
        &ds.simulation_files,
        None,
        &ds.window,
        &|id, _| wanted.contains(&id),
        &mut |s, _, w| {
            if wanted.contains(&s.id) {
                b.add(s, w)?;
            }
            Ok(())
        },
    )?;
    Ok(b.finish(ds))
}

/// Reads and z-scores (with `norm`, a model's statistics) only the samples of `split`, in one
/// streaming pass: the dataset of that split and its prepared samples, index for index.
pub fn load_split(
    info: &DatasetInfo,
    params_file: &Path,
    simulation_files: &[PathBuf],
    window: &WindowConfig,
    split: Split,
    norm: &Normalisation,
) -> Result<(Dataset, Prepared)> {
    let layout = info.layout();
    let params = ParamsTable::read(params_file, &info.system)?;
    let expected = params.by_id.values().filter(|(s, _)| *s == split).count();
    let mut builder: Option<Builder> = None;
    let ds = scan(
        info,
        &params,
        simulation_files,
        None,
        window,
        &|_, s| s == split,
        &mut |s, t, w| {
            if builder.is_none() {
                builder = Some(Builder::new(norm, layout, t.len(), expected)?);
            }
            builder.as_mut().expect("created").add(s, w)
        },
    )?;
    let b = match builder {
        Some(b) => b,
        None => Builder::new(norm, layout, ds.t.len(), 0)?,
    };
    let items = b.finish(&ds);
    Ok((ds, items))
}
