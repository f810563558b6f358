//! Model files and training checkpoints: safetensors for tensors, a JSON sidecar for the rest.
//!
//! - `model.safetensors` (the parameters, f32, names of [`crate::model::parameter_shapes`]) +
//!   `model.json` ([`ModelMeta`]: model and training configuration, window and time grid,
//!   normalisation statistics) is what `evaluate` and `predict` load.
//! - `checkpoint.safetensors` (`param.NAME`, `adam_m.NAME`, `adam_v.NAME`) +
//!   `checkpoint.json` ([`ModelMeta`] plus [`TrainState`]: epochs done, optimizer step, loss
//!   history) is written after every epoch; training resumes from it bit for bit.
//!
//! Every file is written atomically (temporary file, fsync, rename); the JSON sidecar is
//! written last, so a JSON file always describes a complete tensor file.

use crate::config::{ModelConfig, TrainConfig, WindowConfig};
use crate::model::Fno;
use crate::norm::Normalisation;
use crate::optim::Adam;
use crate::spectral::Transform;
use crate::{io_err, write_atomic, Error, Result};
use candle_core::{Device, Tensor};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::Path;

/// Format tag of `model.json`.
pub const MODEL_FORMAT: &str = "pino-mbd-fno";
/// Model weights file name.
pub const MODEL_WEIGHTS: &str = "model.safetensors";
/// Model sidecar file name.
pub const MODEL_META: &str = "model.json";
/// Checkpoint tensor file name.
pub const CHECKPOINT_TENSORS: &str = "checkpoint.safetensors";
/// Checkpoint sidecar file name.
pub const CHECKPOINT_META: &str = "checkpoint.json";

/// The time grid the model was trained on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeGrid {
    /// First time of the window (s).
    pub t0: f64,
    /// Spacing (s).
    pub dt: f64,
    /// Number of points `T`.
    pub t_points: usize,
    /// Length of the full records the window was cut from (points, before striding).
    pub record_points: usize,
}

impl TimeGrid {
    /// The window's times.
    pub fn times(&self) -> Vec<f64> {
        (0..self.t_points)
            .map(|k| self.t0 + k as f64 * self.dt)
            .collect()
    }
}

/// Everything about a model except its tensors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelMeta {
    /// [`MODEL_FORMAT`].
    pub format: String,
    /// Sizes.
    pub model: ModelConfig,
    /// Algorithm, loss weights and optimiser settings it was trained with.
    pub train: TrainConfig,
    /// Window of the records.
    pub window: WindowConfig,
    /// Time grid.
    pub grid: TimeGrid,
    /// Z-score statistics (training split).
    pub norm: Normalisation,
    /// Force scale of the global ODE loss (N).
    pub f_ref: f64,
    /// Training samples seen per epoch.
    pub train_samples: usize,
}

/// One epoch of the loss history.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HistoryRow {
    /// Epoch (1-based).
    pub epoch: usize,
    /// Optimizer steps after it.
    pub step: u64,
    /// Learning rate used.
    pub lr: f64,
    /// Mean total loss over the epoch's batches.
    pub loss_total: f64,
    /// Mean `L_data`.
    pub loss_data: f64,
    /// Mean `L_deriv` (0 unless algorithm 4/5).
    pub loss_deriv: f64,
    /// Mean ODE loss (0 unless algorithm 2/3).
    pub loss_ode: f64,
    /// Validation relative L2 of solutions (fraction).
    pub val_solution: f64,
    /// Validation relative L2 of first derivatives.
    pub val_first: f64,
    /// Validation relative L2 of second derivatives.
    pub val_second: f64,
}

/// Training progress stored in a checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainState {
    /// Completed epochs.
    pub epochs_done: usize,
    /// Optimizer steps taken.
    pub step: u64,
    /// History so far.
    pub history: Vec<HistoryRow>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CheckpointJson {
    meta: ModelMeta,
    state: TrainState,
}

fn save_tensors(path: &Path, tensors: &HashMap<String, Tensor>) -> Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    candle_core::safetensors::save(tensors, &tmp)?;
    let f = std::fs::File::open(&tmp).map_err(|e| io_err(&tmp, e))?;
    f.sync_all().map_err(|e| io_err(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| io_err(path, e))
}

