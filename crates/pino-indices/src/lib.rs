//! Engineering indices of one vertical vehicle-track record: the few numbers a railway
//! engineer reads off a simulation (`docs/indices.md`).
//!
//! Per sample, over the evaluation window (the record minus its start-up), from the
//! contact forces `P_i` (N), the car-body accelerations `Z_c''` (m/s^2) and `beta_c''`
//! (rad/s^2), the bogie accelerations `Z_t1''`, `Z_t2''` and the rail displacements under the
//! wheels `Z_ri` (m, downward positive):
//!
//! ```text
//! peak wheel-rail force       max_{t,i} P_i(t)                                  kN
//! wheel load reduction rate   max_i (W - min_t P_i(t)) / W    W: static wheel load
//! car-body acceleration       a_centre = Z_c'',  a_front = Z_c'' - l_c beta_c'',
//!                             a_rear = Z_c'' + l_c beta_c'':  peak max_t |a|,  RMS   m/s^2
//! Sperling ride index W_z     of a_centre, a_front, a_rear ([`sperling`])
//! bogie-frame acceleration    max_t |Z_t1''|, max_t |Z_t2''|                     m/s^2
//! rail deflection, peak       max_{t,i} Z_ri(t)                                  mm
//! ```
//!
//! Everything except the Sperling index is a fold of per-sample aggregates ([`Aggregates`]:
//! maxima, minima, sums of squares), so a column engine can compute it in one streaming
//! group-by; [`Indices::from_parts`] turns the aggregates, the three `W_z` and the sample's
//! `W` into the indices. [`compute`] does all of it in plain Rust for one record; the
//! `indices` stage, `evaluate` and `predict` all end in [`Indices::from_parts`].
//!
//! ```
//! use pino_indices::{compute, IndexParams, Record};
//! let n = 1000;
//! let dt = 1e-3;
//! let zero = vec![0.0; n];
//! let p = vec![70e3; n]; // N, a steady wheel load
//! let rec = Record {
//!     dt,
//!     p: [&p, &p, &p, &p],
//!     z_c_a: &zero,
//!     beta_c_a: &zero,
//!     z_t_a: [&zero, &zero],
//!     z_r: [&zero, &zero, &zero, &zero],
//! };
//! let cfg = IndexParams::default().validate()?;
//! let ix = compute(&rec, 9.0, 70e3, &cfg)?;
//! assert_eq!(ix.peak_wheel_rail_force_kn, 70.0);
//! assert_eq!(ix.wheel_load_reduction_rate, 0.0);
//! # Ok::<(), pino_indices::Error>(())
//! ```
#![warn(missing_docs)]

mod config;
pub mod lateral;
pub mod sperling;

pub mod system;

pub use config::{IndexConfig, IndexParams, Limits, SperlingParams, Taper};
pub use lateral::{lateral_indices, LateralParams, LateralRecord, LATERAL_COLUMNS};
pub use system::{column_units, IndexSet, LateralColumns, RailwayColumns};

