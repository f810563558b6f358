//! Pass 1 of the scan: every sample's record, streamed in plain Rust.
//!
//! Reads `t`, the car-body columns of the railway binding (vertical and pitch acceleration)
//! and the channels of the simple indices, one whole sample at a time through the shared
//! record reader ([`pino_data::records::for_each_record`], one file at a time so that a sample
//! met again in another file is named with both files), gathers samples into groups and
//! computes each group in parallel (rayon): the record's checks (a uniform grid, finite values
//! in the window), its evaluation window, and
//!
//! - with a railway binding, on the three car-body accelerations (centre, front, rear, with
//!   the sample's `l_c`): the Sperling index (rustfft), the peak and the sum of squares (in
//!   time order, so the RMS has the same bits on every run);
//! - every simple index `stat(x - subtract) / divide` of its channel over the window
//!   ([`pino_indices::system::simple`], `subtract` and `divide` evaluated on the sample's
//!   parameters).

use crate::{dataset, Error, Result, SampleInfo};
use mbd_system::System;
use pino_data::records::{for_each_record, Record};
use pino_data::schema;
use pino_indices::{IndexConfig, IndexSet};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The car body's part of the railway indices of one sample (centre, front, rear).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CarBody {
    /// Sperling `W_z`.
    pub wz: [f64; 3],
    /// `max_t |a|` (m/s^2).
    pub abs_max: [f64; 3],
    /// `sum_t a^2` (summed in time order: deterministic).
    pub sum_sq: [f64; 3],
}

/// What the record pass found for one sample.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordIndices {
    /// Index of its simulation file.
    pub file: usize,
    /// Points of its evaluation window.
    pub n: usize,
    /// Time step (s).
    pub dt: f64,
    /// Time of the first point of the window (s).
    pub t_start: f64,
    /// The car body's indices, when the railway family is bound.
    pub car_body: Option<CarBody>,
    /// The lateral family's indices, when it is bound (`pino_indices::LATERAL_COLUMNS`).
    pub lateral: Option<[f64; 14]>,
    /// The simple indices, in `System::indices` order.
    pub simple: Vec<f64>,
}

/// Where the lateral binding's signals sit among the columns read.
struct LateralLayout {
    wheels: Vec<(usize, usize)>,
    car_body: [usize; 3],
    stability: usize,
    excitations: Vec<usize>,
}

/// Where each signal of the pass sits among the columns read.
struct Layout {
    /// The columns read besides `sample_id`: `t` first.
    columns: Vec<String>,
    /// Car-body vertical and pitch accelerations (railway binding).
    car_body: Option<(usize, usize)>,
    /// The lateral binding's columns: per wheel `(Y, Q)`, the car body's three, the
    /// stability column, the excitations.
    lateral: Option<LateralLayout>,
    /// Per simple index, its channel's column.
    simple: Vec<usize>,
}

impl Layout {
    fn of(system: &System, set: &IndexSet) -> Self {
        let mut columns = vec![schema::TIME.to_owned()];
        let mut at = |name: &str| match columns.iter().position(|c| c == name) {
            Some(k) => k,
            None => {
                columns.push(name.to_owned());
                columns.len() - 1
            }
        };
        let car_body = set
            .railway
            .as_ref()
            .map(|r| (at(&r.z_c_a), at(&r.beta_c_a)));
        let lateral = set.lateral.as_ref().map(|l| LateralLayout {
            wheels: l.wheels.iter().map(|[y, q]| (at(y), at(q))).collect(),
            car_body: [at(&l.car_body[0]), at(&l.car_body[1]), at(&l.car_body[2])],
            stability: at(&l.stability),
            excitations: l.excitations.iter().map(|e| at(e)).collect(),
        });
        let simple = system
            .indices
            .iter()
            .map(|ix| at(&system.channels[ix.channel].name))
            .collect();
        Self {
            columns,
            car_body,
            lateral,
            simple,
        }
    }
}

