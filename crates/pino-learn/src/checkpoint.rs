//! Model files and training checkpoints: safetensors for tensors, a JSON sidecar for the rest.
//!
//! - `model.safetensors` (the parameters, f32, names of [`crate::model::parameter_shapes`]) +
//!   `model.json` ([`ModelMeta`]: model and training configuration, window and time grid,
//!   normalisation statistics, the channel layout, the system description it was trained on
//!   and how its data were simulated) is what `evaluate`, `predict` and `explore` load: a model
//!   directory is self-contained.
//! - `checkpoint.safetensors` (`param.NAME`, `adam_m.NAME`, `adam_v.NAME`) is written after
//!   every epoch; training resumes from it bit for bit. It is self-contained: its safetensors
//!   header metadata (key [`CHECKPOINT_STATE_KEY`]) holds the [`ModelMeta`] and [`TrainState`]
//!   (epochs done, optimizer step, loss history) of exactly these tensors, so the weights and
//!   the state they belong to are replaced together by one atomic rename and can never come
//!   from different epochs. `checkpoint.json` is a readable copy of that state, written
//!   *before* the tensor file and never read on resume (after a crash between the two writes it
//!   may be one epoch ahead of the tensors; resume ignores it).
//!
//! Every file is written atomically ([`atomic_file`]: temporary sibling, fsync, rename).

use crate::config::{ModelConfig, TrainConfig, WindowConfig};
use crate::model::Fno;
use crate::norm::Normalisation;
use crate::optim::{Adam, Average};
use crate::spectral::Transform;
use crate::{io_err, Error, Result};
use candle_core::{Device, Tensor};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::Path;

/// Format tag of `model.json` (version 2: a model of a described system).
pub const MODEL_FORMAT: &str = "pino-mbd-fno-2";
/// The model's file names (kept here under their old path for the crates that load models).
pub use pino_data::artifacts::{MODEL_META, MODEL_WEIGHTS};
/// Checkpoint tensor file name.
pub const CHECKPOINT_TENSORS: &str = "checkpoint.safetensors";
/// Checkpoint sidecar file name (a readable copy; resume reads the tensor file only).
pub const CHECKPOINT_META: &str = "checkpoint.json";
/// Safetensors header metadata key of `checkpoint.safetensors` holding its model metadata and
/// training state (JSON).
pub const CHECKPOINT_STATE_KEY: &str = "pino-mbd.checkpoint";

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

/// How the training data were simulated: the run controls of `simulate` and the profile
/// controls of `irregularity` (what `predict` and `explore` need to make a design's excitation
/// and to solve it exactly).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataSettings {
    /// The simulation's run controls.
    pub run: mbd_engine::RunConfig,
    /// The profile generator's controls, when the description has a generated profile.
    pub profiles: Option<mbd_dataset::ProfileParams>,
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
    /// Force scale of the global ODE loss (N), when the description has one.
    pub f_ref: Option<f64>,
    /// Training samples seen per epoch.
    pub train_samples: usize,
    /// The parameter ranges the model was trained on.
    pub training_ranges: TrainingRanges,
    /// The tensors' channels.
    pub layout: crate::layout::Layout,
    /// The system description (text and overrides) the data were simulated from.
    pub system: mbd_system::SystemSource,
    /// How the data were simulated (absent when the dataset did not say).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<DataSettings>,
}

impl ModelMeta {
    /// The compiled system description.
    pub fn compile_system(&self, path: &Path) -> Result<mbd_system::System> {
        self.system.compile().map_err(|e| Error::Format {
            path: path.to_owned(),
            message: format!("the model's system description: {e}"),
        })
    }
}

/// The sampling range of each sampled parameter a model was trained on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainingRanges {
    /// Where they come from (`system description`: its sampling ranges with the run's
    /// overrides).
    pub source: String,
    /// Parameter names (description order).
    pub names: Vec<String>,
    /// Lower bounds (parameter units).
    pub min: Vec<f64>,
    /// Upper bounds.
    pub max: Vec<f64>,
}

/// One parameter of a design outside its training range.
#[derive(Debug, Clone, PartialEq)]
pub struct OutOfRange {
    /// Parameter name.
    pub name: String,
    /// The design's value.
    pub value: f64,
    /// The training range.
    pub range: [f64; 2],
}

impl std::fmt::Display for OutOfRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} = {} (trained on {} .. {})",
            self.name, self.value, self.range[0], self.range[1]
        )
    }
}

