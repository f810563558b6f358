//! Prediction for design exploration: a trained model, parameter sets and an irregularity
//! profile in, the 14 displacement responses, the 4 contact forces and the vehicle
//! derivatives out, from one forward pass.
//!
//! The irregularity under wheel `i` follows the `simulate` stage (`vtcd::simulation`):
//! `eta_i(t) = r(t) eta(x0 + v t + o_i)` with `o = (2 l_c + 2 l_t, 2 l_c, 2 l_t, 0)` (m), the
//! start-up factor `r(t)` of [`vtcd::simulation::SimulationConfig::ramp`] over the record
//! duration (the model's record length), and the profile linearly interpolated. The model
//! sees the same window of times it was trained on. Output rows are the interior points of
//! the window (`n = 1..T-2`), where the central-difference derivatives exist:
//! `set, t, <14 solutions>, p_1..p_4, <10 _v>, <10 _a>, eta_1..eta_4` (SI units, forces N).
//!
//! Parameter sets come from YAML, either a list of maps or `{sets: [...]}`; each map gives
//! any of the 14 parameter names (the rest take the CRH380 nominal values of
//! [`vtcd::params::SampleParams::NOMINAL`]); `name=value` overrides apply to every set.
//! Sweeps ([`parse_sweep`]) give designs by the thousand: a grid or a seeded random sample
//! over ranges. [`Predictor`] runs them in batches (side by side on the CPU) and computes
//! their engineering indices ([`Predictor::indices`], `docs/indices.md`) from the predicted
//! contact forces and central-difference accelerations, as `evaluate` does. Designs outside
//! the model's training ranges ([`crate::checkpoint::TrainingRanges`], stored in `model.json`)
//! are reported by [`Predictor::outside_training`].

use crate::checkpoint::{load_model, ModelMeta, OutOfRange};
use crate::config::{DOFS, OUT_CHANNELS};
use crate::data::input_block;
use crate::eval::{to_physical, Physical};
use crate::indices_eval::indices_of_physical;
use crate::model::Fno;
use crate::spectral::Transform;
use crate::{Error, Result};
use candle_core::{Device, Tensor};
use pino_data::{schema, Column, Table};
use pino_indices::{IndexConfig, Indices, INDEX_COLUMNS};
use std::collections::BTreeMap;
use std::path::Path;
use vtcd::params::{SampleParams, PARAMETER_NAMES};
use vtcd::simulation::{Profile, SimulationConfig};

fn fmt_err(path: &Path, message: String) -> Error {
    Error::Format {
        path: path.to_owned(),
        message,
    }
}

/// Position of parameter `name` in [`PARAMETER_NAMES`], or an error naming `origin` and
/// the allowed names.
fn param_index(name: &str, origin: &Path) -> Result<usize> {
    PARAMETER_NAMES
        .iter()
        .position(|n| *n == name)
        .ok_or_else(|| {
            fmt_err(
                origin,
                format!(
                    "unknown parameter `{name}`; allowed: {}",
                    PARAMETER_NAMES.join(", ")
                ),
            )
        })
}

fn set_param(p: &mut [f64; 14], name: &str, value: f64, origin: &Path) -> Result<()> {
    let k = param_index(name, origin)?;
    if !(value.is_finite() && value > 0.0) {
        return Err(fmt_err(
            origin,
            format!("parameter `{name}` = {value} must be finite and > 0"),
        ));
    }
    p[k] = value;
    Ok(())
}

/// Parses parameter sets from YAML text (`origin` names the file in errors).
pub fn parse_param_sets(text: &str, origin: &Path) -> Result<Vec<SampleParams>> {
    #[derive(serde::Deserialize)]
    #[serde(untagged)]
    enum Doc {
        List(Vec<BTreeMap<String, f64>>),
        Sets { sets: Vec<BTreeMap<String, f64>> },
    }
    let doc: Doc = serde_yaml::from_str(text).map_err(|e| {
        fmt_err(
            origin,
            format!("expected a list of parameter maps or `sets: [...]` with numbers: {e}"),
        )
    })?;
    let maps = match doc {
        Doc::List(l) | Doc::Sets { sets: l } => l,
    };
    if maps.is_empty() {
        return Err(fmt_err(origin, "no parameter set given".into()));
    }
    maps.iter()
        .map(|m| {
            let mut p = SampleParams::NOMINAL.to_array();
            for (k, v) in m {
                set_param(&mut p, k, *v, origin)?;
            }
            Ok(SampleParams::from_array(p))
        })
        .collect()
}

