//! The indices of a described system: the railway family (this crate's [`crate::compute`]) when
//! the description binds it to its columns (`railway:` in the description), the lateral family
//! ([`crate::lateral`]) when it binds that (`lateral:`), then the description's own simple
//! indices (`indices:`): `stat(channel - subtract) / divide` over the
//! evaluation window with `stat` one of max, min, max |.|, RMS and peak-to-peak, and an
//! optional upper limit.
//!
//! Everything is looked up by column name, so the same code serves the solver's stored record
//! (the `indices` stage), a prediction (`evaluate`, `predict`) and the solver under the
//! explorer: the caller hands a lookup `column name -> values over the window`.

use crate::{
    lateral_indices, IndexConfig, Indices, LateralParams, LateralRecord, Record, Result,
    INDEX_COLUMNS, LATERAL_COLUMNS,
};
use mbd_system::schema::IndexStat;
use mbd_system::system::{Lateral, LateralLimits};
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

/// Column names the lateral indices read, from the description's binding.
#[derive(Debug, Clone, PartialEq)]
pub struct LateralColumns {
    /// Per wheel, front to rear, left before right: `Y` and `Q`.
    pub wheels: Vec<[String; 2]>,
    /// The car body's lateral, yaw and roll accelerations.
    pub car_body: [String; 3],
    /// The stability column.
    pub stability: String,
    /// The stored excitations.
    pub excitations: Vec<String>,
}

impl LateralColumns {
    /// Every column, each once, in the binding's order.
    pub fn all(&self) -> Vec<&str> {
        let mut v: Vec<&str> = Vec::new();
        let names = self
            .wheels
            .iter()
            .flatten()
            .chain(&self.car_body)
            .chain(std::iter::once(&self.stability))
            .chain(&self.excitations);
        for n in names {
            if !v.contains(&n.as_str()) {
                v.push(n);
            }
        }
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

/// The unit of every index column `system` defines (the railway family's when it binds them,
/// the lateral family's, its own), `(name, unit)` in value order: what a writer of index
/// columns adds to the units of the system's other columns (`pino_data::system::units_of`).
pub fn column_units(system: &System) -> Vec<(String, String)> {
    IndexSet::of(system)
        .columns(system)
        .into_iter()
        .map(|c| (c.name, c.unit))
        .collect()
}

/// The indices a description defines.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexSet {
    /// The railway binding.
    pub railway: Option<RailwayColumns>,
    /// The lateral binding.
    pub lateral: Option<LateralColumns>,
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
        let name = |c: usize| system.channels[c].name.clone();
        let lateral = system.lateral.as_ref().map(|l| LateralColumns {
            wheels: l.wheels.iter().map(|w| w.map(name)).collect(),
            car_body: l.car_body.map(name),
            stability: name(l.stability),
            excitations: l.excitations.iter().map(|&c| name(c)).collect(),
        });
        let simple = system
            .indices
            .iter()
            .enumerate()
            .map(|(i, ix)| (i, system.channels[ix.channel].name.clone()))
            .collect();
        Self {
            railway,
            lateral,
            simple,
        }
    }

    /// Whether there is no index.
    pub fn is_empty(&self) -> bool {
        self.railway.is_none() && self.lateral.is_none() && self.simple.is_empty()
    }

    /// The number of columns before the simple indices' (the families').
    fn families_len(&self) -> usize {
        self.railway.as_ref().map_or(0, |_| INDEX_COLUMNS.len())
            + self.lateral.as_ref().map_or(0, |_| LATERAL_COLUMNS.len())
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
        if self.lateral.is_some() {
            out.extend(LATERAL_COLUMNS.iter().map(|c| IndexInfo {
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
        for c in self.lateral.iter().flat_map(|l| l.all()) {
            if !v.iter().any(|x| x == c) {
                v.push(c.to_owned());
            }
        }
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
        if let (Some(l), Some(b)) = (&self.lateral, &system.lateral) {
            let fetch = |c: &str| get(c).ok_or_else(|| missing(c));
            let wheels: Vec<[Vec<f64>; 2]> = l
                .wheels
                .iter()
                .map(|[y, q]| Ok([fetch(y)?, fetch(q)?]))
                .collect::<Result<_>>()?;
            let car: Vec<Vec<f64>> = l.car_body.iter().map(|c| fetch(c)).collect::<Result<_>>()?;
            let stability = fetch(&l.stability)?;
            let excitations: Vec<Vec<f64>> = l
                .excitations
                .iter()
                .map(|c| fetch(c))
                .collect::<Result<_>>()?;
            let rec = LateralRecord {
                dt,
                wheels: wheels
                    .iter()
                    .map(|[y, q]| (y.as_slice(), q.as_slice()))
                    .collect(),
                car_body: [&car[0], &car[1], &car[2]],
                stability: &stability,
                excitations: excitations.iter().map(Vec::as_slice).collect(),
            };
            out.extend(lateral_indices(
                &rec,
                &lateral_params(system, b, values),
                &cfg.sperling,
            )?);
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
        if let (Some(_), Some(b)) = (&self.lateral, &system.lateral) {
            out.extend(
                LATERAL_COLUMNS
                    .iter()
                    .map(|c| lateral_limit(c.name, &b.limits)),
            );
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
        if let (Some(_), Some(b)) = (&self.lateral, &system.lateral) {
            let start = self.railway.as_ref().map_or(0, |_| INDEX_COLUMNS.len());
            for (k, c) in LATERAL_COLUMNS.iter().enumerate() {
                if let (Some(limit), Some(&v)) =
                    (lateral_limit(c.name, &b.limits), values.get(start + k))
                {
                    if (v > limit || v.is_nan()) && !out.iter().any(|o| o == c.name) {
                        out.push(c.name.to_owned());
                    }
                }
            }
        }
        let offset = self.families_len();
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

/// The limit of a lateral index column (`name` of [`LATERAL_COLUMNS`]).
fn lateral_limit(name: &str, l: &LateralLimits) -> Option<f64> {
    match name {
        "derailment_quotient_2m" => l.derailment_quotient,
        "prudhomme_ratio" => l.lateral_force,
        n if n.starts_with("sperling_wy") => l.sperling,
        crate::lateral::STABILITY_INDEX => l.stability,
        _ => None,
    }
}

/// A sample's lateral constants: the frame's speed and the binding's expressions over its
/// parameter values.
pub fn lateral_params(system: &System, b: &Lateral, values: &[f64]) -> LateralParams {
    LateralParams {
        speed: system.speed.eval(values),
        half_length: b.half_length.eval(values),
        floor: b.floor.eval(values),
        axle_load: b.axle_load.eval(values),
        prudhomme: b.prudhomme.eval(values),
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