impl TrainingRanges {
    /// The sampling ranges of `system`.
    pub fn of(system: &mbd_system::System) -> Self {
        let ranges = system.ranges();
        Self {
            source: "system description".into(),
            names: system
                .sampled_names()
                .into_iter()
                .map(str::to_owned)
                .collect(),
            min: ranges.iter().map(|r| r[0]).collect(),
            max: ranges.iter().map(|r| r[1]).collect(),
        }
    }

    /// The parameters of `design` outside their training range, read by name, in the ranges'
    /// order; bounds are inclusive, with a relative slack of 1e-9 for values written in
    /// decimal.
    pub fn outside(&self, design: &mbd_system::Sampled) -> Vec<OutOfRange> {
        let mut out = Vec::new();
        for (k, name) in self.names.iter().enumerate() {
            let Some(v) = design.get(name) else {
                continue;
            };
            let (lo, hi) = (self.min[k], self.max[k]);
            let slack = 1e-9 * lo.abs().max(hi.abs());
            if !(v >= lo - slack && v <= hi + slack) {
                out.push(OutOfRange {
                    name: self.names[k].clone(),
                    value: v,
                    range: [lo, hi],
                });
            }
        }
        out
    }
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

/// Writes `tensors` (with optional header metadata) to `path` in one atomic replacement.
fn save_tensors(
    path: &Path,
    tensors: &HashMap<String, Tensor>,
    metadata: Option<HashMap<String, String>>,
) -> Result<()> {
    let bytes = safetensors::serialize(tensors, metadata).map_err(|e| Error::Format {
        path: path.to_owned(),
        message: format!("cannot serialise tensors: {e}"),
    })?;
    Ok(atomic_file::write_atomic(path, &bytes)?)
}

/// Reads a safetensors file: its tensors and its header metadata.
fn load_tensors(
    path: &Path,
    device: &Device,
) -> Result<(HashMap<String, Tensor>, HashMap<String, String>)> {
    let bytes = std::fs::read(path).map_err(|e| io_err(path, e))?;
    let unreadable = |e: &dyn std::fmt::Display| Error::Format {
        path: path.to_owned(),
        message: format!("not a readable safetensors file: {e}"),
    };
    let (_, header) =
        safetensors::SafeTensors::read_metadata(&bytes).map_err(|e| unreadable(&e))?;
    let metadata = header.metadata().clone().unwrap_or_default();
    let tensors =
        candle_core::safetensors::load_buffer(&bytes, device).map_err(|e| unreadable(&e))?;
    Ok((tensors, metadata))
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value).map_err(|e| Error::Format {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    Ok(atomic_file::write_atomic(path, text.as_bytes())?)
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
    save_tensors(&dir.join(MODEL_WEIGHTS), &model.tensors(), None)?;
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
    let (tensors, _) = load_tensors(&weights, device)?;
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

/// Writes a checkpoint: the readable `checkpoint.json` copy, then `checkpoint.safetensors`
/// (tensors and, in its header, the metadata and state), each atomically. The tensor file is
/// the checkpoint; a crash between the two writes leaves the previous one intact.
pub fn save_checkpoint(
    dir: &Path,
    (model, adam, average): (&Fno, &Adam, Option<&Average>),
    meta: &ModelMeta,
    state: &TrainState,
) -> Result<()> {
    let mut tensors = HashMap::new();
    for (i, (name, var)) in model.vars().iter().enumerate() {
        tensors.insert(format!("param.{name}"), var.as_tensor().clone());
        tensors.insert(format!("adam_m.{name}"), adam.m[i].clone());
        tensors.insert(format!("adam_v.{name}"), adam.v[i].clone());
        if let Some(a) = average {
            tensors.insert(format!("average.{name}"), a.values[i].clone());
        }
    }
    let json = CheckpointJson {
        meta: meta.clone(),
        state: state.clone(),
    };
    let path = dir.join(CHECKPOINT_TENSORS);
    let header = serde_json::to_string(&json).map_err(|e| Error::Format {
        path: path.clone(),
        message: e.to_string(),
    })?;
    write_json(&dir.join(CHECKPOINT_META), &json)?;
    save_tensors(
        &path,
        &tensors,
        Some(HashMap::from([(CHECKPOINT_STATE_KEY.to_owned(), header)])),
    )
}

/// Whether `dir` holds a checkpoint (its tensor file; the JSON copy is not needed).
pub fn has_checkpoint(dir: &Path) -> bool {
    dir.join(CHECKPOINT_TENSORS).is_file()
}

/// A checkpoint read back: the model, the optimiser, the weights' average (when the training
/// keeps one), the metadata and the state.
pub type Checkpoint = (Fno, Adam, Option<Average>, ModelMeta, TrainState);

/// Loads a checkpoint: model, optimizer, the weights' average, metadata and state, all from
/// `checkpoint.safetensors` (a file without the state in its header is refused).
pub fn load_checkpoint(dir: &Path, transform: Transform, device: &Device) -> Result<Checkpoint> {
    let path = dir.join(CHECKPOINT_TENSORS);
    let (all, header) = load_tensors(&path, device)?;
    let text = header.get(CHECKPOINT_STATE_KEY).ok_or_else(|| Error::Format {
        path: path.clone(),
        message: format!(
            "no training state in the header (key `{CHECKPOINT_STATE_KEY}`): a checkpoint of an older version; delete it to train from the start"
        ),
    })?;
    let json: CheckpointJson = serde_json::from_str(text).map_err(|e| Error::Format {
        path: path.clone(),
        message: format!("header key `{CHECKPOINT_STATE_KEY}`: {e}"),
    })?;
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
    let mut average = json
        .meta
        .train
        .average_decay
        .map(|d| Average::new(model.vars(), d))
        .transpose()?;
    let (m, v, a) = (pick("adam_m."), pick("adam_v."), pick("average."));
    for (i, (name, var)) in model.vars().iter().enumerate() {
        let mut slots = vec![
            (&m, &mut adam.m[i], "adam moment"),
            (&v, &mut adam.v[i], "adam moment"),
        ];
        if let Some(avg) = average.as_mut() {
            slots.push((&a, &mut avg.values[i], "weights' average"));
        }
        for (store, slot, what) in slots {
            let t = store.get(name).ok_or_else(|| Error::ModelMismatch {
                path: path.clone(),
                tensor: format!("{what} of {name}"),
                found: vec![],
                expected: var.dims().to_vec(),
                config: json.meta.model.to_string().into(),
            })?;
            if t.dims() != var.dims() {
                return Err(Error::ModelMismatch {
                    path: path.clone(),
                    tensor: format!("{what} of {name}"),
                    found: t.dims().to_vec(),
                    expected: var.dims().to_vec(),
                    config: json.meta.model.to_string().into(),
                });
            }
            *slot = t.clone();
        }
    }
    adam.step = json.state.step;
    Ok((model, adam, average, json.meta, json.state))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{TrainParams, WindowConfig};
    use crate::data::Dataset;
    use crate::synthetic::{write_dataset, SyntheticSpec};
    use crate::train::{train, TrainOptions, TrainOutcome};
    use std::path::PathBuf;

    const EPOCHS: usize = 3;

    fn window() -> WindowConfig {
        WindowConfig {
            startup_fraction: 0.1,
            time_stride: 1,
        }
    }

    fn setup(dir: &Path) -> (Dataset, ModelConfig, TrainConfig) {
        let spec = SyntheticSpec {
            n_train: 4,
            n_validation: 2,
            duration: 0.2,
            ..Default::default()
        };
        let ds = write_dataset(&spec, dir)
            .unwrap()
            .load(&window(), true)
            .unwrap();
        let mut p = TrainParams::small(4);
        (p.modes, p.depth) = (6, Some(2));
        (p.epochs, p.learning_rate) = (EPOCHS, 3e-3);
        let (m, t, _) = p.configs(&ds.layout).unwrap();
        (ds, m, t)
    }

    fn run(
        ds: &Dataset,
        m: ModelConfig,
        t: TrainConfig,
        ck: &Path,
        stop: Option<usize>,
    ) -> TrainOutcome {
        let opts = TrainOptions {
            transform: Transform::Matmul,
            checkpoint_dir: ck.to_owned(),
            stop_after_epochs: stop,
        };
        let dev = Device::Cpu;
        train(ds, m, t, window(), &opts, &dev, &mut |_| {}).unwrap()
    }

    fn params(model: &Fno) -> Vec<Vec<f32>> {
        model
            .vars()
            .iter()
            .map(|(_, v)| v.as_tensor().flatten_all().unwrap().to_vec1().unwrap())
            .collect()
    }

    fn fresh(dir: &Path, name: &str) -> PathBuf {
        let d = dir.join(name);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// Both ways a kill can split the two files of one save: the JSON copy of epoch 2 next to
    /// the tensors of epoch 1 (a kill inside this version's save), and the tensors of epoch 2
    /// next to the JSON of epoch 1 (a kill inside the former tensors-then-JSON save, which
    /// resumed epoch-2 weights with epoch-1 state). Resume must take epoch, state and weights
    /// from the tensor file alone and end bit for bit where an uninterrupted run ends.
    #[test]
    fn a_kill_between_the_two_writes_cannot_mix_epochs() {
        let dir = tempfile::tempdir().unwrap();
        let (ds, m, t) = setup(dir.path());
        let reference = run(&ds, m, t, &fresh(dir.path(), "reference"), None);
        assert!(reference.finished);

        let ck = fresh(dir.path(), "ck");
        run(&ds, m, t, &ck, Some(1));
        let json1 = std::fs::read(ck.join(CHECKPOINT_META)).unwrap();
        let tensors1 = std::fs::read(ck.join(CHECKPOINT_TENSORS)).unwrap();
        let after2 = run(&ds, m, t, &ck, Some(2));
        let json2 = std::fs::read(ck.join(CHECKPOINT_META)).unwrap();
        let tensors2 = std::fs::read(ck.join(CHECKPOINT_TENSORS)).unwrap();
        assert_ne!(json1, json2);

        for (case, json, tensors, epoch) in [
            ("json ahead", &json2, &tensors1, 1),
            ("tensors ahead", &json1, &tensors2, 2),
        ] {
            let mixed = fresh(dir.path(), case);
            std::fs::write(mixed.join(CHECKPOINT_META), json).unwrap();
            std::fs::write(mixed.join(CHECKPOINT_TENSORS), tensors).unwrap();
            let (model, adam, _, _, state) =
                load_checkpoint(&mixed, Transform::Matmul, &Device::Cpu).unwrap();
            assert_eq!(state.epochs_done, epoch, "{case}");
            assert_eq!(state.history[..], reference.history[..epoch], "{case}");
            assert_eq!(adam.step, reference.history[epoch - 1].step, "{case}");
            if epoch == 2 {
                assert_eq!(params(&model), params(&after2.model), "{case}");
            }
            let resumed = run(&ds, m, t, &mixed, None);
            assert_eq!(resumed.resumed_after, Some(epoch), "{case}");
            assert_eq!(resumed.history, reference.history, "{case}");
            assert_eq!(params(&resumed.model), params(&reference.model), "{case}");
        }
    }

    /// With a weights' average, a run stopped after an epoch resumes to the uninterrupted
    /// run's history and weights bit for bit; the model kept is the average, not the last
    /// iterate (the same training without it ends elsewhere).
    #[test]
    fn a_weights_average_resumes_exactly_and_is_the_model_kept() {
        let dir = tempfile::tempdir().unwrap();
        let (ds, m, mut t) = setup(dir.path());
        let plain = run(&ds, m, t, &fresh(dir.path(), "plain"), None);
        t.average_decay = Some(0.9);
        let reference = run(&ds, m, t, &fresh(dir.path(), "reference"), None);
        assert!(reference.finished);
        assert_ne!(params(&reference.model), params(&plain.model));
        let ck = fresh(dir.path(), "ck");
        run(&ds, m, t, &ck, Some(1));
        let (_, _, average, _, _) = load_checkpoint(&ck, Transform::Matmul, &Device::Cpu).unwrap();
        assert_eq!(average.map(|a| a.decay), Some(0.9));
        let resumed = run(&ds, m, t, &ck, None);
        assert_eq!(resumed.resumed_after, Some(1));
        assert_eq!(resumed.history, reference.history);
        assert_eq!(params(&resumed.model), params(&reference.model));
    }

    #[test]
    fn a_tensor_file_without_its_state_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let (ds, m, t) = setup(dir.path());
        let ck = fresh(dir.path(), "ck");
        let out = run(&ds, m, t, &ck, Some(1));
        // The former layout: tensors with no state in the header.
        save_tensors(&ck.join(CHECKPOINT_TENSORS), &out.model.tensors(), None).unwrap();
        let err = load_checkpoint(&ck, Transform::Matmul, &Device::Cpu)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(CHECKPOINT_TENSORS) && err.contains(CHECKPOINT_STATE_KEY),
            "{err}"
        );
        // A missing tensor file is no checkpoint, whatever the JSON copy says.
        std::fs::remove_file(ck.join(CHECKPOINT_TENSORS)).unwrap();
        assert!(ck.join(CHECKPOINT_META).is_file() && !has_checkpoint(&ck));
    }
}