fn load_tensors(path: &Path, device: &Device) -> Result<HashMap<String, Tensor>> {
    if !path.is_file() {
        return Err(io_err(
            path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        ));
    }
    candle_core::safetensors::load(path, device).map_err(|e| Error::Format {
        path: path.to_owned(),
        message: format!("not a readable safetensors file: {e}"),
    })
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value).map_err(|e| Error::Format {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    write_atomic(path, text.as_bytes())
}

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| io_err(path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::Format {
        path: path.to_owned(),
        message: e.to_string(),
    })
}

/// Writes `model.safetensors` and `model.json` into `dir`.
pub fn save_model(dir: &Path, model: &Fno, meta: &ModelMeta) -> Result<()> {
    save_tensors(&dir.join(MODEL_WEIGHTS), &model.tensors())?;
    write_json(&dir.join(MODEL_META), meta)
}

/// Loads a model directory, checking that the tensors fit the configuration in `model.json`.
pub fn load_model(dir: &Path, transform: Transform, device: &Device) -> Result<(Fno, ModelMeta)> {
    let meta_path = dir.join(MODEL_META);
    let meta: ModelMeta = read_json(&meta_path)?;
    if meta.format != MODEL_FORMAT {
        return Err(Error::Format {
            path: meta_path,
            message: format!("format `{}`, expected `{MODEL_FORMAT}`", meta.format),
        });
    }
    let weights = dir.join(MODEL_WEIGHTS);
    let tensors = load_tensors(&weights, device)?;
    let model = Fno::from_tensors(
        meta.model,
        meta.grid.t_points,
        &tensors,
        transform,
        &weights,
        device,
    )?;
    Ok((model, meta))
}

/// Writes a checkpoint (tensors first, then the sidecar).
pub fn save_checkpoint(
    dir: &Path,
    model: &Fno,
    adam: &Adam,
    meta: &ModelMeta,
    state: &TrainState,
) -> Result<()> {
    let mut tensors = HashMap::new();
    for (i, (name, var)) in model.vars().iter().enumerate() {
        tensors.insert(format!("param.{name}"), var.as_tensor().clone());
        tensors.insert(format!("adam_m.{name}"), adam.m[i].clone());
        tensors.insert(format!("adam_v.{name}"), adam.v[i].clone());
    }
    save_tensors(&dir.join(CHECKPOINT_TENSORS), &tensors)?;
    write_json(
        &dir.join(CHECKPOINT_META),
        &CheckpointJson {
            meta: meta.clone(),
            state: state.clone(),
        },
    )
}

/// Whether `dir` holds a checkpoint.
pub fn has_checkpoint(dir: &Path) -> bool {
    dir.join(CHECKPOINT_META).is_file() && dir.join(CHECKPOINT_TENSORS).is_file()
}

/// Loads a checkpoint: model, optimizer, metadata and state.
pub fn load_checkpoint(
    dir: &Path,
    transform: Transform,
    device: &Device,
) -> Result<(Fno, Adam, ModelMeta, TrainState)> {
    let json: CheckpointJson = read_json(&dir.join(CHECKPOINT_META))?;
    let path = dir.join(CHECKPOINT_TENSORS);
    let all = load_tensors(&path, device)?;
    let pick = |prefix: &str| -> HashMap<String, Tensor> {
        all.iter()
            .filter_map(|(k, v)| k.strip_prefix(prefix).map(|n| (n.to_owned(), v.clone())))
            .collect()
    };
    let model = Fno::from_tensors(
        json.meta.model,
        json.meta.grid.t_points,
        &pick("param."),
        transform,
        &path,
        device,
    )?;
    let mut adam = Adam::new(model.vars())?;
    let (m, v) = (pick("adam_m."), pick("adam_v."));
    for (i, (name, var)) in model.vars().iter().enumerate() {
        for (store, slot) in [(&m, &mut adam.m[i]), (&v, &mut adam.v[i])] {
            let t = store.get(name).ok_or_else(|| Error::ModelMismatch {
                path: path.clone(),
                tensor: format!("adam moment of {name}"),
                found: vec![],
                expected: var.dims().to_vec(),
                config: json.meta.model.to_string(),
            })?;
            if t.dims() != var.dims() {
                return Err(Error::ModelMismatch {
                    path: path.clone(),
                    tensor: format!("adam moment of {name}"),
                    found: t.dims().to_vec(),
                    expected: var.dims().to_vec(),
                    config: json.meta.model.to_string(),
                });
            }
            *slot = t.clone();
        }
    }
    adam.step = json.state.step;
    Ok((model, adam, json.meta, json.state))
}
