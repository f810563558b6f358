//! The split an evaluation scores ([`EvalData`]) and its samples as models of one window and
//! statistics read them ([`ScoredData`]): loaded once, shared by Table 4, the calibration and
//! the surrogate's report.

use crate::indices_eval::{IndexInputs, StoredColumns};
use crate::Result;
use pino_learn::checkpoint::ModelMeta;
use pino_learn::config::WindowConfig;
use pino_learn::data::{load_split, Dataset, DatasetInfo, Prepared, Split};
use pino_learn::norm::Normalisation;
use std::path::{Path, PathBuf};

/// The dataset an evaluation scores: its records, `params.parquet` and the simulation shards.
#[derive(Debug, Clone, Copy)]
pub struct EvalData<'a> {
    /// The description and run controls the dataset was simulated with.
    pub info: &'a DatasetInfo,
    /// The dataset's `params.parquet` (splits and parameters).
    pub params_file: &'a Path,
    /// Every shard's `simulation.parquet`.
    pub simulation_files: &'a [PathBuf],
}

/// The scored split as models of one (window, statistics) see it: loaded once, shared by
/// every model trained on the same data.
pub struct ScoredData {
    window: WindowConfig,
    norm: Normalisation,
    /// The split's records in the model's window.
    pub ds: Dataset,
    /// The split's samples, normalised with the model's statistics.
    pub items: Prepared,
    /// The stored columns the indices read (empty when the description has none).
    pub stored: StoredColumns,
}

impl ScoredData {
    /// Whether a model with `meta` reads this data.
    pub fn serves(&self, meta: &ModelMeta) -> bool {
        self.window == meta.window && self.norm == meta.norm
    }

    /// Loads `split` of `data` in the window and statistics of `meta`.
    pub fn load(
        data: &EvalData<'_>,
        split: Split,
        meta: &ModelMeta,
        index_inputs: &IndexInputs,
    ) -> Result<Self> {
        let info = data
            .info
            .clone()
            .with_rate_outputs(meta.layout.rate_outputs())?;
        let (ds, items) = load_split(
            &info,
            data.params_file,
            data.simulation_files,
            &meta.window,
            split,
            &meta.norm,
        )?;
        let stored = if index_inputs.computable() {
            let ids = (0..items.len()).map(|i| items.id(i)).collect();
            StoredColumns::read(data.simulation_files, index_inputs, &ids, &meta.window)?
        } else {
            StoredColumns::default()
        };
        Ok(Self {
            window: meta.window,
            norm: meta.norm.clone(),
            ds,
            items,
            stored,
        })
    }
}
