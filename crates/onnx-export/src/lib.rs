//! A trained surrogate as one self-contained ONNX file (`docs/export.md`): the network, its
//! prediction in physical units, the description's indices, the calibrated intervals at the
//! levels the calibration supports and the training-range flag, as one graph of standard
//! operators that ONNX Runtime (or any runtime of opset 13, or 17 for the `DFT` form) runs
//! without this product.
//!
//! A surrogate is a list of members (trained models, each with its own calibration); every
//! output quantity is taken from the member routed to it. A single model is a surrogate of
//! one member. Inputs: `parameters [B, P]` (the sampled parameters in the description's units
//! and order) and `excitation [B, T, E]` (the profile under each moving point on the model's
//! time grid, and its rate where the model reads one; the recipe is in the metadata,
//! [`recipe`]), both double. Outputs ([`outputs`]): `channels`, `indices`, their intervals,
//! `verdicts`, `outside_training_range`, `extrapolated`.
//!
//! Modules: [`proto`] (the protobuf messages, hand-encoded), [`graph`] (a graph builder),
//! [`expr`] (the description's expressions per design), [`network`] (the FNO), [`dft`] (its
//! truncated DFT as fixed matrices), [`member`]
//! (one model's prediction, channels and index inputs), [`indices`], [`intervals`],
//! [`recipe`] (the excitation's description), [`outputs`] (assembly and metadata).
#![warn(missing_docs)]

pub mod dft;
pub mod expr;
pub mod graph;
pub mod indices;
pub mod intervals;
pub mod member;
pub mod network;
pub mod outputs;
pub mod proto;
pub mod recipe;

pub use network::Spectral;
pub use outputs::{build, Exported, Summary};

use pino_calibration::Normaliser;
use std::path::{Path, PathBuf};

