//! Checks that need numbers: the description instantiated at its nominal values must have
//! every field in its domain, and every body DOF must be restrained.
//!
//! **Restraint.** With the beams and the ground held fixed, the elements give the rigid DOFs
//! the stiffness `K = sum_e k_e b_e b_e^T`, `b_e` the element's deflection per unit DOF motion
//! (`+1` / `-x` on the `from` body's `z` / pitch, minus the same for the `to` body); a contact
//! counts as restraining (it carries the static load). `K` scaled to unit diagonal must be
//! positive definite; a zero diagonal or a vanishing Cholesky pivot names the DOF that nothing
//! holds (a free body, or a pitch with all its elements at one point).

use crate::diag::Diagnostics;
use crate::model::{ModelEnd, ModelLaw};
use crate::schema::RawDescription;
use crate::system::System;
use crate::yaml::Pos;

/// Relative pivot below which a DOF counts as unrestrained.
const PIVOT_TOLERANCE: f64 = 1e-10;

fn position(raw: &RawDescription, path: &str) -> Pos {
    let mut parts = path.split('.');
    let section = parts.next().unwrap_or("");
    let name = parts.next().unwrap_or("");
    let name = name.split('[').next().unwrap_or(name);
    let found = match section {
        "parameters" => raw
            .parameters
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.pos),
        "bodies" => raw.bodies.iter().find(|b| b.name == name).map(|b| b.pos),
        "beams" => raw.beams.iter().find(|b| b.name == name).map(|b| b.pos),
        "elements" => raw.elements.iter().find(|e| e.name == name).map(|e| e.pos),
        "loads" => raw.loads.iter().find(|l| l.name == name).map(|l| l.pos),
        "sensors" => raw.sensors.iter().find(|s| s.name == name).map(|s| s.pos),
        "profiles" => raw.profiles.iter().find(|p| p.name == name).map(|p| p.pos),
        "moving" => raw.moving.as_ref().map(|m| {
            m.points
                .iter()
                .find(|p| path.contains(&format!(".{}.", p.name)))
                .map_or(m.pos, |p| p.pos)
        }),
        _ => None,
    };
    found.unwrap_or(Pos { line: 1, col: 1 })
}

/// Domain and restraint checks at the nominal values.
pub fn nominal_checks(system: &System, raw: &RawDescription, diag: &mut Diagnostics) {
    let model = match system.instantiate(&system.nominal()) {
        Ok(m) => m,
        Err(e) => {
            diag.push(
                position(raw, &e.path),
                format!("at the nominal values, {e}"),
            );
            return;
        }
    };
    let n = system.dofs.len();
    let mut k = vec![vec![0.0; n]; n];
    for e in &model.elements {
        let stiffness = match &e.law {
            ModelLaw::SpringDamper { k, .. } => *k,
            ModelLaw::Hertz { .. } => 1.0,
            ModelLaw::Table { .. } => 1.0,
        };
        let mut b = vec![0.0; n];
        for (end, sign) in [(&e.from, 1.0), (&e.to, -1.0)] {
            if let ModelEnd::Body(t) = end {
                if let Some(z) = t.z {
                    b[z] += sign;
                }
                if let Some((p, c)) = t.pitch {
                    b[p] += sign * c;
                }
            }
        }
        for i in 0..n {
            for j in 0..n {
                k[i][j] += stiffness * b[i] * b[j];
            }
        }
    }
    if let Some(dof) = unrestrained(&mut k) {
        let d = &system.dofs[dof];
        let body = &system.bodies[d.body];
        let pos = raw
            .bodies
            .iter()
            .find(|b| b.name == body.name)
            .map_or(Pos { line: 1, col: 1 }, |b| b.pos);
        diag.push(
            pos,
            format!(
                "bodies.{}: DOF `{}` is not restrained by any element (the static problem is singular); connect the body so that every DOF is held, e.g. a pitch needs elements at two different points",
                body.name, d.name
            ),
        );
    }
}

/// The first DOF whose pivot vanishes in the Cholesky factorisation of `k` scaled to unit
/// diagonal, or `None` when `k` is positive definite.
fn unrestrained(k: &mut [Vec<f64>]) -> Option<usize> {
    let n = k.len();
    let scale: Vec<f64> = (0..n).map(|i| k[i][i]).collect();
    if let Some(i) = scale.iter().position(|&d| d.is_nan() || d <= 0.0) {
        return Some(i);
    }
    for i in 0..n {
        for j in 0..n {
            k[i][j] /= (scale[i] * scale[j]).sqrt();
        }
    }
    for j in 0..n {
        let d = k[j][j] - k[j][..j].iter().map(|x| x * x).sum::<f64>();
        if d.is_nan() || d <= PIVOT_TOLERANCE {
            return Some(j);
        }
        let d = d.sqrt();
        k[j][j] = d;
        for i in j + 1..n {
            let s = k[i][j] - (0..j).map(|p| k[i][p] * k[j][p]).sum::<f64>();
            k[i][j] = s / d;
        }
    }
    None
}
