//! The indices of a described system: the railway family (this crate's [`crate::compute`]) when
//! the description binds it to its columns (`railway:` in the description), then the
//! description's own simple indices (`indices:`): `stat(channel - subtract) / divide` over the
//! evaluation window with `stat` one of max, min, max |.|, RMS and peak-to-peak, and an
//! optional upper limit.
//!
//! Everything is looked up by column name, so the same code serves the solver's stored record
//! (the `indices` stage), a prediction (`evaluate`, `predict`) and the solver under the
//! explorer: the caller hands a lookup `column name -> values over the window`.

use crate::{IndexConfig, Indices, Record, Result, INDEX_COLUMNS};
use mbd_system::schema::IndexStat;
use mbd_system::System;

/// Column names the railway indices read, from the description's binding.
#[derive(Debug, Clone, PartialEq)]
pub struct RailwayColumns {
    /// Contact forces (4).
    pub p: [String; 4],
    /// Car-body vertical acceleration.
    pub z_c_a: String,
    /// Car-body pitch acceleration.
    pub beta_c_a: String,
    /// Bogie accelerations (2).
    pub z_t_a: [String; 2],
    /// Rail deflections (4).
    pub z_r: [String; 4],
}

impl RailwayColumns {
    /// Every column with its role, in [`Record::signals`] order.
    pub fn all(&self) -> Vec<&str> {
        let mut v: Vec<&str> = self.p.iter().map(String::as_str).collect();
        v.push(&self.z_c_a);
        v.push(&self.beta_c_a);
        v.extend(self.z_t_a.iter().map(String::as_str));
        v.extend(self.z_r.iter().map(String::as_str));
        v
    }
}

/// One index column of a system: name, unit, definition, limit.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexInfo {
    /// Column name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// What it is.
    pub definition: String,
}

/// The indices a description defines.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexSet {
    /// The railway binding.
    pub railway: Option<RailwayColumns>,
    /// The simple indices: `(index number in System::indices, channel name)`.
    simple: Vec<(usize, String)>,
}

fn arr<const N: usize>(system: &System, cols: &[usize]) -> [String; N] {
    std::array::from_fn(|i| system.channels[cols[i]].name.clone())
}

impl IndexSet {
    /// The indices of `system`.
    pub fn of(system: &System) -> Self {
        let railway = system.railway.as_ref().map(|r| RailwayColumns {
            p: arr(system, &r.contact_forces),
            z_c_a: system.channels[r.car_body_vertical].name.clone(),
            beta_c_a: system.channels[r.car_body_pitch].name.clone(),
            z_t_a: arr(system, &r.bogies),
            z_r: arr(system, &r.rails),
        });
        let simple = system
            .indices
            .iter()
            .enumerate()
            .map(|(i, ix)| (i, system.channels[ix.channel].name.clone()))
            .collect();
        Self { railway, simple }
    }

    /// Whether there is no index.
    pub fn is_empty(&self) -> bool {
        self.railway.is_none() && self.simple.is_empty()
    }

    /// The index columns in value order: the railway family's, then the simple ones.
    pub fn columns(&self, system: &System) -> Vec<IndexInfo> {
        let mut out = Vec::new();
        if self.railway.is_some() {
            out.extend(INDEX_COLUMNS.iter().map(|c| IndexInfo {
                name: c.name.to_owned(),
                unit: c.unit.to_owned(),
                definition: c.definition.to_owned(),
            }));
        }
        for (i, channel) in &self.simple {
            let ix = &system.indices[*i];
            let mut def = format!("{} of {channel}", ix.stat.keyword());
            if !ix.subtract.is_zero() {
                def = format!("{} of ({channel} - {})", ix.stat.keyword(), ix.subtract);
            }
            if !matches!(ix.divide, mbd_system::expr::Expr::Num(v) if v == 1.0) {
                def = format!("{def} / {}", ix.divide);
            }
            if let Some(d) = &ix.doc {
                def = format!("{def}: {d}");
            }
            out.push(IndexInfo {
                name: ix.name.clone(),
                unit: ix.unit.clone(),
                definition: def,
            });
        }
        out
    }

    /// Every column the indices read.
    pub fn inputs(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .railway
            .iter()
            .flat_map(|r| r.all())
            .map(str::to_owned)
            .collect();
        for (_, c) in &self.simple {
            if !v.contains(c) {
                v.push(c.clone());
            }
        }
        v
    }