/// What can go wrong; every message names the file, layer, index or value at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Loading the model or its calibration failed.
    #[error(transparent)]
    Eval(#[from] pino_outputs::Error),
    /// The learning engine refused the model.
    #[error(transparent)]
    Learn(#[from] pino_learn::Error),
    /// Something the graph cannot express (a layer, an index, a normaliser, a level).
    #[error("cannot export: {0}")]
    Unsupported(String),
    /// Writing the file failed.
    #[error("{path}: {message}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// One model of a surrogate.
#[derive(Debug, Clone, PartialEq)]
pub struct MemberSpec {
    /// Its key (`train[algorithm=5]`; empty: `algorithm-<A>` of its model).
    pub key: String,
    /// The model directory (`model.json`, `model.safetensors`).
    pub model: PathBuf,
    /// Its calibration (a `calibration.json` or the `calibrate` stage's output); `None`:
    /// exported without intervals, and the metadata says so.
    pub calibration: Option<PathBuf>,
}

/// What to export.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportSpec {
    /// The members; the first answers every quantity no route names.
    pub members: Vec<MemberSpec>,
    /// Per index name, the member that answers it.
    pub index_routes: Vec<(String, usize)>,
    /// Per channel name, the member that answers it.
    pub channel_routes: Vec<(String, usize)>,
    /// The spectral layers' form.
    pub spectral: Spectral,
    /// The intervals' normaliser (`None`: the calibration's when the graph can compute it,
    /// else `none`).
    pub normaliser: Option<Normaliser>,
    /// The interval levels (`None`: the calibration's reported levels it supports).
    pub levels: Option<Vec<f64>>,
    /// Only these indices (`None`: every index the graph can compute; one it cannot is an
    /// error naming it).
    pub indices: Option<Vec<String>>,
}

impl ExportSpec {
    /// The surrogate in `dir` (the `surrogate` stage's output): its members, each with its
    /// calibration, the primary first (the channels follow its order), and its routes.
    pub fn surrogate(dir: &Path) -> Result<Self> {
        use pino_surrogate::manifest::Manifest;
        let m = Manifest::load(dir)?;
        let primary = m.primary();
        let mut order: Vec<usize> = (0..m.members.len()).collect();
        order.sort_by_key(|&k| k != primary);
        let members = order
            .iter()
            .map(|&k| {
                let at = Manifest::member_dir(dir, &m.members[k].name);
                MemberSpec {
                    key: m.members[k].name.clone(),
                    calibration: Some(at.join(pino_calibration::CALIBRATION_FILE)),
                    model: at,
                }
            })
            .collect();
        let position = |name: &str| {
            order
                .iter()
                .position(|&k| m.members[k].name == name)
                .unwrap_or(0)
        };
        let routes = |r: &[pino_surrogate::manifest::Route]| {
            r.iter()
                .map(|r| (r.name.clone(), position(&r.member)))
                .collect()
        };
        Ok(Self {
            members,
            index_routes: routes(&m.indices),
            channel_routes: routes(&m.channels),
            ..Self::single(Path::new(""), None)
        })
    }

    /// A single model with its calibration, every default.
    pub fn single(model: &Path, calibration: Option<&Path>) -> Self {
        Self {
            members: vec![MemberSpec {
                key: String::new(),
                model: model.to_owned(),
                calibration: calibration.map(Path::to_owned),
            }],
            index_routes: Vec::new(),
            channel_routes: Vec::new(),
            spectral: Spectral::Matmul,
            normaliser: None,
            levels: None,
            indices: None,
        }
    }
}

/// Builds the graph of `spec` and writes it to `path` atomically (a temporary sibling renamed
/// over it: never a half-written file).
pub fn export(spec: &ExportSpec, path: &Path) -> Result<Summary> {
    let exported = build(spec)?;
    atomic_file::write_atomic(path, &exported.bytes).map_err(|e| Error::Write {
        path: path.to_owned(),
        message: e.source.to_string(),
    })?;
    Ok(exported.summary)
}

/// The `export` stage's parameters (`pipeline.yaml`), also the command line's options.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExportParams {
    /// `matmul` (opset 13, the default) or `dft` (opset 17).
    #[serde(default = "default_spectral")]
    pub spectral: String,
    /// `none` or `error_head` (absent: the calibration's when the graph can compute it, else
    /// `none`).
    #[serde(default)]
    pub normaliser: Option<Normaliser>,
    /// Interval levels (absent: the calibration's reported levels it supports).
    #[serde(default)]
    pub levels: Option<Vec<f64>>,
    /// Only these indices (absent: all the graph can compute).
    #[serde(default)]
    pub indices: Option<Vec<String>>,
    /// Which model, when the input holds several (a matrix of `train`).
    #[serde(default)]
    pub algorithm: Option<i64>,
}

fn default_spectral() -> String {
    Spectral::Matmul.as_str().to_owned()
}

impl ExportParams {
    /// The export of the surrogate in `dir` with these settings.
    pub fn surrogate_spec(&self, dir: &Path) -> Result<ExportSpec> {
        Ok(ExportSpec {
            spectral: Spectral::parse(&self.spectral)?,
            normaliser: self.normaliser,
            levels: self.levels.clone(),
            indices: self.indices.clone(),
            ..ExportSpec::surrogate(dir)?
        })
    }

    /// The export of one of `models` (the one of `algorithm` when there are several) with the
    /// calibration under `calibration`.
    pub fn spec(&self, models: &[PathBuf], calibration: Option<&Path>) -> Result<ExportSpec> {
        let spectral = Spectral::parse(&self.spectral)?;
        let model = match (models, self.algorithm) {
            ([one], None) => one.clone(),
            (_, None) => {
                return Err(Error::Unsupported(format!(
                    "{} models given: name the one to export (`algorithm`)",
                    models.len()
                )))
            }
            (_, Some(a)) => {
                let mut found = None;
                for m in models {
                    if pino_calibration::ModelIdentity::of(m)?.algorithm == a {
                        found = Some(m.clone());
                    }
                }
                found.ok_or_else(|| {
                    Error::Unsupported(format!("no model of algorithm {a} among the inputs"))
                })?
            }
        };
        Ok(ExportSpec {
            spectral,
            normaliser: self.normaliser,
            levels: self.levels.clone(),
            indices: self.indices.clone(),
            ..ExportSpec::single(&model, calibration)
        })
    }
}