/// Errors of the index computation; each names the field or signal at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A parameter is outside its allowed range.
    #[error("`{field}` = {value} is out of range: {allowed}")]
    OutOfRange {
        /// The parameter.
        field: String,
        /// Its value, as text.
        value: String,
        /// The allowed range.
        allowed: String,
    },
    /// A signal holds a NaN or an infinity.
    #[error("column `{column}` is not finite at row {row} of the window (value {value})")]
    NotFinite {
        /// The signal's column name.
        column: String,
        /// Row within the evaluation window.
        row: usize,
        /// The value found.
        value: f64,
    },
    /// Two signals of one record differ in length.
    #[error("column `{column}` has {found} rows, column `{reference}` has {expected}")]
    Length {
        /// The signal at fault.
        column: String,
        /// Its length.
        found: usize,
        /// The reference signal.
        reference: String,
        /// Its length.
        expected: usize,
    },
    /// A column an index reads is not available.
    #[error("column `{column}` is not available to the indices")]
    Missing {
        /// The column.
        column: String,
    },
    /// Too few points to compute the indices.
    #[error("{what}: {found} points in the evaluation window, at least {needed} needed")]
    TooShort {
        /// What is short (a record, a Sperling segment).
        what: String,
        /// Points there are.
        found: usize,
        /// Points needed.
        needed: usize,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// Column names of the simulation signals the indices read (the public schema of
/// `pino-data`; repeated here so that this crate depends on nothing of the I/O layer).
pub mod columns {
    /// Contact forces (N).
    pub const P: [&str; 4] = ["p_1", "p_2", "p_3", "p_4"];
    /// Car-body vertical acceleration (m/s^2).
    pub const Z_C_A: &str = "z_c_a";
    /// Car-body pitch acceleration (rad/s^2).
    pub const BETA_C_A: &str = "beta_c_a";
    /// Bogie vertical accelerations, front and rear (m/s^2).
    pub const Z_T_A: [&str; 2] = ["z_t1_a", "z_t2_a"];
    /// Rail displacement under each wheel (m).
    pub const Z_R: [&str; 4] = ["z_r1", "z_r2", "z_r3", "z_r4"];
}

/// One record's signals over its evaluation window, equally long, spacing `dt` (s).
#[derive(Debug, Clone, Copy)]
pub struct Record<'a> {
    /// Time step (s).
    pub dt: f64,
    /// Contact forces `p_1..p_4` (N).
    pub p: [&'a [f64]; 4],
    /// Car-body vertical acceleration `z_c_a` (m/s^2).
    pub z_c_a: &'a [f64],
    /// Car-body pitch acceleration `beta_c_a` (rad/s^2).
    pub beta_c_a: &'a [f64],
    /// Bogie vertical accelerations `z_t1_a`, `z_t2_a` (m/s^2).
    pub z_t_a: [&'a [f64]; 2],
    /// Rail displacements under the wheels `z_r1..z_r4` (m, downward positive).
    pub z_r: [&'a [f64]; 4],
}

impl<'a> Record<'a> {
    /// The signals with their column names.
    pub fn signals(&self) -> Vec<(&'static str, &'a [f64])> {
        let mut s: Vec<(&'static str, &'a [f64])> = Vec::with_capacity(12);
        s.extend(columns::P.iter().copied().zip(self.p));
        s.push((columns::Z_C_A, self.z_c_a));
        s.push((columns::BETA_C_A, self.beta_c_a));
        s.extend(columns::Z_T_A.iter().copied().zip(self.z_t_a));
        s.extend(columns::Z_R.iter().copied().zip(self.z_r));
        s
    }

    /// Number of points; an error when the signals differ in length.
    pub fn len(&self) -> Result<usize> {
        let n = self.z_c_a.len();
        for (name, s) in self.signals() {
            if s.len() != n {
                return Err(Error::Length {
                    column: name.to_owned(),
                    found: s.len(),
                    reference: columns::Z_C_A.to_owned(),
                    expected: n,
                });
            }
        }
        Ok(n)
    }

    /// Whether the record has no points.
    pub fn is_empty(&self) -> bool {
        self.z_c_a.is_empty()
    }

    /// The record from point `first` on (the evaluation window of a full record).
    pub fn tail(&self, first: usize) -> Record<'a> {
        let cut = |s: &'a [f64]| &s[first.min(s.len())..];
        Record {
            dt: self.dt,
            p: self.p.map(cut),
            z_c_a: cut(self.z_c_a),
            beta_c_a: cut(self.beta_c_a),
            z_t_a: self.z_t_a.map(cut),
            z_r: self.z_r.map(cut),
        }
    }

    /// Checks that every value is finite; the error names the column and the row.
    pub fn check_finite(&self) -> Result<()> {
        self.signals()
            .into_iter()
            .try_for_each(|(name, s)| check_finite_signal(name, s))
    }

    /// The three car-body signals of this record ([`car_body_signals`]).
    pub fn car_body(&self, l_c: f64) -> [Vec<f64>; 3] {
        car_body_signals(self.z_c_a, self.beta_c_a, l_c)
    }
}

/// The three car-body signals `a_centre, a_front, a_rear` (m/s^2) for half bogie-centre
/// distance `l_c` (m): `Z_c''`, `Z_c'' - l_c beta_c''`, `Z_c'' + l_c beta_c''` (the front
/// bogie sits at `+l_c`, pitch positive nose-up, displacements downward).
pub fn car_body_signals(z_c_a: &[f64], beta_c_a: &[f64], l_c: f64) -> [Vec<f64>; 3] {
    let zb = z_c_a.iter().zip(beta_c_a);
    [
        z_c_a.to_vec(),
        zb.clone().map(|(z, b)| z - l_c * b).collect(),
        zb.map(|(z, b)| z + l_c * b).collect(),
    ]
}

/// Checks that every value of the signal `column` is finite; the error names the column, the
/// first offending row (counted from the slice's start) and its value.
pub fn check_finite_signal(column: &str, values: &[f64]) -> Result<()> {
    match values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        Some((row, &value)) => Err(Error::NotFinite {
            column: column.to_owned(),
            row,
            value,
        }),
        None => Ok(()),
    }
}

/// Per-sample aggregates of a record: everything the indices need except the spectra.
/// Units as the signals (N, m/s^2, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aggregates {
    /// Points in the window.
    pub n: usize,
    /// `max_t P_i` per wheel (N).
    pub p_max: [f64; 4],
    /// `min_t P_i` per wheel (N).
    pub p_min: [f64; 4],
    /// `max_t |a|` of the car body at centre, front, rear (m/s^2).
    pub car_body_abs_max: [f64; 3],
    /// `sum_t a^2` of the car body at centre, front, rear ((m/s^2)^2).
    pub car_body_sum_sq: [f64; 3],
    /// `max_t |Z_t1''|`, `max_t |Z_t2''|` (m/s^2).
    pub bogie_abs_max: [f64; 2],
    /// `max_t Z_ri` per wheel (m).
    pub z_r_max: [f64; 4],
}

