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
use crate::model::ModelLaw;
use crate::reader::Field;
use crate::schema::{
    RawBeam, RawBody, RawDescription, RawElement, RawGeometry, RawLaw, RawLink, RawProfile,
    RawProfileKind, RawWheelset,
};
use crate::system::System;
use crate::yaml::Pos;

/// Relative pivot below which a DOF counts as unrestrained.
const PIVOT_TOLERANCE: f64 = 1e-10;

/// Where the field `path` (`bodies.c.mass`, `beams.r.supports.levels[0].link.k`) was written:
/// the field itself when the description wrote it, else its entry, else the top.
pub(crate) fn position(raw: &RawDescription, path: &str) -> Pos {
    let parts: Vec<&str> = path.split('.').collect();
    let section = parts[0];
    let name = parts
        .get(1)
        .map_or("", |n| n.split('[').next().unwrap_or(n));
    let field: Vec<&str> = parts.iter().skip(2).copied().collect();
    let field = field.as_slice();
    let found = match section {
        "parameters" => raw
            .parameters
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.pos),
        "bodies" => raw
            .bodies
            .iter()
            .find(|b| b.name == name)
            .map(|b| body_field(b, field).unwrap_or(b.pos)),
        "beams" => raw
            .beams
            .iter()
            .find(|b| b.name == name)
            .map(|b| beam_field(b, field).unwrap_or(b.pos)),
        "elements" => raw
            .elements
            .iter()
            .find(|e| e.name == name)
            .map(|e| element_field(e, field).unwrap_or(e.pos)),
        "loads" => raw
            .loads
            .iter()
            .find(|l| l.name == name)
            .map(|l| written(&l.force).unwrap_or(l.pos)),
        "sensors" => raw
            .sensors
            .iter()
            .find(|s| s.name == name)
            .map(|s| written(&s.x).unwrap_or(s.pos)),
        "profiles" => raw
            .profiles
            .iter()
            .find(|p| p.name == name)
            .map(|p| profile_field(p, field).unwrap_or(p.pos)),
        "moving" => raw.moving.as_ref().map(|m| match parts.as_slice() {
            [_, "speed"] => written(&m.speed).unwrap_or(m.pos),
            [_, "points", point, ..] => m
                .points
                .iter()
                .find(|p| p.name == *point)
                .map_or(m.pos, |p| written(&p.offset).unwrap_or(p.pos)),
            _ => m.pos,
        }),
        _ => None,
    };
    found.unwrap_or(Pos { line: 1, col: 1 })
}

/// Where a field was written, when it was.
fn written(f: &Option<Field>) -> Option<Pos> {
    f.as_ref().map(|f| f.pos)
}

/// The index of a list item written `name[i]`.
fn item(s: &str) -> Option<usize> {
    s.split_once('[')?.1.strip_suffix(']')?.parse().ok()
}

/// Where a field of a link (`rest`: `k` or `c`) was written, else the link.
fn link_field(l: &Option<RawLink>, rest: &[&str]) -> Option<Pos> {
    let l = l.as_ref()?;
    match rest {
        ["k"] => written(&l.k),
        ["c"] => written(&l.c),
        _ => None,
    }
    .or(Some(l.pos))
}

/// Where a field of a body (`field` the path below the body) was written.
fn body_field(b: &RawBody, field: &[&str]) -> Option<Pos> {
    match field {
        ["mass"] => written(&b.mass),
        ["inertia"] => b.inertia.first().map(|f| f.1.pos),
        ["inertia", axis] => b
            .inertia
            .iter()
            .find(|(k, _)| k.keyword() == *axis)
            .map(|f| f.1.pos),
        ["points", p] => b.points.iter().find(|q| q.name == *p).map(|q| q.x.pos),
        _ => None,
    }
}