/// Applies `name=value` to every set.
pub fn apply_override(sets: &mut [SampleParams], assignment: &str) -> Result<()> {
    let origin = Path::new("--set");
    let (name, value) = assignment
        .split_once('=')
        .ok_or_else(|| fmt_err(origin, format!("`{assignment}`: expected name=value")))?;
    let value: f64 = value
        .trim()
        .parse()
        .map_err(|_| fmt_err(origin, format!("`{assignment}`: `{value}` is not a number")))?;
    for s in sets.iter_mut() {
        let mut a = s.to_array();
        set_param(&mut a, name.trim(), value, origin)?;
        *s = SampleParams::from_array(a);
    }
    Ok(())
}

/// Reads a profile Parquet file with columns `x` (m) and `eta` (m); when it holds a
/// `sample_id` column (the `irregularity` artifact), the rows of `sample_id` are used.
pub fn read_profile(path: &Path, sample_id: Option<i64>) -> Result<Profile> {
    let t = pino_data::read_parquet(path, None)?;
    let x = t.f64(schema::TRACK_X)?;
    let eta = t.f64(schema::TRACK_ETA)?;
    let rows: Vec<usize> = match (t.i64(schema::SAMPLE_ID).ok(), sample_id) {
        (Some(ids), Some(id)) => (0..ids.len()).filter(|&r| ids[r] == id).collect(),
        (Some(ids), None) => {
            let first = ids.first().copied().unwrap_or(0);
            (0..ids.len()).filter(|&r| ids[r] == first).collect()
        }
        (None, _) => (0..x.len()).collect(),
    };
    if rows.is_empty() {
        return Err(fmt_err(
            path,
            format!("no profile rows for sample_id {sample_id:?}"),
        ));
    }
    Profile::new(
        rows.iter().map(|&r| x[r]).collect(),
        rows.iter().map(|&r| eta[r]).collect(),
    )
    .map_err(|e| fmt_err(path, e.to_string()))
}

/// A generated profile: the `irregularity` stage's defaults with `seed`, sample `id`.
pub fn generated_profile(seed: u64, id: u64) -> Result<Profile> {
    let gen = vtcd::irregularity::IrregularityParams::with_seed(seed)
        .validate()
        .map_err(|e| fmt_err(Path::new("--seed"), e.to_string()))?;
    Profile::new(gen.positions(), gen.profile(id))
        .map_err(|e| fmt_err(Path::new("--seed"), e.to_string()))
}

/// Placement and start-up of the records the model was trained on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Rear-wheel position at t = 0 (m); the spec's default is 20.
    pub x0: f64,
    /// Fraction of the record with the irregularity off (0: the `simulate` default since the
    /// equilibrium start).
    pub startup_zero_fraction: f64,
    /// Fraction over which it fades in (0, as `simulate`).
    pub startup_ramp_fraction: f64,
}

impl Default for Placement {
    fn default() -> Self {
        Self {
            x0: 20.0,
            startup_zero_fraction: 0.0,
            startup_ramp_fraction: 0.0,
        }
    }
}