impl Aggregates {
    /// The plain-Rust fold over one record's window (`l_c` in m, for the front and rear
    /// car-body signals). The record must be non-empty and finite ([`Record::check_finite`]).
    pub fn fold(rec: &Record, l_c: f64) -> Result<Self> {
        let n = rec.len()?;
        if n == 0 {
            return Err(Error::TooShort {
                what: "record".into(),
                found: 0,
                needed: 1,
            });
        }
        let max = |s: &[f64]| s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = |s: &[f64]| s.iter().copied().fold(f64::INFINITY, f64::min);
        let (car_body_abs_max, car_body_sum_sq) = car_body_folds(&rec.car_body(l_c));
        Ok(Self {
            n,
            p_max: rec.p.map(max),
            p_min: rec.p.map(min),
            car_body_abs_max,
            car_body_sum_sq,
            bogie_abs_max: rec.z_t_a.map(abs_max),
            z_r_max: rec.z_r.map(max),
        })
    }
}

/// `max_t |x|` of a signal (0 for an empty one).
pub fn abs_max(s: &[f64]) -> f64 {
    s.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

/// `(max_t |a|, sum_t a^2)` of each of the three [`car_body_signals`], summed in time order
/// (so the result does not depend on how the work is split).
pub fn car_body_folds(car: &[Vec<f64>; 3]) -> ([f64; 3], [f64; 3]) {
    let sum_sq = |s: &[f64]| s.iter().map(|v| v * v).sum::<f64>();
    (
        std::array::from_fn(|k| abs_max(&car[k])),
        std::array::from_fn(|k| sum_sq(&car[k])),
    )
}

/// Description of one index column: name (snake_case, unit suffix), unit, meaning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexColumn {
    /// Column name in every artifact.
    pub name: &'static str,
    /// Unit (`-` when dimensionless).
    pub unit: &'static str,
    /// One line of definition.
    pub definition: &'static str,
}

/// The index columns, in [`Indices::values`] order.
pub const INDEX_COLUMNS: [IndexColumn; 14] = [
    IndexColumn {
        name: "peak_wheel_rail_force_kn",
        unit: "kN",
        definition: "max over t and the 4 wheels of p_i",
    },
    IndexColumn {
        name: "wheel_load_reduction_rate",
        unit: "1",
        definition: "max over wheels of (W - min_t p_i) / W, W the static wheel load",
    },
    IndexColumn {
        name: "car_body_acc_peak_centre_ms2",
        unit: "m/s^2",
        definition: "max_t |z_c''|",
    },
    IndexColumn {
        name: "car_body_acc_peak_front_ms2",
        unit: "m/s^2",
        definition: "max_t |z_c'' - l_c beta_c''| (above the front bogie)",
    },
    IndexColumn {
        name: "car_body_acc_peak_rear_ms2",
        unit: "m/s^2",
        definition: "max_t |z_c'' + l_c beta_c''| (above the rear bogie)",
    },
    IndexColumn {
        name: "car_body_acc_rms_centre_ms2",
        unit: "m/s^2",
        definition: "RMS over t of z_c''",
    },
    IndexColumn {
        name: "car_body_acc_rms_front_ms2",
        unit: "m/s^2",
        definition: "RMS over t of z_c'' - l_c beta_c''",
    },
    IndexColumn {
        name: "car_body_acc_rms_rear_ms2",
        unit: "m/s^2",
        definition: "RMS over t of z_c'' + l_c beta_c''",
    },
    IndexColumn {
        name: "sperling_wz_centre",
        unit: "1",
        definition: "Sperling ride index W_z (vertical) of z_c''",
    },
    IndexColumn {
        name: "sperling_wz_front",
        unit: "1",
        definition: "Sperling ride index W_z of z_c'' - l_c beta_c''",
    },
    IndexColumn {
        name: "sperling_wz_rear",
        unit: "1",
        definition: "Sperling ride index W_z of z_c'' + l_c beta_c''",
    },
    IndexColumn {
        name: "bogie_acc_peak_front_ms2",
        unit: "m/s^2",
        definition: "max_t |z_t1''|",
    },
    IndexColumn {
        name: "bogie_acc_peak_rear_ms2",
        unit: "m/s^2",
        definition: "max_t |z_t2''|",
    },
    IndexColumn {
        name: "rail_deflection_peak_mm",
        unit: "mm",
        definition: "max over t and the 4 wheels of z_ri (downward positive)",
    },
];

