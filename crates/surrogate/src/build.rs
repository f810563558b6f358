//! Building a surrogate (the `surrogate` stage): for every index and every predicted channel,
//! the candidate model with the lowest error on the validation split answers it, with its own
//! calibration (made on the calibration split by `calibrate`, which also recorded the
//! validation errors). The test split plays no part: it scores the surrogate afterwards.
//!
//! The error compared is the mean relative error (%): an index's `|y - f| / |y|`, a channel's
//! relative L2 error over its curve; where some candidate has none defined (every exact value
//! zero), the mean absolute error. Ties go to the earlier candidate.

use super::manifest::{
    file_blake3, Candidate, Manifest, Member, Route, MEMBER_FILES, SURROGATE_FORMAT,
};
use crate::Error;
use crate::Result;
use pino_calibration::scored::band_channels;
use pino_calibration::{Calibration, ModelIdentity, QuantityScores, ValidationError};
use pino_data::{Column, Table};
use pino_learn::checkpoint::{ModelMeta, MODEL_META};
use pino_learn::Error as LearnError;
use pino_outputs::channels::{prediction_channels, ChannelSource};
use report::csv::write_csv;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One candidate: its model directory, identity, metadata and calibration.
struct Loaded {
    dir: PathBuf,
    name: String,
    identity: ModelIdentity,
    meta: ModelMeta,
    calibration: Calibration,
    calibration_file: PathBuf,
}

/// A quantity of one candidate: its unit and validation error.
struct Scored<'a> {
    unit: &'a str,
    error: ValidationError,
}

/// Builds the surrogate of `candidates` (model directories, in order of preference on ties)
/// with their calibrations found under `calibrations` (the `calibrate` stage's output) and
/// writes it into `out`; returns its manifest.
pub fn build(candidates: &[PathBuf], calibrations: &Path, out: &Path) -> Result<Manifest> {
    if candidates.is_empty() {
        return Err(LearnError::OutOfRange {
            field: "candidates".into(),
            value: "[]".into(),
            allowed: "at least one trained model (wire the training stages to `candidates`)".into(),
        }
        .into());
    }
    let loaded = load_candidates(candidates, calibrations)?;
    let first = &loaded[0];
    let indices = route_indices(&loaded)?;
    let channels = route_channels(&loaded)?;
    let chosen: Vec<&Loaded> = loaded
        .iter()
        .filter(|c| indices.iter().chain(&channels).any(|r| r.member == c.name))
        .collect();
    let mut members = Vec::with_capacity(chosen.len());
    for c in chosen {
        let at = Manifest::member_dir(out, &c.name);
        std::fs::create_dir_all(&at).map_err(|e| LearnError::Io {
            path: at.clone(),
            source: e,
        })?;
        for (file, from) in MEMBER_FILES.iter().zip([
            c.dir.join(MODEL_META),
            c.dir.join(pino_calibration::MODEL_WEIGHTS),
            c.calibration_file.clone(),
        ]) {
            let bytes = std::fs::read(&from).map_err(|e| LearnError::Io {
                path: from.clone(),
                source: e,
            })?;
            atomic_file::write_atomic(&at.join(file), &bytes)?;
        }
        members.push(Member {
            name: c.name.clone(),
            model: c.identity.clone(),
            calibration_blake3: file_blake3(&at.join(pino_calibration::CALIBRATION_FILE))?,
        });
    }
    let manifest = Manifest {
        format: SURROGATE_FORMAT.into(),
        system: first.identity.system.clone(),
        design: first.calibration.design.clone(),
        n_validation: first.calibration.n_fit,
        candidates: loaded
            .iter()
            .map(|c| Candidate {
                name: c.name.clone(),
                model: c.identity.clone(),
            })
            .collect(),
        members,
        indices,
        channels,
    };
    manifest.write(out)?;
    write_routes(out, &manifest)?;
    Ok(manifest)
}