    /// The index values of one record: `values` every parameter's value (`System::values`),
    /// `get(column)` the column over the evaluation window, `dt` its spacing (s). The railway
    /// indices come back too (for the pass/fail limits of the railway family).
    pub fn compute(
        &self,
        system: &System,
        values: &[f64],
        get: &dyn Fn(&str) -> Option<Vec<f64>>,
        dt: f64,
        cfg: &IndexConfig,
    ) -> Result<(Vec<f64>, Option<Indices>)> {
        let missing = |c: &str| crate::Error::Missing {
            column: c.to_owned(),
        };
        let mut out = Vec::new();
        let mut railway = None;
        if let (Some(r), Some(b)) = (&self.railway, &system.railway) {
            let fetch = |c: &str| get(c).ok_or_else(|| missing(c));
            let p: Vec<Vec<f64>> = r.p.iter().map(|c| fetch(c)).collect::<Result<_>>()?;
            let z_c = fetch(&r.z_c_a)?;
            let beta = fetch(&r.beta_c_a)?;
            let z_t: Vec<Vec<f64>> = r.z_t_a.iter().map(|c| fetch(c)).collect::<Result<_>>()?;
            let z_r: Vec<Vec<f64>> = r.z_r.iter().map(|c| fetch(c)).collect::<Result<_>>()?;
            let rec = Record {
                dt,
                p: std::array::from_fn(|i| p[i].as_slice()),
                z_c_a: &z_c,
                beta_c_a: &beta,
                z_t_a: std::array::from_fn(|i| z_t[i].as_slice()),
                z_r: std::array::from_fn(|i| z_r[i].as_slice()),
            };
            let ix = crate::compute(
                &rec,
                b.half_length.eval(values),
                b.static_wheel_load.eval(values),
                cfg,
            )?;
            out.extend(ix.values());
            railway = Some(ix);
        }
        for (i, channel) in &self.simple {
            let ix = &system.indices[*i];
            let x = get(channel).ok_or_else(|| missing(channel))?;
            crate::check_finite_signal(channel, &x)?;
            out.push(simple(
                ix.stat,
                &x,
                ix.subtract.eval(values),
                ix.divide.eval(values),
            ));
        }
        Ok((out, railway))
    }

    /// The limit of each column of [`IndexSet::columns`] (`None`: no limit): a value passes
    /// when it is at most its limit, as [`IndexSet::failed`] judges it (the Sperling limit
    /// holds at each car-body point).
    pub fn column_limits(&self, system: &System, cfg: &IndexConfig) -> Vec<Option<f64>> {
        let mut out = Vec::new();
        if self.railway.is_some() {
            let l = &cfg.limits;
            out.extend(INDEX_COLUMNS.iter().map(|c| match c.name {
                "peak_wheel_rail_force_kn" => l.peak_wheel_rail_force_kn,
                "wheel_load_reduction_rate" => l.wheel_load_reduction_rate,
                n if n.starts_with("sperling_wz") => l.sperling_wz,
                _ => None,
            }));
        }
        out.extend(self.simple.iter().map(|(i, _)| system.indices[*i].limit));
        out
    }

    /// The names of the limits a record's values exceed: the railway family's limits
    /// (`cfg.limits`) and each simple index's own.
    pub fn failed(
        &self,
        system: &System,
        values: &[f64],
        railway: Option<&Indices>,
        cfg: &IndexConfig,
    ) -> Vec<String> {
        let mut out: Vec<String> = railway
            .map(|ix| {
                cfg.limits
                    .failed(ix)
                    .into_iter()
                    .map(str::to_owned)
                    .collect()
            })
            .unwrap_or_default();
        let offset = if self.railway.is_some() {
            INDEX_COLUMNS.len()
        } else {
            0
        };
        for (k, (i, _)) in self.simple.iter().enumerate() {
            let ix = &system.indices[*i];
            if let Some(limit) = ix.limit {
                let v = values[offset + k];
                if v > limit || v.is_nan() {
                    out.push(ix.name.clone());
                }
            }
        }
        out
    }
}

/// `stat(x - subtract) / divide`.
pub fn simple(stat: IndexStat, x: &[f64], subtract: f64, divide: f64) -> f64 {
    let it = x.iter().map(|v| v - subtract);
    let v = match stat {
        IndexStat::Max => it.fold(f64::NEG_INFINITY, f64::max),
        IndexStat::Min => it.fold(f64::INFINITY, f64::min),
        IndexStat::MaxAbs => it.fold(0.0f64, |m, v| m.max(v.abs())),
        IndexStat::Rms => (it.map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt(),
        IndexStat::PeakToPeak => {
            let (lo, hi) = it.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
            hi - lo
        }
    };
    v / divide
}
