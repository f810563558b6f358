//! Pass 1 of the scan: the car body's indices of every sample, streamed in plain Rust.
//!
//! Reads `sample_id, t, z_c_a, beta_c_a` batch by batch, gathers whole samples into groups
//! and computes each group in parallel (rayon): the record's checks (contiguous rows, a
//! uniform grid, finite values in the window), its evaluation window and, on the three
//! car-body accelerations (centre, front, rear), the Sperling index (rustfft), the peak and
//! the sum of squares (in time order, so the RMS has the same bits on every run).

use crate::{dataset, Error, Result, SampleInfo};
use pino_data::schema;
use pino_indices::IndexConfig;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What the spectral pass found for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spectral {
    /// Index of its simulation file.
    pub file: usize,
    /// Points of its evaluation window.
    pub n: usize,
    /// Time step (s).
    pub dt: f64,
    /// Time of the first point of the window (s).
    pub t_start: f64,
    /// Sperling `W_z` at the car body's centre, front and rear.
    pub wz: [f64; 3],
    /// `max_t |a|` of the car body at centre, front and rear (m/s^2).
    pub car_abs_max: [f64; 3],
    /// `sum_t a^2` of the same (summed in time order: deterministic).
    pub car_sum_sq: [f64; 3],
}

/// One sample's rows of the spectral columns.
struct Rows {
    id: i64,
    t: Vec<f64>,
    z: Vec<f64>,
    b: Vec<f64>,
}

fn spectral_of(
    r: &Rows,
    l_c: f64,
    cfg: &IndexConfig,
    path: &Path,
    file: usize,
) -> Result<Spectral> {
    let wrap = |source| Error::Index {
        path: path.to_owned(),
        sample: r.id,
        source,
    };
    let n = r.t.len();
    let first = cfg.first_index(n);
    if n < first + 2 {
        return Err(wrap(pino_indices::Error::TooShort {
            what: format!("record of {n} rows, window from row {first}"),
            found: n.saturating_sub(first),
            needed: 2,
        }));
    }
    let dt = r.t[1] - r.t[0];
    let span = r.t[n - 1] - r.t[0];
    if !(dt > 0.0 && (span - (n - 1) as f64 * dt).abs() <= 1e-6 * span) {
        return Err(dataset(
            path,
            format!(
                "sample {}: column `t` is not a uniform grid ({n} rows from {} to {} s, first step {dt} s)",
                r.id,
                r.t[0],
                r.t[n - 1]
            ),
        ));
    }
    for (name, s) in [
        (pino_indices::columns::Z_C_A, &r.z),
        (pino_indices::columns::BETA_C_A, &r.b),
    ] {
        pino_indices::check_finite_signal(name, &s[first..]).map_err(wrap)?;
    }
    let car = pino_indices::car_body_signals(&r.z[first..], &r.b[first..], l_c);
    let (car_abs_max, car_sum_sq) = pino_indices::car_body_folds(&car);
    let mut wz = [0.0; 3];
    for (w, a) in wz.iter_mut().zip(&car) {
        *w = pino_indices::sperling::sperling_wz(a, dt, &cfg.sperling).map_err(wrap)?;
    }
    Ok(Spectral {
        file,
        n: n - first,
        dt,
        t_start: r.t[first],
        wz,
        car_abs_max,
        car_sum_sq,
    })
}

/// Pass 1: every sample's window and Sperling indices, streamed file by file in groups of
/// whole samples (memory: one group plus one batch), groups computed in parallel. Samples
/// must be in `params`, their rows contiguous, and each in one file only.
pub fn spectral_pass(
    files: &[PathBuf],
    params: &BTreeMap<i64, SampleInfo>,
    cfg: &IndexConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<BTreeMap<i64, Spectral>> {
    let cols = [
        schema::SAMPLE_ID,
        schema::TIME,
        pino_indices::columns::Z_C_A,
        pino_indices::columns::BETA_C_A,
    ];
    let group = 32 * rayon::current_num_threads().max(1);
    let mut out: BTreeMap<i64, Spectral> = BTreeMap::new();
    for (fi, path) in files.iter().enumerate() {
        let mut pending: Vec<Rows> = Vec::new();
        let mut current: Option<Rows> = None;
        let mut failure: Option<Error> = None;
        let flush = |pending: &mut Vec<Rows>, out: &mut BTreeMap<i64, Spectral>| -> Result<()> {
            let done: Vec<Result<(i64, Spectral)>> = pending
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
                    let l_c = vtcd::params::SampleParams::from_array(info.params).l_c;
                    let s = spectral_of(r, l_c, cfg, path, fi)?;
                    progress(1);
                    Ok((r.id, s))
                })
                .collect();
            pending.clear();
            for d in done {
                let (id, s) = d?;
                if let Some(prev) = out.insert(id, s) {
                    let msg = if prev.file == fi {
                        format!("rows of sample {id} are not contiguous: expected rows sorted by sample_id, t")
                    } else {
                        format!("sample {id} is also in {}", files[prev.file].display())
                    };
                    return Err(dataset(path, msg));
                }
            }
            Ok(())
        };
        let streamed = pino_data::for_each_batch(path, Some(&cols[..]), |t| {
            let ids = t.i64(schema::SAMPLE_ID)?;
            let (tt, z, b) = (
                t.f64(schema::TIME)?,
                t.f64(pino_indices::columns::Z_C_A)?,
                t.f64(pino_indices::columns::BETA_C_A)?,
            );
            let mut lo = 0;
            while lo < ids.len() {
                let id = ids[lo];
                let hi = (lo..ids.len()).find(|&r| ids[r] != id).unwrap_or(ids.len());
                if current.as_ref().is_some_and(|c| c.id != id) {
                    pending.push(current.take().expect("checked"));
                    if pending.len() >= group {
                        if let Err(e) = flush(&mut pending, &mut out) {
                            failure = Some(e);
                            return Err(pino_data::Error::Parquet {
                                path: path.clone(),
                                message: "stopped".into(),
                            });
                        }
                    }
                }
                let r = current.get_or_insert_with(|| Rows {
                    id,
                    t: Vec::new(),
                    z: Vec::new(),
                    b: Vec::new(),
                });
                r.t.extend_from_slice(&tt[lo..hi]);
                r.z.extend_from_slice(&z[lo..hi]);
                r.b.extend_from_slice(&b[lo..hi]);
                lo = hi;
            }
            Ok(())
        });
        if let Some(e) = failure {
            return Err(e);
        }
        streamed?;
        pending.extend(current.take());
        flush(&mut pending, &mut out)?;
    }
    Ok(out)
}
