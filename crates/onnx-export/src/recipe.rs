//! What a caller needs to build the graph's excitation input exactly as `predict` builds it
//! (`mbd_engine::Excitations`, `docs/export.md`), as data in the file's metadata:
//!
//! ```text
//! t_n = t0 + n dt                                   n = 0 .. T-1
//! x_e(t) = (x0 + v t) + o_e                         v, o_e affine in the parameters
//! r(t)  = 0 before `on`, (t - on) / ramp during the ramp, 1 after;  r' = 1 / ramp during it
//! eta_e = r eta(x_e) (0 while r = 0)                eta_e_v = r v eta'(x_e) + r' eta(x_e)
//! ```
//!
//! with `eta` the profile the element reads: its points read linearly or by the not-a-knot
//! cubic spline (`mbd_engine::Profile`), or a harmonic. The speed and each moving point's
//! offset are written as affine forms `constant + sum_j c_j p_j` over the sampled parameters;
//! a description whose speed or offset is not affine in them, or whose harmonic profile reads
//! a sampled parameter, is refused by name.

use crate::{Error, Result};
use mbd_system::expr::{Expr, Op};
use mbd_system::system::{End, ParamSource, Profile, Quantity};
use mbd_system::System;
use pino_learn::checkpoint::ModelMeta;
use serde_json::{json, Value};
use std::collections::BTreeMap;

/// `constant + sum c_j p_j`.
type Affine = (f64, BTreeMap<String, f64>);

/// The affine form of `e` over the sampled parameters, or `None` when it is not affine.
fn affine(system: &System, nominal: &[f64], e: &Expr) -> Option<Affine> {
    let varies = |e: &Expr| -> bool { !affine_const(system, e) };
    if !varies(e) {
        return Some((e.eval(nominal), BTreeMap::new()));
    }
    let scale = |(c, t): Affine, k: f64| -> Affine {
        (c * k, t.into_iter().map(|(n, v)| (n, v * k)).collect())
    };
    match e {
        Expr::Var(_, Some(i)) => match &system.parameters[*i].source {
            ParamSource::Sampled { .. } => Some((
                0.0,
                BTreeMap::from([(system.parameters[*i].name.clone(), 1.0)]),
            )),
            ParamSource::Derived(d) => affine(system, nominal, d),
            ParamSource::Fixed(v) => Some((*v, BTreeMap::new())),
        },
        Expr::Neg(a) => affine(system, nominal, a).map(|a| scale(a, -1.0)),
        Expr::Bin(op @ (Op::Add | Op::Sub), a, b) => {
            let (a, b) = (affine(system, nominal, a)?, affine(system, nominal, b)?);
            let sign = if *op == Op::Add { 1.0 } else { -1.0 };
            let mut t = a.1;
            for (n, v) in b.1 {
                *t.entry(n).or_insert(0.0) += sign * v;
            }
            Some((a.0 + sign * b.0, t))
        }
        Expr::Bin(Op::Mul, a, b) => {
            let (a, b) = (affine(system, nominal, a)?, affine(system, nominal, b)?);
            match (a.1.is_empty(), b.1.is_empty()) {
                (true, _) => Some(scale(b, a.0)),
                (_, true) => Some(scale(a, b.0)),
                _ => None,
            }
        }
        Expr::Bin(Op::Div, a, b) => {
            let (a, b) = (affine(system, nominal, a)?, affine(system, nominal, b)?);
            b.1.is_empty().then(|| scale(a, 1.0 / b.0))
        }
        _ => None,
    }
}

/// Whether `e` reads no sampled parameter.
fn affine_const(system: &System, e: &Expr) -> bool {
    e.parameters()
        .iter()
        .all(|i| match &system.parameters[*i].source {
            ParamSource::Sampled { .. } => false,
            ParamSource::Fixed(_) => true,
            ParamSource::Derived(d) => affine_const(system, d),
        })
}

fn affine_json(a: &Affine) -> Value {
    json!({"constant": a.0, "per_parameter": a.1})
}