/// Irregularity under the four wheels `[T, 4]` at times `t` for one parameter set.
pub fn wheel_irregularity(
    p: &SampleParams,
    profile: &Profile,
    t: &[f64],
    duration: f64,
    place: &Placement,
) -> Result<Vec<f64>> {
    let cfg = SimulationConfig {
        duration,
        startup_zero_fraction: place.startup_zero_fraction,
        startup_ramp_fraction: place.startup_ramp_fraction,
        x0: place.x0,
        ..SimulationConfig::default()
    };
    let offsets = [2.0 * (p.l_c + p.l_t), 2.0 * p.l_c, 2.0 * p.l_t, 0.0];
    let [lo, hi] = profile.range();
    let mut out = Vec::with_capacity(4 * t.len());
    for &tk in t {
        let r = cfg.ramp(tk);
        for o in offsets {
            let x = place.x0 + p.speed() * tk + o;
            if x < lo || x > hi {
                return Err(Error::OutOfRange {
                    field: "irregularity profile".into(),
                    value: format!("wheel position {x:.2} m at t = {tk} s"),
                    allowed: format!("[{lo}, {hi}] m (the profile's extent)"),
                });
            }
            out.push(if r > 0.0 { r * profile.at(x) } else { 0.0 });
        }
    }
    Ok(out)
}

/// A trained model loaded for prediction.
pub struct Predictor {
    model: Fno,
    /// Its metadata (window, statistics, training ranges).
    pub meta: ModelMeta,
    device: Device,
}

/// One set's prediction in physical units: outputs `[T, 18]`, interior velocities and
/// accelerations `[T-2, 10]` ([`Physical`]), and the irregularity under the wheels `[T, 4]`.
pub struct SetPrediction {
    /// Outputs and derivatives.
    pub physical: Physical,
    /// Irregularity under the wheels (m).
    pub eta: Vec<f64>,
}

impl Predictor {
    /// Loads `model.safetensors` + `model.json` from `model_dir`.
    pub fn load(model_dir: &Path, device: &Device) -> Result<Self> {
        let (model, meta) = load_model(model_dir, Transform::for_device(device), device)?;
        if meta.model.out_channels != OUT_CHANNELS {
            return Err(fmt_err(
                &model_dir.join("model.json"),
                format!(
                    "the model predicts {} channels; this build predicts {OUT_CHANNELS} ({}): retrain it",
                    meta.model.out_channels,
                    schema::output_channels().join(", ")
                ),
            ));
        }
        Ok(Self {
            model,
            meta,
            device: device.clone(),
        })
    }

    /// The parameters of each set outside the model's training ranges (empty lists when the
    /// model has none recorded: see [`ModelMeta::training_ranges`]).
    pub fn outside_training(&self, sets: &[SampleParams]) -> Vec<Vec<OutOfRange>> {
        sets.iter()
            .map(|p| {
                self.meta
                    .training_ranges
                    .as_ref()
                    .map_or_else(Vec::new, |r| r.outside(&p.to_array()))
            })
            .collect()
    }

    /// Predicts `sets` in one forward pass.
    pub fn forward(
        &self,
        sets: &[SampleParams],
        profile: &Profile,
        place: &Placement,
    ) -> Result<Vec<SetPrediction>> {
        let meta = &self.meta;
        let times = meta.grid.times();
        let tp = meta.grid.t_points;
        let record_dt = meta.grid.dt / meta.window.time_stride as f64;
        let duration = meta.grid.record_points as f64 * record_dt;
        let mut x = Vec::with_capacity(sets.len() * tp * 19);
        let mut etas = Vec::with_capacity(sets.len());
        for p in sets {
            p.validate()
                .map_err(|e| fmt_err(Path::new("parameters"), e.to_string()))?;
            let eta = wheel_irregularity(p, profile, &times, duration, place)?;
            x.extend(
                meta.norm
                    .inputs
                    .normalise(&input_block(&times, &eta, &p.to_array())),
            );
            etas.push(eta);
        }
        let xt = Tensor::from_vec(x, (sets.len(), tp, 19), &self.device)?;
        let u = self
            .model
            .predictor()?
            .predict(&xt)?
            .flatten_all()?
            .to_vec1::<f32>()?;
        Ok(u.chunks(tp * OUT_CHANNELS)
            .zip(etas)
            .map(|(chunk, eta)| SetPrediction {
                physical: to_physical(chunk, meta),
                eta,
            })
            .collect())
    }

