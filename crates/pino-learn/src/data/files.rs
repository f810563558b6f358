//! The dataset's tables besides the simulation: `params.parquet` (split and design per
//! sample) and `weights.parquet` (the ODE magnitude weights), read and checked by name.

use crate::layout::Layout;
use crate::{Error, Result};
use mbd_system::{Sampled, System};
use pino_data::{read_parquet, schema};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mbd_dataset::Split;

/// The message of an unknown split label.
pub(super) fn unknown_split(label: &str) -> String {
    let allowed: Vec<String> = Split::ALL
        .iter()
        .map(|s| format!("`{}`", s.as_str()))
        .collect();
    format!("split `{label}`, allowed {}", allowed.join(", "))
}

pub(super) fn dataset_err(path: &Path, message: String) -> Error {
    Error::Dataset {
        path: path.to_owned(),
        message,
    }
}

/// Reads `params.parquet` ([`pino_data::records::read_params`]): `(sample_id, split, design)`
/// rows, a design of `system` each, each split label known.
pub fn read_params(path: &Path, system: &System) -> Result<Vec<(i64, Split, Sampled)>> {
    let table = pino_data::records::read_params_of(&[path.to_path_buf()], system)?;
    table
        .rows()
        .map(|(id, label, values)| {
            let split = Split::from_label(&label).ok_or_else(|| {
                dataset_err(path, format!("sample {id}: {}", unknown_split(&label)))
            })?;
            Ok((id, split, system.sampled_values(values)?))
        })
        .collect()
}

/// `params.parquet` read once, by sample id: what a streaming pass ([`scan`]) looks each
/// record up in.
#[derive(Debug)]
pub(super) struct ParamsTable {
    /// The file (named in errors).
    pub(super) file: PathBuf,
    /// Split and design per `sample_id`, ids ascending.
    pub(super) by_id: BTreeMap<i64, (Split, Sampled)>,
}

impl ParamsTable {
    /// [`read_params`] of `file`, keyed by sample id.
    pub(super) fn read(file: &Path, system: &System) -> Result<Arc<Self>> {
        let by_id = read_params(file, system)?
            .into_iter()
            .map(|(id, s, p)| (id, (s, p)))
            .collect();
        Ok(Arc::new(Self {
            file: file.to_owned(),
            by_id,
        }))
    }
}

/// Reads `weights.parquet` into `(sample_id, phi)` rows (the `phi_<dof>` of each equation of
/// `layout`); every phi must be finite and > 0.
pub fn read_weights(path: &Path, layout: &Layout) -> Result<Vec<(i64, Vec<f64>)>> {
    let names = layout.phi_columns();
    let mut cols = vec![schema::SAMPLE_ID];
    cols.extend(names.iter().map(String::as_str));
    let t = read_parquet(path, Some(&cols))?;
    let ids = t.i64(schema::SAMPLE_ID)?;
    let phis: Vec<&[f64]> = names
        .iter()
        .map(|n| t.f64(n))
        .collect::<pino_data::Result<_>>()?;
    let mut out = Vec::with_capacity(ids.len());
    for (r, &id) in ids.iter().enumerate() {
        let phi: Vec<f64> = phis.iter().map(|p| p[r]).collect();
        if let Some(i) = phi.iter().position(|p| !(p.is_finite() && *p > 0.0)) {
            return Err(dataset_err(
                path,
                format!(
                    "sample {id}: {} = {} must be finite and > 0",
                    names[i], phi[i]
                ),
            ));
        }
        out.push((id, phi));
    }
    Ok(out)
}

/// The splits present in `params.parquet`, without reading any simulation.
pub fn splits_present(params_file: &Path) -> Result<BTreeSet<Split>> {
    Ok(splits_of(params_file)?.into_iter().collect())
}

/// The split label of every row of `params.parquet`.
pub(super) fn splits_of(params_file: &Path) -> Result<Vec<Split>> {
    pino_data::records::read_params(&[params_file.to_path_buf()], &[])?
        .splits
        .iter()
        .map(|label| {
            Split::from_label(label).ok_or_else(|| dataset_err(params_file, unknown_split(label)))
        })
        .collect()
}