/// Where a field of a beam (`field` the path below the beam) was written.
fn beam_field(b: &RawBeam, field: &[&str]) -> Option<Pos> {
    let supports = |rest: &[&str]| -> Option<Pos> {
        let s = b.supports.as_ref()?;
        match rest {
            ["spacing"] => written(&s.spacing),
            ["count"] => written(&s.count),
            ["first"] => written(&s.first),
            ["ground", rest @ ..] => link_field(&s.ground, rest),
            [level, rest @ ..] if level.starts_with("levels[") => {
                let l = s.levels.get(item(level)?)?;
                match rest {
                    ["mass"] => written(&l.mass),
                    ["link", rest @ ..] => link_field(&l.link, rest),
                    ["shear", rest @ ..] => link_field(&l.shear, rest),
                    _ => None,
                }
                .or(Some(l.pos))
            }
            _ => None,
        }
        .or(Some(s.pos))
    };
    match field {
        ["length"] => written(&b.length),
        ["modes"] => written(&b.modes),
        ["mass_per_length"] => written(&b.mass_per_length),
        ["bending_stiffness"] => written(&b.bending_stiffness),
        ["damping_ratio"] => written(&b.damping_ratio),
        ["supports", rest @ ..] => supports(rest),
        _ => None,
    }
}

/// Where a field of an element's law (`field` the path below the element) was written.
fn element_field(e: &RawElement, field: &[&str]) -> Option<Pos> {
    let list = |fields: &[Field], key: &str| item(key).and_then(|i| fields.get(i)).map(|f| f.pos);
    match (&e.law, field) {
        (RawLaw::SpringDamper { k, .. }, ["k"]) => written(k),
        (RawLaw::SpringDamper { c, .. } | RawLaw::Table { c, .. }, ["c"]) => written(c),
        (RawLaw::SpringDamper { preload, .. }, ["preload"]) => written(preload),
        (RawLaw::Hertz { g, .. }, ["g"]) => written(g),
        (RawLaw::Hertz { exponent, .. }, ["exponent"]) => written(exponent),
        (RawLaw::Table { deflection, .. }, [key]) if key.starts_with("deflection") => {
            list(deflection, key)
        }
        (RawLaw::Table { force, .. }, [key]) if key.starts_with("force") => list(force, key),
        (RawLaw::Wheelset(w), rest) => wheelset_field(w, rest),
        _ => None,
    }
}

/// Where a field of a profile (`field` the path below the profile) was written.
fn profile_field(p: &RawProfile, field: &[&str]) -> Option<Pos> {
    match (&p.kind, field) {
        (RawProfileKind::Harmonic { amplitude, .. }, ["amplitude"]) => written(amplitude),
        (RawProfileKind::Harmonic { wavelength, .. }, ["wavelength"]) => written(wavelength),
        (RawProfileKind::Harmonic { phase, .. }, ["phase"]) => written(phase),
        (RawProfileKind::Generated { interpolation, .. }, ["interpolation"]) => {
            Some(interpolation.1)
        }
        (
            RawProfileKind::Generated {
                until: Some((x, _)),
                ..
            },
            ["until", "x"],
        ) => Some(x.pos),
        (
            RawProfileKind::Generated {
                until: Some((_, taper)),
                ..
            },
            ["until", "taper"],
        ) => Some(taper.pos),
        _ => None,
    }
}

/// Where a field of a wheelset was written (`rest` the path below the element).
fn wheelset_field(w: &RawWheelset, rest: &[&str]) -> Option<Pos> {
    match rest {
        ["half_gauge"] => written(&w.half_gauge),
        ["radius"] => written(&w.radius),
        ["hertz"] => written(&w.hertz),
        ["conicity"] => match &w.geometry {
            Some(RawGeometry::Conicity(c)) => Some(c.pos),
            _ => None,
        },
        ["geometry", key] => match &w.geometry {
            Some(RawGeometry::Table {
                pos,
                shift,
                radius,
                angle,
            }) => {
                let list = if key.starts_with("shift") {
                    shift
                } else if key.starts_with("radius") {
                    radius
                } else {
                    angle
                };
                item(key)
                    .and_then(|i| list.get(i))
                    .map(|f| f.pos)
                    .or(Some(*pos))
            }
            _ => None,
        },
        ["creep", key] => w.creep.as_ref().and_then(|c| {
            match *key {
                "young" => written(&c.young),
                "poisson" => written(&c.poisson),
                "friction" => written(&c.friction),
                "rail_radius" => written(&c.rail_radius),
                "wheel_profile_radius" => written(&c.wheel_profile_radius),
                _ => None,
            }
            .or(Some(c.pos))
        }),
        ["flange", key] => w.flange.as_ref().and_then(|f| {
            match *key {
                "clearance" => written(&f.clearance),
                "stiffness" => written(&f.stiffness),
                _ => None,
            }
            .or(Some(f.pos))
        }),
        _ => None,
    }
}