    /// Runs `f` on the predictions of `sets` in batches of `batch` sets (side by side on the
    /// CPU; results in set order, independent of the thread count).
    fn batched<T: Send>(
        &self,
        sets: &[SampleParams],
        profile: &Profile,
        place: &Placement,
        batch: usize,
        f: &(dyn Fn(usize, &SetPrediction) -> Result<T> + Sync),
    ) -> Result<Vec<T>> {
        use rayon::prelude::*;
        let chunks: Vec<(usize, &[SampleParams])> = sets
            .chunks(batch.max(1))
            .enumerate()
            .map(|(k, c)| (k * batch.max(1), c))
            .collect();
        let run = |(start, chunk): &(usize, &[SampleParams])| -> Result<Vec<T>> {
            self.forward(chunk, profile, place)?
                .iter()
                .enumerate()
                .map(|(k, p)| f(start + k, p))
                .collect()
        };
        let parts: Vec<Vec<T>> = if self.device.is_cpu() {
            chunks.par_iter().map(run).collect::<Result<_>>()?
        } else {
            chunks.iter().map(run).collect::<Result<_>>()?
        };
        Ok(parts.into_iter().flatten().collect())
    }

    /// The time histories of every set (module doc) as one table.
    pub fn histories(
        &self,
        sets: &[SampleParams],
        profile: &Profile,
        place: &Placement,
        batch: usize,
    ) -> Result<Table> {
        let times = self.meta.grid.times();
        let tp = self.meta.grid.t_points;
        let preds = self.batched(sets, profile, place, batch, &|_, p| {
            Ok(SetPrediction {
                physical: Physical {
                    u: p.physical.u.clone(),
                    v: p.physical.v.clone(),
                    a: p.physical.a.clone(),
                },
                eta: p.eta.clone(),
            })
        })?;
        let mut cols: Vec<(String, Vec<f64>)> = Vec::new();
        for name in schema::output_channels() {
            cols.push((name.to_string(), Vec::new()));
        }
        for name in schema::VEHICLE_DOFS {
            cols.push((schema::velocity(name), Vec::new()));
        }
        for name in schema::VEHICLE_DOFS {
            cols.push((schema::acceleration(name), Vec::new()));
        }
        for name in schema::ETA_UNDER_WHEEL {
            cols.push((name.to_owned(), Vec::new()));
        }
        let mut set_col = Vec::new();
        let mut t_col = Vec::new();
        for (s, pred) in preds.iter().enumerate() {
            let ph = &pred.physical;
            for (n, &t) in times.iter().enumerate().take(tp - 1).skip(1) {
                set_col.push(s as i64);
                t_col.push(t);
                for (c, col) in cols.iter_mut().take(OUT_CHANNELS).enumerate() {
                    col.1.push(ph.u[n * OUT_CHANNELS + c]);
                }
                for c in 0..DOFS {
                    cols[OUT_CHANNELS + c].1.push(ph.v[(n - 1) * DOFS + c]);
                    cols[OUT_CHANNELS + DOFS + c]
                        .1
                        .push(ph.a[(n - 1) * DOFS + c]);
                }
                for i in 0..4 {
                    cols[OUT_CHANNELS + 2 * DOFS + i]
                        .1
                        .push(pred.eta[n * 4 + i]);
                }
            }
        }
        let mut table = Table::default();
        table.push("set", Column::I64(set_col))?;
        table.push(schema::TIME, Column::F64(t_col))?;
        for (name, values) in cols {
            table.push(&name, Column::F64(values))?;
        }
        Ok(table)
    }

    /// The settings of the indices of a prediction: the `indices` stage's defaults with the
    /// model's gravity and no start-up (the model's window already excludes it).
    pub fn index_config(&self) -> Result<IndexConfig> {
        crate::indices_eval::eval_config(&self.meta)
    }

    /// The engineering indices (`docs/indices.md`) of every set, computed from its predicted
    /// contact forces, displacements and central-difference accelerations (the interior
    /// points of the window), as `evaluate` computes them; batches of `batch` sets.
    pub fn indices(
        &self,
        sets: &[SampleParams],
        profile: &Profile,
        place: &Placement,
        cfg: &IndexConfig,
        batch: usize,
    ) -> Result<Vec<Indices>> {
        let dt = self.meta.grid.dt;
        self.batched(sets, profile, place, batch, &|k, p| {
            indices_of_physical(
                &p.physical.u,
                &p.physical.a,
                true,
                dt,
                &sets[k].to_array(),
                cfg,
            )
            .map_err(|e| fmt_err(Path::new("prediction"), format!("set {k}: indices: {e}")))
        })
    }
}

