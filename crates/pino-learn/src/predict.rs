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

use crate::checkpoint::{load_model, ModelMeta};
use crate::config::{DOFS, OUT_CHANNELS};
use crate::data::input_block;
use crate::eval::to_physical;
use crate::spectral::Transform;
use crate::{Error, Result};
use candle_core::{Device, Tensor};
use pino_data::{schema, Column, Table};
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

fn set_param(p: &mut [f64; 14], name: &str, value: f64, origin: &Path) -> Result<()> {
    let k = PARAMETER_NAMES
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
        })?;
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

/// Predicts every set; returns the output table and the model's metadata.
pub fn predict(
    model_dir: &Path,
    sets: &[SampleParams],
    profile: &Profile,
    place: &Placement,
    device: &Device,
) -> Result<(Table, ModelMeta)> {
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
    let xt = Tensor::from_vec(x, (sets.len(), tp, 19), device)?;
    let u = model
        .predictor()?
        .predict(&xt)?
        .flatten_all()?
        .to_vec1::<f32>()?;
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
    for (s, chunk) in u.chunks(tp * OUT_CHANNELS).enumerate() {
        let ph = to_physical(chunk, &meta);
        for n in 1..tp - 1 {
            set_col.push(s as i64);
            t_col.push(times[n]);
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
                cols[OUT_CHANNELS + 2 * DOFS + i].1.push(etas[s][n * 4 + i]);
            }
        }
    }
    let mut table = Table::default();
    table.push("set", Column::I64(set_col))?;
    table.push(schema::TIME, Column::F64(t_col))?;
    for (name, values) in cols {
        table.push(&name, Column::F64(values))?;
    }
    Ok((table, meta))
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