/// Domain and restraint checks at the nominal values.
pub fn nominal_checks(system: &System, raw: &RawDescription, diag: &mut Diagnostics) {
    let model = match system.instantiate_all(&system.nominal()) {
        Ok(m) => m,
        Err(errors) => {
            for e in errors {
                diag.push(
                    position(raw, &e.path),
                    format!("at the nominal values, {e}"),
                );
            }
            return;
        }
    };
    let n = system.dofs.len();
    let mut k = vec![vec![0.0; n]; n];
    for e in &model.elements {
        let stiffness = match &e.law {
            ModelLaw::SpringDamper { k, .. } => *k,
            ModelLaw::Hertz { .. } | ModelLaw::Table { .. } | ModelLaw::Wheel(_) => 1.0,
        };
        let mut b = vec![e.incidence(n)];
        // A wheel holds its wheelset laterally and in yaw too (creep, gravity, flange).
        if let Some(w) = e.law.wheel() {
            b.extend(w.tangential_incidence(n));
        }
        for b in &b {
            for i in 0..n {
                for j in 0..n {
                    k[i][j] += stiffness * b[i] * b[j];
                }
            }
        }
    }
    // Every unrestrained DOF, one problem per body.
    let free = unrestrained(&mut k);
    for (bi, body) in system.bodies.iter().enumerate() {
        let dofs: Vec<&str> = free
            .iter()
            .filter(|&&d| system.dofs[d].body == bi)
            .map(|&d| system.dofs[d].name.as_str())
            .collect();
        if dofs.is_empty() {
            continue;
        }
        let pos = raw
            .bodies
            .iter()
            .find(|b| b.name == body.name)
            .map_or(Pos { line: 1, col: 1 }, |b| b.pos);
        let (noun, verb) = if dofs.len() == 1 {
            ("DOF", "is")
        } else {
            ("DOFs", "are")
        };
        diag.push(
            pos,
            format!(
                "bodies.{}: {noun} `{}` {verb} not restrained by any element (the static problem is singular); connect the body so that every DOF is held, e.g. a pitch needs elements at two different points",
                body.name,
                dofs.join("`, `")
            ),
        );
    }
}

/// The DOFs whose pivot vanishes in the Cholesky factorisation of `k` scaled to unit diagonal
/// (empty when `k` is positive definite). A DOF found free is taken out (its pivot set to 1,
/// its column of the factor to 0) and the factorisation goes on, so every free DOF is named.
fn unrestrained(k: &mut [Vec<f64>]) -> Vec<usize> {
    let n = k.len();
    // A DOF without any stiffness: its row and column are zero (K is a sum of b b^T).
    let mut free: Vec<usize> = (0..n)
        .filter(|&i| k[i][i].is_nan() || k[i][i] <= 0.0)
        .collect();
    for &i in &free {
        for row in k.iter_mut() {
            row[i] = 0.0;
        }
        k[i].fill(0.0);
        k[i][i] = 1.0;
    }
    let scale: Vec<f64> = (0..n).map(|i| k[i][i]).collect();
    for i in 0..n {
        for j in 0..n {
            k[i][j] /= (scale[i] * scale[j]).sqrt();
        }
    }
    for j in 0..n {
        let d = k[j][j] - k[j][..j].iter().map(|x| x * x).sum::<f64>();
        if d.is_nan() || d <= PIVOT_TOLERANCE {
            free.push(j);
            k[j][j] = 1.0;
            for row in k.iter_mut().skip(j + 1) {
                row[j] = 0.0;
            }
            continue;
        }
        let d = d.sqrt();
        k[j][j] = d;
        for i in j + 1..n {
            let s = k[i][j] - (0..j).map(|p| k[i][p] * k[j][p]).sum::<f64>();
            k[i][j] = s / d;
        }
    }
    free.sort_unstable();
    free.dedup();
    free
}