/// The excitation recipe of a model of `system` (metadata `meta`), as JSON.
pub fn recipe(system: &System, meta: &ModelMeta) -> Result<Value> {
    let run = meta.data.as_ref().map(|d| d.run).ok_or_else(|| {
        Error::Unsupported(
            "the model's dataset records no run controls (run.json of `simulate`): the excitation cannot be described".into(),
        )
    })?;
    let nominal = system
        .values(&system.nominal())
        .map_err(|e| Error::Unsupported(e.to_string()))?;
    let refuse = |what: String| {
        Error::Unsupported(format!(
            "{what} is not affine in the sampled parameters: its excitation cannot be described"
        ))
    };
    let speed = affine(system, &nominal, &system.speed)
        .ok_or_else(|| refuse("the moving frame's speed".into()))?;
    let mut columns = Vec::new();
    for name in &meta.layout.excitations {
        let quantity = system.channel(name).map(|c| system.channels[c].quantity);
        let (element, rate) = match quantity {
            Some(Quantity::Excitation(e)) => (e, false),
            Some(Quantity::ExcitationRate(e)) => (e, true),
            _ => return Err(Error::Unsupported(format!("`{name}` is not an excitation"))),
        };
        let el = &system.elements[element];
        let (Some(p), End::Moving(pt)) = (el.profile, &el.to) else {
            return Err(Error::Unsupported(format!(
                "`{name}`: its element reads no profile at a moving point"
            )));
        };
        let point = &system.points[*pt];
        let offset = affine(system, &nominal, &point.offset)
            .ok_or_else(|| refuse(format!("the offset of moving point `{}`", point.name)))?;
        columns.push(json!({
            "name": name,
            "kind": if rate { "rate" } else { "profile" },
            "profile": system.profiles[p].name(),
            "offset": affine_json(&offset),
        }));
    }
    let mut profiles = Vec::new();
    for p in &system.profiles {
        profiles.push(match p {
            Profile::Generated {
                name,
                interpolation,
                until: None,
                ..
            } => json!({"name": name, "kind": "points", "interpolation": interpolation.keyword()}),
            Profile::Generated { name, .. } => {
                return Err(Error::Unsupported(format!(
                    "generated profile `{name}` ends (`until`): the recipe describes points read as they are"
                )))
            }
            Profile::Combination { name, .. } => {
                return Err(Error::Unsupported(format!(
                    "profile `{name}` combines other profiles: the recipe describes single profiles"
                )))
            }
            Profile::Harmonic {
                name,
                amplitude,
                wavelength,
                phase,
            } => {
                let value = |e: &Expr, what: &str| {
                    if affine_const(system, e) {
                        Ok(e.eval(&nominal))
                    } else {
                        Err(Error::Unsupported(format!(
                            "the {what} of harmonic profile `{name}` reads a sampled parameter: its excitation cannot be described"
                        )))
                    }
                };
                json!({"name": name, "kind": "harmonic",
                    "amplitude": value(amplitude, "amplitude")?,
                    "wavelength": value(wavelength, "wavelength")?,
                    "phase": value(phase, "phase")?})
            }
        });
    }
    let g = &meta.grid;
    Ok(json!({
        "t0": g.t0,
        "dt": g.dt,
        "points": g.t_points,
        "x0": run.x0,
        "profile_on": run.startup_zero_fraction * run.duration,
        "ramp": run.startup_ramp_fraction * run.duration,
        "speed": affine_json(&speed),
        "columns": columns,
        "profiles": profiles,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vehicle-track description's speed `v_kmh / 3.6` and the offsets `2 (l_c + l_t)`,
    /// `2 l_c`, `2 l_t`, `0`; a product of two sampled parameters is not affine.
    #[test]
    fn speeds_and_offsets_are_affine_forms_of_the_parameters() {
        let s = learn_fixtures::synthetic::vehicle_track_system();
        let nominal = s.values(&s.nominal()).unwrap();
        let speed = affine(&s, &nominal, &s.speed).unwrap();
        assert_eq!(speed.0, 0.0);
        assert!((speed.1["v_kmh"] - 1.0 / 3.6).abs() < 1e-15);
        let offsets: Vec<Affine> = s
            .points
            .iter()
            .map(|p| affine(&s, &nominal, &p.offset).unwrap())
            .collect();
        assert_eq!(
            offsets[0].1,
            BTreeMap::from([("l_c".into(), 2.0), ("l_t".into(), 2.0)])
        );
        assert_eq!(offsets[1].1, BTreeMap::from([("l_c".into(), 2.0)]));
        assert!(offsets[3].1.is_empty() && offsets[3].0 == 0.0);
        let mut product = Expr::parse("l_c * l_t + 2 * g").unwrap();
        product.resolve(&|n| s.parameter(n)).unwrap();
        assert!(affine(&s, &nominal, &product).is_none());
        let mut fixed = Expr::parse("2 * g - l_c / 4").unwrap();
        fixed.resolve(&|n| s.parameter(n)).unwrap();
        let f = affine(&s, &nominal, &fixed).unwrap();
        assert_eq!((f.0, f.1["l_c"]), (2.0 * 9.81, -0.25));
    }
}