/// Every candidate with its calibration, checked to be of one system and one dataset design,
/// named by its label (made unique with its hash).
fn load_candidates(candidates: &[PathBuf], calibrations: &Path) -> Result<Vec<Loaded>> {
    let mut loaded: Vec<Loaded> = Vec::with_capacity(candidates.len());
    for dir in candidates {
        let identity = ModelIdentity::of(dir)?;
        let meta_path = dir.join(MODEL_META);
        let meta: ModelMeta =
            serde_json::from_str(&std::fs::read_to_string(&meta_path).map_err(|e| {
                LearnError::Io {
                    path: meta_path.clone(),
                    source: e,
                }
            })?)
            .map_err(|e| Error::format(&meta_path, e.to_string()))?;
        let calibration_file = Calibration::find(calibrations, &identity)?;
        let calibration = Calibration::load(&calibration_file, &identity)?;
        if let Some(q) = calibration
            .indices
            .iter()
            .chain(calibration.channels.iter().map(|c| &c.quantity))
            .find(|q| q.validation.is_none())
        {
            return Err(Error::format(
                &calibration_file,
                format!(
                    "the calibration of `{}` records no validation error of `{}` (written by an older `calibrate`): calibrate it again",
                    identity.label(),
                    q.name
                ),
            ));
        }
        if let Some(prev) = loaded.first() {
            same_design(
                prev,
                dir,
                (&identity, &meta),
                &calibration,
                &calibration_file,
            )?;
        }
        if let Some(prev) = loaded.iter().find(|c| c.identity.blake3 == identity.blake3) {
            return Err(Error::format(
                dir,
                format!(
                    "the same model as candidate {} (`{}`): give each model once",
                    prev.dir.display(),
                    prev.name
                ),
            ));
        }
        let taken: Vec<String> = loaded.iter().map(|c| c.name.clone()).collect();
        let name = pino_calibration::build::model_subdir(&identity, &taken);
        loaded.push(Loaded {
            dir: dir.clone(),
            name,
            identity,
            meta,
            calibration,
            calibration_file,
        });
    }
    Ok(loaded)
}

/// A candidate of another system or dataset design than the first is refused, naming both.
fn same_design(
    first: &Loaded,
    dir: &Path,
    (identity, meta): (&ModelIdentity, &ModelMeta),
    calibration: &Calibration,
    file: &Path,
) -> Result<()> {
    let why = if identity.system != first.identity.system {
        Some(format!(
            "a model of system `{}`, the first candidate (`{}`) is of `{}`",
            identity.system, first.name, first.identity.system
        ))
    } else if calibration.design != first.calibration.design {
        Some(format!(
            "calibrated on another dataset design (description or sampling ranges) than the first candidate (`{}`, {}): a surrogate's models come from one dataset",
            first.name,
            first.calibration_file.display()
        ))
    } else if meta.norm.inputs != first.meta.norm.inputs || meta.data != first.meta.data {
        // The inputs' statistics are the training split's: another dataset, other numbers.
        Some(format!(
            "trained on another dataset than the first candidate (`{}`, {}): a surrogate's models come from one dataset",
            first.name,
            first.dir.display()
        ))
    } else if calibration.n != first.calibration.n || calibration.n_fit != first.calibration.n_fit {
        Some(format!(
            "calibrated on {} samples (validation {}), the first candidate (`{}`) on {} (validation {}): calibrate every candidate in one `calibrate` run",
            calibration.n,
            calibration.n_fit,
            first.name,
            first.calibration.n,
            first.calibration.n_fit
        ))
    } else {
        None
    };
    match why {
        Some(why) => Err(Error::format(
            file,
            format!(
                "candidate model {} (`{}`): {why}",
                dir.display(),
                identity.label()
            ),
        )),
        None => Ok(()),
    }
}