/// The indices table of `predict`: `set`, the 14 parameters, the 14 indices, `window_s`,
/// `pass`, `failed`, and `outside_training_range` (the parameters outside the model's
/// training ranges, `name=value` comma-separated; empty inside).
pub fn indices_table(
    sets: &[SampleParams],
    indices: &[Indices],
    outside: &[Vec<OutOfRange>],
    cfg: &IndexConfig,
) -> Result<Table> {
    let mut t = Table::default();
    t.push("set", Column::I64((0..sets.len() as i64).collect()))?;
    for (j, name) in schema::PARAMETERS.iter().enumerate() {
        t.push(
            name,
            Column::F64(sets.iter().map(|p| p.to_array()[j]).collect()),
        )?;
    }
    for (k, c) in INDEX_COLUMNS.iter().enumerate() {
        t.push(
            c.name,
            Column::F64(indices.iter().map(|ix| ix.values()[k]).collect()),
        )?;
    }
    t.push(
        pino_indices::WINDOW_COLUMN,
        Column::F64(indices.iter().map(|ix| ix.window_s).collect()),
    )?;
    let failed: Vec<Vec<&str>> = indices.iter().map(|ix| cfg.limits.failed(ix)).collect();
    t.push(
        pino_indices::PASS_COLUMN,
        Column::I64(failed.iter().map(|f| f.is_empty() as i64).collect()),
    )?;
    t.push(
        pino_indices::FAILED_COLUMN,
        Column::Str(failed.iter().map(|f| f.join(",")).collect()),
    )?;
    t.push(
        OUTSIDE_COLUMN,
        Column::Str(outside.iter().map(|o| outside_flag(o)).collect()),
    )?;
    Ok(t)
}

/// Column of the indices table naming the parameters outside the training ranges.
pub const OUTSIDE_COLUMN: &str = "outside_training_range";

/// The [`OUTSIDE_COLUMN`] value of one design: its parameters outside the training ranges as
/// `name=value`, comma-separated (empty inside).
pub fn outside_flag(outside: &[OutOfRange]) -> String {
    outside
        .iter()
        .map(|r| format!("{}={}", r.name, r.value))
        .collect::<Vec<_>>()
        .join(",")
}

/// Predicts every set; returns the time-history table and the model's metadata.
pub fn predict(
    model_dir: &Path,
    sets: &[SampleParams],
    profile: &Profile,
    place: &Placement,
    device: &Device,
) -> Result<(Table, ModelMeta)> {
    let p = Predictor::load(model_dir, device)?;
    let table = p.histories(sets, profile, place, 16)?;
    Ok((table, p.meta))
}

/// How a sweep is written (`predict --sweep FILE`): `base` (optional, values of the parameters
/// not swept; the rest nominal) and exactly one of `grid` (every combination of the listed
/// axes, the last varying fastest; an axis is a list of values or `{from, to, steps}`, evenly
/// spaced, ends included) or `random` (`seed`, `count`, `ranges: {name: [lo, hi]}`: design `i`
/// draws each listed parameter uniformly, in spec order, from the stream
/// `(seed, Parameters, i)`, so a design depends only on the seed and its index).
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepDoc {
    #[serde(default)]
    base: BTreeMap<String, f64>,
    #[serde(default)]
    grid: Option<serde_yaml::Mapping>,
    #[serde(default)]
    random: Option<RandomDoc>,
}

#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RandomDoc {
    seed: u64,
    count: usize,
    ranges: BTreeMap<String, [f64; 2]>,
}

#[derive(Debug, Clone, serde::Deserialize)]
#[serde(untagged)]
enum Axis {
    Values(Vec<f64>),
    Range { from: f64, to: f64, steps: usize },
}