/// Column of the evaluation window's length (s) written beside the indices.
pub const WINDOW_COLUMN: &str = "window_s";
/// Boolean column: true when every configured limit holds.
pub const PASS_COLUMN: &str = "pass";
/// Column naming the failed limits, comma-separated (null when all pass).
pub const FAILED_COLUMN: &str = "failed";

/// The indices of one sample (units in the field names).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Indices {
    /// `max_{t,i} P_i` (kN).
    pub peak_wheel_rail_force_kn: f64,
    /// `max_i (W - min_t P_i) / W` (-).
    pub wheel_load_reduction_rate: f64,
    /// Car-body peak `max_t |a|` at centre, front, rear (m/s^2).
    pub car_body_acc_peak_ms2: [f64; 3],
    /// Car-body RMS at centre, front, rear (m/s^2).
    pub car_body_acc_rms_ms2: [f64; 3],
    /// Sperling `W_z` at centre, front, rear (-).
    pub sperling_wz: [f64; 3],
    /// Bogie-frame peak `max_t |Z_t''|`, front and rear (m/s^2).
    pub bogie_acc_peak_ms2: [f64; 2],
    /// `max_{t,i} Z_ri` (mm).
    pub rail_deflection_peak_mm: f64,
    /// Length of the evaluation window (s): points times `dt`.
    pub window_s: f64,
}

impl Indices {
    /// The indices from a record's aggregates, its three Sperling indices (centre, front,
    /// rear), its static wheel load `w` (N) and time step `dt` (s).
    pub fn from_parts(agg: &Aggregates, sperling_wz: [f64; 3], w: f64, dt: f64) -> Self {
        let p_max = agg.p_max.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let p_min = agg.p_min.iter().copied().fold(f64::INFINITY, f64::min);
        let n = agg.n.max(1) as f64;
        Self {
            peak_wheel_rail_force_kn: 1e-3 * p_max,
            // max_i (W - min_t P_i) / W = (W - min_{t,i} P_i) / W.
            wheel_load_reduction_rate: (w - p_min) / w,
            car_body_acc_peak_ms2: agg.car_body_abs_max,
            car_body_acc_rms_ms2: agg.car_body_sum_sq.map(|s| (s / n).sqrt()),
            sperling_wz,
            bogie_acc_peak_ms2: agg.bogie_abs_max,
            rail_deflection_peak_mm: 1e3
                * agg
                    .z_r_max
                    .iter()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max),
            window_s: agg.n as f64 * dt,
        }
    }

    /// The values in [`INDEX_COLUMNS`] order.
    pub fn values(&self) -> [f64; 14] {
        let [pc, pf, pr] = self.car_body_acc_peak_ms2;
        let [rc, rf, rr] = self.car_body_acc_rms_ms2;
        let [sc, sf, sr] = self.sperling_wz;
        let [bf, br] = self.bogie_acc_peak_ms2;
        [
            self.peak_wheel_rail_force_kn,
            self.wheel_load_reduction_rate,
            pc,
            pf,
            pr,
            rc,
            rf,
            rr,
            sc,
            sf,
            sr,
            bf,
            br,
            self.rail_deflection_peak_mm,
        ]
    }
}

/// The plain-Rust path for one record's evaluation window: finite check, [`Aggregates::fold`],
/// the Sperling index of the three car-body signals, [`Indices::from_parts`]. `l_c` (m) the
/// half bogie-centre distance, `w` (N) the static wheel load.
pub fn compute(rec: &Record, l_c: f64, w: f64, cfg: &IndexConfig) -> Result<Indices> {
    rec.check_finite()?;
    let agg = Aggregates::fold(rec, l_c)?;
    let wz = sperling_of_record(rec, l_c, cfg)?;
    Ok(Indices::from_parts(&agg, wz, w, rec.dt))
}

/// The Sperling index of the car body at centre, front and rear.
pub fn sperling_of_record(rec: &Record, l_c: f64, cfg: &IndexConfig) -> Result<[f64; 3]> {
    sperling_of_car_body(rec.z_c_a, rec.beta_c_a, l_c, rec.dt, cfg)
}

/// The Sperling index of [`car_body_signals`] (centre, front, rear), sampled every `dt` s.
pub fn sperling_of_car_body(
    z_c_a: &[f64],
    beta_c_a: &[f64],
    l_c: f64,
    dt: f64,
    cfg: &IndexConfig,
) -> Result<[f64; 3]> {
    let car = car_body_signals(z_c_a, beta_c_a, l_c);
    let mut out = [0.0; 3];
    for (o, a) in out.iter_mut().zip(&car) {
        *o = sperling::sperling_wz(a, dt, &cfg.sperling)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