fn indices_of(
    r: &Record,
    layout: &Layout,
    system: &System,
    info: &SampleInfo,
    cfg: &IndexConfig,
    path: &Path,
    file: usize,
) -> Result<RecordIndices> {
    let wrap = |source| Error::Index {
        path: path.to_owned(),
        sample: r.id,
        source,
    };
    let t = &r.columns[0];
    let n = t.len();
    let first = cfg.first_row(t);
    if n < first + 2 {
        return Err(wrap(pino_indices::Error::TooShort {
            what: format!("record of {n} rows, window from row {first}"),
            found: n.saturating_sub(first),
            needed: 2,
        }));
    }
    let dt = t[1] - t[0];
    let span = t[n - 1] - t[0];
    if !(dt > 0.0 && (span - (n - 1) as f64 * dt).abs() <= 1e-6 * span) {
        return Err(dataset(
            path,
            format!(
                "sample {}: column `t` is not a uniform grid ({n} rows from {} to {} s, first step {dt} s)",
                r.id,
                t[0],
                t[n - 1]
            ),
        ));
    }
    let car_body = match layout.car_body {
        Some((kz, kb)) => {
            let (z, b) = (&r.columns[kz], &r.columns[kb]);
            for k in [kz, kb] {
                pino_indices::check_finite_signal(&layout.columns[k], &r.columns[k][first..])
                    .map_err(wrap)?;
            }
            let l_c = system
                .railway
                .as_ref()
                .expect("a car body only with a railway binding")
                .half_length
                .eval(&info.values);
            let car = pino_indices::car_body_signals(&z[first..], &b[first..], l_c);
            let (abs_max, sum_sq) = pino_indices::car_body_folds(&car);
            let mut wz = [0.0; 3];
            for (w, a) in wz.iter_mut().zip(&car) {
                *w = pino_indices::sperling::sperling_wz(a, dt, &cfg.sperling).map_err(wrap)?;
            }
            Some(CarBody {
                wz,
                abs_max,
                sum_sq,
            })
        }
        None => None,
    };
    let lateral = match (&layout.lateral, &system.lateral) {
        (Some(l), Some(binding)) => {
            let col = |k: usize| &r.columns[k][first..];
            let rec = pino_indices::LateralRecord {
                dt,
                wheels: l.wheels.iter().map(|&(y, q)| (col(y), col(q))).collect(),
                car_body: l.car_body.map(col),
                stability: col(l.stability),
                excitations: l.excitations.iter().map(|&k| col(k)).collect(),
            };
            let p = pino_indices::system::lateral_params(system, binding, &info.values);
            Some(pino_indices::lateral_indices(&rec, &p, &cfg.sperling).map_err(wrap)?)
        }
        _ => None,
    };
    let mut simple = Vec::with_capacity(layout.simple.len());
    for (ix, &k) in system.indices.iter().zip(&layout.simple) {
        let x = &r.columns[k][first..];
        pino_indices::check_finite_signal(&layout.columns[k], x).map_err(wrap)?;
        simple.push(pino_indices::system::simple(
            ix.stat,
            x,
            ix.subtract.eval(&info.values),
            ix.divide.eval(&info.values),
        ));
    }
    Ok(RecordIndices {
        file,
        n: n - first,
        dt,
        t_start: t[first],
        car_body,
        lateral,
        simple,
    })
}

/// Pass 1: every sample's window, car-body indices (railway binding) and simple indices,
/// streamed file by file in groups of whole samples (memory: one group plus one batch),
/// groups computed in parallel. Samples must be in `params`, their rows contiguous, and each
/// in one file only.
pub fn record_pass(
    files: &[PathBuf],
    system: &System,
    set: &IndexSet,
    params: &BTreeMap<i64, SampleInfo>,
    cfg: &IndexConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<BTreeMap<i64, RecordIndices>> {
    let layout = Layout::of(system, set);
    let cols: Vec<&str> = layout.columns.iter().map(String::as_str).collect();
    let group = 32 * rayon::current_num_threads().max(1);
    let mut out: BTreeMap<i64, RecordIndices> = BTreeMap::new();
    for (fi, path) in files.iter().enumerate() {
        let mut pending: Vec<Record> = Vec::new();
        let flush =
            |pending: &mut Vec<Record>, out: &mut BTreeMap<i64, RecordIndices>| -> Result<()> {
                let done: Vec<Result<(i64, RecordIndices)>> = pending
                    .par_iter()
                    .map(|r| {
                        let info = params.get(&r.id).ok_or_else(|| {
                            dataset(
                                path,
                                format!(
                                "sample {} is not in params.parquet (inputs from different runs?)",
                                r.id
                            ),
                            )
                        })?;
                        let s = indices_of(r, &layout, system, info, cfg, path, fi)?;
                        progress(1);
                        Ok((r.id, s))
                    })
                    .collect();
                pending.clear();
                for d in done {
                    let (id, s) = d?;
                    if let Some(prev) = out.insert(id, s) {
                        // Within one file the record reader refuses interleaved rows itself.
                        return Err(dataset(
                            path,
                            format!("sample {id} is also in {}", files[prev.file].display()),
                        ));
                    }
                }
                Ok(())
            };
        for_each_record::<Error>(std::slice::from_ref(path), &cols, &mut |_, rec| {
            pending.push(rec);
            if pending.len() >= group {
                flush(&mut pending, &mut out)?;
            }
            Ok(())
        })?;
        flush(&mut pending, &mut out)?;
    }
    Ok(out)
}