/// Most designs a sweep may produce (a typo in `steps` should not exhaust the memory).
pub const MAX_SWEEP: usize = 10_000_000;

/// Parses a sweep (see the YAML layout above) into parameter sets (`origin` names the file).
pub fn parse_sweep(text: &str, origin: &Path) -> Result<Vec<SampleParams>> {
    let doc: SweepDoc = serde_yaml::from_str(text).map_err(|e| {
        fmt_err(
            origin,
            format!("expected `base:` and one of `grid:` or `random:`: {e}"),
        )
    })?;
    let mut base = SampleParams::NOMINAL.to_array();
    for (k, v) in &doc.base {
        set_param(&mut base, k, *v, origin)?;
    }
    let index_of = |name: &str| param_index(name, origin);
    match (doc.grid, doc.random) {
        (Some(grid), None) => {
            let mut axes: Vec<(usize, Vec<f64>)> = Vec::new();
            for (k, v) in grid {
                let name = k
                    .as_str()
                    .ok_or_else(|| fmt_err(origin, format!("grid: key {k:?} is not a name")))?
                    .to_owned();
                let axis: Axis = serde_yaml::from_value(v).map_err(|e| {
                    fmt_err(
                        origin,
                        format!("grid.{name}: a list of values or {{from, to, steps}}: {e}"),
                    )
                })?;
                let values = match axis {
                    Axis::Values(v) => v,
                    Axis::Range { from, to, steps } => {
                        if steps < 1 {
                            return Err(fmt_err(
                                origin,
                                format!("grid.{name}.steps = 0: at least 1"),
                            ));
                        }
                        if steps == 1 {
                            vec![from]
                        } else {
                            (0..steps)
                                .map(|i| from + (to - from) * i as f64 / (steps - 1) as f64)
                                .collect()
                        }
                    }
                };
                if values.is_empty() {
                    return Err(fmt_err(origin, format!("grid.{name}: no values")));
                }
                axes.push((index_of(&name)?, values));
            }
            let total = axes
                .iter()
                .try_fold(1usize, |n, (_, v)| n.checked_mul(v.len()))
                .filter(|&n| n <= MAX_SWEEP)
                .ok_or_else(|| fmt_err(origin, format!("grid: more than {MAX_SWEEP} designs")))?;
            let mut sets = Vec::with_capacity(total);
            for i in 0..total {
                let mut p = base;
                let mut rest = i;
                for (k, values) in axes.iter().rev() {
                    let v = values[rest % values.len()];
                    rest /= values.len();
                    set_param(&mut p, PARAMETER_NAMES[*k], v, origin)?;
                }
                sets.push(SampleParams::from_array(p));
            }
            Ok(sets)
        }
        (None, Some(r)) => {
            if r.count == 0 || r.count > MAX_SWEEP {
                return Err(fmt_err(
                    origin,
                    format!("random.count = {}: allowed 1 ..= {MAX_SWEEP}", r.count),
                ));
            }
            let mut ranges: Vec<(usize, [f64; 2])> = Vec::new();
            for (name, range) in &r.ranges {
                let [lo, hi] = *range;
                if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
                    return Err(fmt_err(
                        origin,
                        format!("random.ranges.{name} = [{lo}, {hi}]: finite, 0 < lo <= hi"),
                    ));
                }
                ranges.push((index_of(name)?, *range));
            }
            ranges.sort_by_key(|(k, _)| *k);
            Ok((0..r.count)
                .map(|i| {
                    let mut s = mbd_dataset::rng::SampleStream::new(
                        r.seed,
                        mbd_dataset::rng::Purpose::Parameters,
                        i as u64,
                    );
                    let mut p = base;
                    for (k, [lo, hi]) in &ranges {
                        p[*k] = s.uniform_in(*lo, *hi);
                    }
                    SampleParams::from_array(p)
                })
                .collect())
        }
        _ => Err(fmt_err(
            origin,
            "give exactly one of `grid:` or `random:`".into(),
        )),
    }
}