/// The candidate with the lowest error among `(name, scored)` (ties: the first) and the route.
fn choose(name: &str, options: &[(&str, Scored<'_>)]) -> Route {
    let relative = options
        .iter()
        .all(|(_, s)| s.error.mean_relative_pct.is_some());
    let metric = |s: &Scored<'_>| {
        if relative {
            s.error.mean_relative_pct.unwrap_or(f64::INFINITY)
        } else {
            s.error.mean_abs
        }
    };
    let mut best = 0;
    for (k, (_, s)) in options.iter().enumerate() {
        // NaN never wins.
        if metric(s) < metric(&options[best].1) || metric(&options[best].1).is_nan() {
            best = k;
        }
    }
    Route {
        name: name.to_owned(),
        unit: options[best].1.unit.to_owned(),
        member: options[best].0.to_owned(),
        validation: options
            .iter()
            .map(|(n, s)| ((*n).to_owned(), metric(s)))
            .collect(),
        metric: if relative {
            "mean_relative_pct"
        } else {
            "mean_abs"
        }
        .into(),
    }
}

/// The route of every index (the first candidate's index order; every candidate calibrates
/// the description's indices, or none when its predictions cannot give them).
fn route_indices(loaded: &[Loaded]) -> Result<Vec<Route>> {
    let names: Vec<&str> = loaded
        .iter()
        .find(|c| !c.calibration.indices.is_empty())
        .map_or(Vec::new(), |c| {
            c.calibration
                .indices
                .iter()
                .map(|q| q.name.as_str())
                .collect()
        });
    names
        .iter()
        .map(|&name| {
            let options: Vec<(&str, Scored<'_>)> = loaded
                .iter()
                .filter_map(|c| {
                    let q = c.calibration.indices.iter().find(|q| q.name == name)?;
                    Some((c.name.as_str(), scored(q)?))
                })
                .collect();
            Ok(choose(name, &options))
        })
        .collect()
}

fn scored(q: &QuantityScores) -> Option<Scored<'_>> {
    Some(Scored {
        unit: &q.unit,
        error: q.validation?,
    })
}

/// The route of every predicted channel (the name a prediction's column has: a rate a model
/// outputs directly answers under the rate's own name), the first candidate's channels first,
/// then channels only later candidates predict; excitations are exact inputs, not routed.
fn route_channels(loaded: &[Loaded]) -> Result<Vec<Route>> {
    // Per candidate: channel name -> its band's scores.
    let per: Vec<BTreeMap<String, &QuantityScores>> = loaded
        .iter()
        .map(|c| {
            let layout = &c.meta.layout;
            let (o, d) = (layout.n_outputs(), layout.n_dofs());
            let bands = band_channels(layout);
            prediction_channels(layout)
                .into_iter()
                .filter_map(|(name, source)| {
                    let band = &bands.get(source.band(o, d)?)?.name;
                    let q = c
                        .calibration
                        .channels
                        .iter()
                        .find(|b| b.quantity.name == *band)?;
                    Some((name, &q.quantity))
                })
                .collect()
        })
        .collect();
    let mut order: Vec<String> = Vec::new();
    for c in loaded {
        for (name, source) in prediction_channels(&c.meta.layout) {
            if !matches!(source, ChannelSource::Excitation(_)) && !order.contains(&name) {
                order.push(name);
            }
        }
    }
    order
        .iter()
        .map(|name| {
            let options: Vec<(&str, Scored<'_>)> = loaded
                .iter()
                .zip(&per)
                .filter_map(|(c, m)| Some((c.name.as_str(), scored(m.get(name)?)?)))
                .collect();
            if options.is_empty() {
                return Err(Error::format(
                    &loaded[0].calibration_file,
                    format!("channel `{name}` has no calibrated band in any candidate"),
                ));
            }
            Ok(choose(name, &options))
        })
        .collect()
}

/// `routes.csv` (one row per quantity and candidate: its validation error, whether chosen) and
/// `routes.md` (one row per quantity: the member and the candidates' errors).
fn write_routes(out: &Path, m: &Manifest) -> Result<()> {
    let names: Vec<&str> = m.candidates.iter().map(|c| c.name.as_str()).collect();
    let mut cols: [Vec<String>; 5] = Default::default();
    let (mut errors, mut chosen) = (Vec::new(), Vec::new());
    let mut md = format!(
        "# Surrogate routes\n\nPer quantity, the model that answers it: the candidate with the lowest error on the validation split ({} samples; mean relative error in %, or mean absolute error where marked). Members: {}.\n\n| kind | quantity | member | {} |\n|---|---|---|{}\n",
        m.n_validation,
        m.members
            .iter()
            .map(|x| format!("`{}`", x.name))
            .collect::<Vec<_>>()
            .join(", "),
        names.join(" | "),
        "---|".repeat(names.len())
    );
    for (kind, routes) in [("index", &m.indices), ("channel", &m.channels)] {
        for r in routes.iter() {
            let mut cells = Vec::with_capacity(names.len());
            for n in &names {
                let v = r.validation.get(*n);
                if let Some(&v) = v {
                    for (col, value) in cols.iter_mut().zip([kind, &r.name, &r.unit, n, &r.metric])
                    {
                        col.push(value.to_owned());
                    }
                    errors.push(v);
                    chosen.push(r.member == *n);
                }
                let cell = match v {
                    Some(v) if r.metric == "mean_abs" => format!("{v:.4} (abs)"),
                    Some(v) => format!("{v:.2}"),
                    None => "-".into(),
                };
                cells.push(if r.member == *n {
                    format!("**{cell}**")
                } else {
                    cell
                });
            }
            md.push_str(&format!(
                "| {kind} | `{}` | `{}` | {} |\n",
                r.name,
                r.member,
                cells.join(" | ")
            ));
        }
    }
    let mut table = Table::default();
    for (name, col) in ["kind", "quantity", "unit", "candidate", "metric"]
        .iter()
        .zip(cols)
    {
        table.push(name, Column::Str(col))?;
    }
    table.push("validation_error", Column::F64(errors))?;
    table.push("chosen", Column::Bool(chosen))?;
    write_csv(&out.join("routes.csv"), &table)?;
    atomic_file::write_atomic(&out.join("routes.md"), md.as_bytes())?;
    Ok(())
}