/// The parameter type of a set (re-exported so that callers need not depend on `vtcd`).
pub type NominalParams = SampleParams;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaml_sets_and_overrides() {
        let o = Path::new("sets.yaml");
        let sets = parse_param_sets("- {k_s: 4.0e5}\n- {v_kmh: 310}\n", o).unwrap();
        assert_eq!(sets.len(), 2);
        assert_eq!(sets[0].k_s, 4.0e5);
        assert_eq!(sets[0].m_c, SampleParams::NOMINAL.m_c);
        assert_eq!(sets[1].v_kmh, 310.0);
        let sets2 = parse_param_sets("sets:\n  - {c_p: 2.2e4}\n", o).unwrap();
        assert_eq!(sets2[0].c_p, 2.2e4);
        let mut s = sets.clone();
        apply_override(&mut s, "l_c=8.5").unwrap();
        assert!(s.iter().all(|p| p.l_c == 8.5));
        let err = parse_param_sets("- {kk: 1}\n", o).unwrap_err().to_string();
        assert!(
            err.contains("sets.yaml") && err.contains("unknown parameter `kk`"),
            "{err}"
        );
        assert!(apply_override(&mut s, "m_c=-1").is_err());
        assert!(apply_override(&mut s, "m_c").is_err());
    }

    #[test]
    fn sweeps_by_grid_and_by_seeded_random_sample() {
        let o = Path::new("sweep.yaml");
        let g = parse_sweep(
            "base: {v_kmh: 340}\ngrid:\n  k_s: {from: 4.0e+5, to: 5.0e+5, steps: 3}\n  c_s: [1.0e+4, 3.0e+4]\n",
            o,
        )
        .unwrap();
        // Every combination, the last axis fastest; the base and nominal values elsewhere.
        assert_eq!(g.len(), 6);
        let ks: Vec<f64> = g.iter().map(|p| p.k_s).collect();
        let cs: Vec<f64> = g.iter().map(|p| p.c_s).collect();
        assert_eq!(ks, [4.0e5, 4.0e5, 4.5e5, 4.5e5, 5.0e5, 5.0e5]);
        assert_eq!(cs, [1.0e4, 3.0e4, 1.0e4, 3.0e4, 1.0e4, 3.0e4]);
        assert!(g
            .iter()
            .all(|p| p.v_kmh == 340.0 && p.m_c == SampleParams::NOMINAL.m_c));
        let text =
            "random: {seed: 7, count: 500, ranges: {k_f: [3.5e+7, 4.5e+7], v_kmh: [300, 350]}}\n";
        let r = parse_sweep(text, o).unwrap();
        assert_eq!(r.len(), 500);
        assert!(r
            .iter()
            .all(|p| (3.5e7..4.5e7).contains(&p.k_f) && (300.0..350.0).contains(&p.v_kmh)));
        assert!(r.iter().all(|p| p.k_s == SampleParams::NOMINAL.k_s));
        // Deterministic, and design i depends only on (seed, i).
        assert_eq!(parse_sweep(text, o).unwrap(), r);
        let fewer = parse_sweep(&text.replace("500", "20"), o).unwrap();
        assert_eq!(fewer[..], r[..20]);
        let mean = r.iter().map(|p| p.k_f).sum::<f64>() / 500.0;
        assert!((mean - 4.0e7).abs() < 0.1e7, "{mean}");
        // Bad input: named file, field and allowed values.
        for (bad, want) in [
            ("grid: {kk: [1]}\n", "unknown parameter `kk`"),
            ("grid: {k_s: {from: 1, to: 2, steps: 0}}\n", "steps = 0"),
            (
                "random: {seed: 1, count: 0, ranges: {}}\n",
                "random.count = 0",
            ),
            (
                "random: {seed: 1, count: 5, ranges: {k_s: [5, 1]}}\n",
                "0 < lo <= hi",
            ),
            ("base: {k_s: 1}\n", "exactly one of `grid:` or `random:`"),
            ("grid: {k_s: [-1]}\n", "must be finite and > 0"),
        ] {
            let e = parse_sweep(bad, o).unwrap_err().to_string();
            assert!(e.contains("sweep.yaml") && e.contains(want), "{bad}: {e}");
        }
    }

    #[test]
    fn training_ranges_flag_designs_outside_and_old_model_files_still_load() {
        let r = crate::checkpoint::TrainingRanges {
            source: "sample-params".into(),
            names: PARAMETER_NAMES.iter().map(|s| s.to_string()).collect(),
            min: (0..14)
                .map(|k| 0.8 * SampleParams::NOMINAL.to_array()[k])
                .collect(),
            max: (0..14)
                .map(|k| 1.2 * SampleParams::NOMINAL.to_array()[k])
                .collect(),
        };
        assert!(r.outside(&SampleParams::NOMINAL.to_array()).is_empty());
        let mut p = SampleParams::NOMINAL.to_array();
        p[12] = 1e9; // k_f, 25x the nominal
        p[0] = r.max[0]; // a bound itself is inside
        let out = r.outside(&p);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].name, "k_f");
        assert!(out[0].to_string().contains("k_f = 1000000000 (trained on"));
        // A model.json without the field (written before it existed) reads as `None`.
        let dir = tempfile::tempdir().unwrap();
        let spec = crate::synthetic::SyntheticSpec {
            n_train: 2,
            n_validation: 1,
            ..Default::default()
        };
        let files = crate::synthetic::write_dataset(&spec, dir.path()).unwrap();
        let (m, t, w) = crate::config::TrainParams::with_algorithm(1)
            .configs()
            .unwrap();
        let ds = crate::data::load_dataset(
            &files.params,
            std::slice::from_ref(&files.simulation),
            None,
            &w,
        )
        .unwrap();
        let mut meta = crate::train::model_meta(&ds, m, t, w).unwrap();
        let ranges = meta.training_ranges.clone().unwrap();
        assert_eq!(ranges.source, "training samples");
        assert!(ranges.min.iter().zip(&ranges.max).all(|(a, b)| a <= b));
        // With the sampling ranges beside params.parquet (as `sample-params` writes them),
        // those are the training ranges.
        let mut rt = Table::default();
        rt.push("name", Column::Str(r.names.clone())).unwrap();
        let units = r.names.iter().map(|_| "-".to_string()).collect();
        rt.push("unit", Column::Str(units)).unwrap();
        rt.push("min", Column::F64(r.min.clone())).unwrap();
        rt.push("max", Column::F64(r.max.clone())).unwrap();
        let beside = files
            .params
            .parent()
            .unwrap()
            .join(crate::checkpoint::RANGES_FILE);
        pino_data::write_parquet(&beside, &rt).unwrap();
        assert_eq!(crate::train::training_ranges(&ds).unwrap(), r);
        meta.training_ranges = None;
        let old = serde_json::to_string(&meta).unwrap();
        assert!(!old.contains("training_ranges"));
        let back: ModelMeta = serde_json::from_str(&old).unwrap();
        assert_eq!(back.training_ranges, None);
    }

    #[test]
    fn wheel_irregularity_follows_the_simulation_placement() {
        // Profile eta(x) = 1e-3 x (linear): wheel 4 at x0 + v t, wheel 1 2(l_c + l_t) ahead.
        let xs: Vec<f64> = (0..=600).map(|k| k as f64).collect();
        let profile = Profile::new(xs.clone(), xs.iter().map(|x| 1e-3 * x).collect()).unwrap();
        let p = SampleParams::NOMINAL;
        let place = Placement {
            startup_zero_fraction: 0.1,
            startup_ramp_fraction: 0.1,
            ..Placement::default()
        };
        // duration 1 s: r = 0 before 0.1 s, 0.5 at 0.15 s, 1 after 0.2 s.
        let eta = wheel_irregularity(&p, &profile, &[0.05, 0.15, 0.5], 1.0, &place).unwrap();
        assert_eq!(&eta[..4], &[0.0; 4]);
        let x4 = 20.0 + p.speed() * 0.15;
        assert!((eta[7] - 0.5e-3 * x4).abs() < 1e-12);
        let x1 = 20.0 + p.speed() * 0.5 + 2.0 * (p.l_c + p.l_t);
        assert!((eta[8] - 1e-3 * x1).abs() < 1e-12);
    }
}
