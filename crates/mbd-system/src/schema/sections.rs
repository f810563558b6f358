//! The readers of the parse step, one per section of a description: each takes its YAML node,
//! checks the entry's shape (the fields it may have, their kinds, names and ranges) and returns
//! the typed record of [`super`], every problem going to the diagnostics with its line.

use super::*;
use crate::diag::Diagnostics;
use crate::reader::{read_expr, read_names, read_pair, valid_name, MapReader};
use crate::yaml::Node;

const TOP: [&str; 16] = [
    "format",
    "name",
    "doc",
    "parameters",
    "bodies",
    "beams",
    "moving",
    "sensors",
    "profiles",
    "elements",
    "loads",
    "outputs",
    "indices",
    "railway",
    "lateral",
    "indices_from",
];

/// Reads the whole description (the parse step); problems go to `diag`.
pub fn read(root: &Node, diag: &mut Diagnostics) -> RawDescription {
    let mut out = RawDescription::default();
    let Some(mut top) = MapReader::new(root, "description", diag) else {
        return out;
    };
    match top.required("format", diag) {
        Some(n) if n.as_number() == Some(FORMAT_VERSION as f64) => {}
        Some(n) => diag.push(
            n.pos,
            format!(
                "format: this program reads format {FORMAT_VERSION}, found {}",
                n.describe()
            ),
        ),
        None => {}
    }
    if let Some((name, _)) = top.required_string("name", diag) {
        out.name = name;
    }
    out.doc = top.string("doc", diag).map(|d| d.0);
    let parameters = named_entries(&mut top, "parameters", diag);
    let bodies = named_entries(&mut top, "bodies", diag);
    let beams = named_entries(&mut top, "beams", diag);
    let sensors = named_entries(&mut top, "sensors", diag);
    let profiles = named_entries(&mut top, "profiles", diag);
    let elements = named_entries(&mut top, "elements", diag);
    let loads = named_entries(&mut top, "loads", diag);
    let indices = named_entries(&mut top, "indices", diag);
    out.parameters = read_entries(&parameters, parameter, diag);
    out.bodies = read_entries(&bodies, body, diag);
    out.beams = read_entries(&beams, beam, diag);
    out.sensors = read_entries(&sensors, sensor, diag);
    out.profiles = read_entries(&profiles, profile, diag);
    out.elements = read_entries(&elements, element, diag);
    out.loads = read_entries(&loads, load, diag);
    out.indices = read_entries(&indices, index, diag);
    if let Some(node) = top.get("moving") {
        out.moving = moving(node, diag);
    }
    if let Some(node) = top.get("outputs") {
        out.outputs = read_names(node, "outputs", diag);
    }
    if let Some(node) = top.get("railway") {
        out.railway = railway(node, diag);
    }
    if let Some(node) = top.get("lateral") {
        out.lateral = lateral(node, diag);
    }
    out.indices_from = top.number("indices_from", diag);
    top.finish(&TOP, diag);
    out
}

/// The entries of the section `name` (a mapping of names to entries), each with its name and
/// where the name was written; an invalid name is reported and its entry left out.
fn named_entries(
    top: &mut MapReader,
    name: &str,
    diag: &mut Diagnostics,
) -> Vec<(String, Pos, Node)> {
    let Some(node) = top.get(name) else {
        return Vec::new();
    };
    let Some(mut m) = MapReader::new(node, name, diag) else {
        return Vec::new();
    };
    m.entries()
        .iter()
        .filter_map(|(k, v)| {
            if valid_name(&k.name) {
                Some((k.name.clone(), k.pos, v.clone()))
            } else {
                diag.push(
                    k.pos,
                    format!(
                        "{name}: `{}` is not a valid name (letters, digits and `_`, at most 64)",
                        k.name
                    ),
                );
                None
            }
        })
        .collect()
}

/// Reads every entry of a section with `entry` (name, where, node), keeping those it reads.
fn read_entries<T>(
    entries: &[(String, Pos, Node)],
    entry: fn(&str, Pos, &Node, &mut Diagnostics) -> Option<T>,
    diag: &mut Diagnostics,
) -> Vec<T> {
    entries
        .iter()
        .filter_map(|(n, p, v)| entry(n, *p, v, diag))
        .collect()
}

/// One entry of `sensors`.
fn sensor(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawSensor> {
    let mut m = MapReader::new(node, &format!("sensors.{name}"), diag)?;
    let s = RawSensor {
        name: name.to_owned(),
        pos,
        on: m.required_string("on", diag),
        x: m.required_expr("x", diag),
    };
    m.finish(&["on", "x"], diag);
    Some(s)
}

/// One entry of `loads`.
fn load(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawLoad> {
    let mut m = MapReader::new(node, &format!("loads.{name}"), diag)?;
    let l = RawLoad {
        name: name.to_owned(),
        pos,
        at: m.required_string("at", diag),
        force: m.required_expr("force", diag),
        direction: direction(&mut m, &format!("loads.{name}"), diag),
    };
    m.finish(&["at", "force", "direction"], diag);
    Some(l)
}

fn parameter(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawParameter> {
    let what = format!("parameters.{name}");
    let mut m = MapReader::new(node, &what, diag)?;
    let unit = m.required_string("unit", diag).map(|u| u.0);
    let doc = m.string("doc", diag).map(|d| d.0);
    let nominal = m.number("nominal", diag);
    let value = m.number("value", diag);
    let expr = m.expr("expr", diag);
    let range = m.get("range");
    m.finish(&["unit", "doc", "nominal", "range", "value", "expr"], diag);
    // A field written but not readable is reported already; no follow-on about the kind.
    let written = |key: &str| {
        node.as_map()
            .is_some_and(|e| e.iter().any(|(k, _)| k.name == key))
    };
    if (nominal.is_none() && written("nominal"))
        || (value.is_none() && written("value"))
        || (expr.is_none() && written("expr"))
    {
        return None;
    }
    let kind = match (nominal, range, value, expr) {
        (Some((nominal, _)), Some(r), None, None) => {
            let range = read_range(r, nominal, &format!("{what}.range"), diag)?;
            ParamKind::Sampled { nominal, range }
        }
        (None, None, Some((value, _)), None) => ParamKind::Fixed { value },
        (None, None, None, Some(expr)) => ParamKind::Derived { expr },
        (None, Some(r), None, None) => {
            diag.push(
                r.pos,
                format!("{what}: a sampled parameter needs `nominal` beside `range`"),
            );
            return None;
        }
        (Some((_, p)), None, None, None) => {
            diag.push(
                p,
                format!(
                    "{what}: `nominal` needs a `range` (sampled); a fixed parameter uses `value`"
                ),
            );
            return None;
        }
        _ => {
            diag.push(
                pos,
                format!("{what}: give exactly one of `nominal` + `range` (sampled per sample), `value` (fixed) or `expr` (derived)"),
            );
            return None;
        }
    };
    Some(RawParameter {
        name: name.to_owned(),
        pos,
        unit: unit?,
        doc,
        kind,
    })
}

/// `[min, max]` or `{factor: [lo, hi]}` (relative to the nominal value).
fn read_range(node: &Node, nominal: f64, what: &str, diag: &mut Diagnostics) -> Option<[f64; 2]> {
    let [lo, hi] = if node.as_map().is_some() {
        let mut m = MapReader::new(node, what, diag)?;
        let factor = m.required("factor", diag);
        m.finish(&["factor"], diag);
        let [a, b] = read_pair(factor?, &format!("{what}.factor"), diag)?;
        [nominal * a, nominal * b]
    } else {
        read_pair(node, what, diag)?
    };
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        diag.push(
            node.pos,
            format!("{what}: [{lo}, {hi}] is empty or inverted; need finite min < max"),
        );
        return None;
    }
    if !(lo <= nominal && nominal <= hi) {
        diag.push(
            node.pos,
            format!("{what}: the nominal value {nominal} is outside [{lo}, {hi}]"),
        );
        return None;
    }
    Some([lo, hi])
}

fn body(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawBody> {
    let what = format!("bodies.{name}");
    let mut m = MapReader::new(node, &what, diag)?;
    let mass = m.required_expr("mass", diag);
    let inertia_node = m.get("inertia");
    let doc = m.string("doc", diag).map(|d| d.0);
    let mut dofs = Vec::new();
    if let Some(n) = m.required("dofs", diag) {
        let allowed: Vec<&str> = DofKind::ALL.iter().map(|k| k.keyword()).collect();
        for (kw, p) in read_names(n, &format!("{what}.dofs"), diag) {
            let Some(kind) = DofKind::from_keyword(&kw) else {
                diag.push(
                    p,
                    format!(
                        "{what}.dofs: unknown DOF `{kw}`; allowed: {} (z vertical, pitch, y lateral, roll, yaw, x longitudinal)",
                        allowed.join(", ")
                    ),
                );
                continue;
            };
            if dofs.iter().any(|(k, _)| *k == kind) {
                diag.push(p, format!("{what}.dofs: `{kw}` listed twice"));
                continue;
            }
            dofs.push((kind, p));
        }
        if dofs.is_empty() && n.as_seq().is_some() {
            diag.push(
                n.pos,
                format!("{what}.dofs: a body needs at least one DOF (z, pitch, y, roll, yaw, x)"),
            );
        }
    }
    let (inertia, inertia_scalar) = match inertia_node {
        None => (Vec::new(), false),
        Some(n) if n.as_map().is_some() => (inertia_axes(n, &what, diag), false),
        Some(n) => (
            read_expr(n, &format!("{what}.inertia"), diag)
                .map(|f| vec![(DofKind::Pitch, f)])
                .unwrap_or_default(),
            true,
        ),
    };
    let mut points = Vec::new();
    if let Some(n) = m.get("points") {
        if let Some(mut pm) = MapReader::new(n, &format!("{what}.points"), diag) {
            for (k, v) in pm.entries() {
                if !valid_name(&k.name) {
                    diag.push(
                        k.pos,
                        format!("{what}.points: `{}` is not a valid name", k.name),
                    );
                    continue;
                }
                if let Some(p) = point(
                    &k.name,
                    k.pos,
                    v,
                    &format!("{what}.points.{}", k.name),
                    diag,
                ) {
                    points.push(p);
                }
            }
        }
    }
    m.finish(&["mass", "inertia", "dofs", "points", "doc"], diag);
    Some(RawBody {
        name: name.to_owned(),
        pos,
        mass,
        inertia,
        inertia_scalar,
        inertia_pos: inertia_node.map(|n| n.pos),
        dofs,
        points,
        doc,
    })
}

/// `inertia: {roll: .., pitch: .., yaw: ..}` (kg m^2, each optional).
fn inertia_axes(node: &Node, what: &str, diag: &mut Diagnostics) -> Vec<(DofKind, Field)> {
    let w = format!("{what}.inertia");
    let Some(mut m) = MapReader::new(node, &w, diag) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for kind in [DofKind::Roll, DofKind::Pitch, DofKind::Yaw] {
        if let Some(f) = m.expr(kind.keyword(), diag) {
            out.push((kind, f));
        }
    }
    m.finish(&["roll", "pitch", "yaw"], diag);
    out
}

/// A body point: `x` (a number or expression) or `[x, y, z]` (m; `y` right, `z` down).
fn point(
    name: &str,
    pos: Pos,
    node: &Node,
    what: &str,
    diag: &mut Diagnostics,
) -> Option<RawPoint> {
    let Some(items) = node.as_seq() else {
        return read_expr(node, what, diag).map(|x| RawPoint {
            name: name.to_owned(),
            pos,
            x,
            y: None,
            z: None,
        });
    };
    if items.len() != 3 {
        diag.push(
            node.pos,
            format!(
                "{what}: a point is `x` or `[x, y, z]` (m: forward, right, down of the centre), found {} values",
                items.len()
            ),
        );
        return None;
    }
    let axes: Vec<Option<Field>> = ["x", "y", "z"]
        .iter()
        .zip(items)
        .map(|(a, n)| read_expr(n, &format!("{what}.{a}"), diag))
        .collect();
    let [x, y, z]: [Option<Field>; 3] = axes.try_into().ok()?;
    Some(RawPoint {
        name: name.to_owned(),
        pos,
        x: x?,
        y: Some(y?),
        z: Some(z?),
    })
}

/// `direction:` of an element or load: `x`, `y` or `z` (the default).
fn direction(m: &mut MapReader, what: &str, diag: &mut Diagnostics) -> (Axis, Option<Pos>) {
    match m.string("direction", diag) {
        None => (Axis::Z, None),
        Some((k, p)) => match Axis::from_keyword(&k) {
            Some(a) => (a, Some(p)),
            None => {
                diag.push(
                    p,
                    format!(
                        "{what}.direction: `{k}`; allowed: x (forward), y (right), z (down, the default)"
                    ),
                );
                (Axis::Z, Some(p))
            }
        },
    }
}

fn link(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<RawLink> {
    let mut m = MapReader::new(node, what, diag)?;
    let l = RawLink {
        pos: node.pos,
        k: m.required_expr("k", diag),
        c: m.expr("c", diag),
    };
    m.finish(&["k", "c"], diag);
    Some(l)
}

fn beam(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawBeam> {
    let what = format!("beams.{name}");
    let mut m = MapReader::new(node, &what, diag)?;
    let outside = match m.string("outside", diag) {
        None => Outside::Refuse,
        Some((s, p)) => match s.as_str() {
            "refuse" => Outside::Refuse,
            "rigid" => Outside::Rigid,
            other => {
                diag.push(p, format!("{what}.outside: `{other}`; allowed: refuse (points must stay on the beam), rigid (off the beam a point rests on rigid ground)"));
                Outside::Refuse
            }
        },
    };
    let supports = m.get("supports").and_then(|n| {
        let w = format!("{what}.supports");
        let mut s = MapReader::new(n, &w, diag)?;
        let levels = match s.required("levels", diag) {
            Some(l) => match l.as_seq() {
                Some(items) => items
                    .iter()
                    .enumerate()
                    .filter_map(|(i, item)| {
                        let lw = format!("{w}.levels[{i}]");
                        let mut lm = MapReader::new(item, &lw, diag)?;
                        let lv = RawLevel {
                            name: lm
                                .required_string("name", diag)
                                .map_or_else(String::new, |n| n.0),
                            pos: item.pos,
                            mass: lm.required_expr("mass", diag),
                            link: lm
                                .required("link", diag)
                                .and_then(|n| link(n, &format!("{lw}.link"), diag)),
                            shear: lm
                                .get("shear")
                                .and_then(|n| link(n, &format!("{lw}.shear"), diag)),
                        };
                        lm.finish(&["name", "mass", "link", "shear"], diag);
                        Some(lv)
                    })
                    .collect(),
                None => {
                    diag.push(
                        l.pos,
                        format!("{w}.levels: expected a list of levels from the beam down"),
                    );
                    Vec::new()
                }
            },
            None => Vec::new(),
        };
        let r = RawSupports {
            pos: n.pos,
            spacing: s.required_expr("spacing", diag),
            count: s.required_expr("count", diag),
            first: s.expr("first", diag),
            levels,
            ground: s
                .required("ground", diag)
                .and_then(|g| link(g, &format!("{w}.ground"), diag)),
        };
        s.finish(&["spacing", "count", "first", "levels", "ground"], diag);
        Some(r)
    });
    let b = RawBeam {
        name: name.to_owned(),
        pos,
        length: m.required_expr("length", diag),
        modes: m.required_expr("modes", diag),
        mass_per_length: m.required_expr("mass_per_length", diag),
        bending_stiffness: m.required_expr("bending_stiffness", diag),
        damping_ratio: m.expr("damping_ratio", diag),
        outside,
        supports,
        doc: m.string("doc", diag).map(|d| d.0),
    };
    m.finish(
        &[
            "length",
            "modes",
            "mass_per_length",
            "bending_stiffness",
            "damping_ratio",
            "outside",
            "supports",
            "doc",
        ],
        diag,
    );
    Some(b)
}

fn moving(node: &Node, diag: &mut Diagnostics) -> Option<RawMoving> {
    let mut m = MapReader::new(node, "moving", diag)?;
    let speed = m.required_expr("speed", diag);
    let mut points = Vec::new();
    if let Some(pn) = m.required("points", diag) {
        if let Some(mut pm) = MapReader::new(pn, "moving.points", diag) {
            for (k, v) in pm.entries() {
                if !valid_name(&k.name) {
                    diag.push(
                        k.pos,
                        format!("moving.points: `{}` is not a valid name", k.name),
                    );
                    continue;
                }
                let w = format!("moving.points.{}", k.name);
                let Some(mut e) = MapReader::new(v, &w, diag) else {
                    continue;
                };
                points.push(RawMovingPoint {
                    name: k.name.clone(),
                    pos: k.pos,
                    on: e.required_string("on", diag),
                    offset: e.required_expr("offset", diag),
                });
                e.finish(&["on", "offset"], diag);
            }
        }
    }
    m.finish(&["speed", "points"], diag);
    Some(RawMoving {
        pos: node.pos,
        speed,
        points,
    })
}

fn profile(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawProfile> {
    let what = format!("profiles.{name}");
    let mut m = MapReader::new(node, &what, diag)?;
    let kind = match m.required_string("kind", diag) {
        Some((k, p)) => match k.as_str() {
            "generated" => generated_profile(m, &what, pos, diag)?,
            "harmonic" => {
                let k = RawProfileKind::Harmonic {
                    amplitude: m.required_expr("amplitude", diag),
                    wavelength: m.required_expr("wavelength", diag),
                    phase: m.expr("phase", diag),
                };
                m.finish(&["kind", "amplitude", "wavelength", "phase"], diag);
                k
            }
            "combination" => combination_profile(m, &what, diag),
            other => {
                diag.push(p, format!("{what}.kind: `{other}`; allowed: generated (random-phase from a spectrum, one per sample), harmonic (analytic), combination (a weighted sum of others)"));
                return None;
            }
        },
        None => return None,
    };
    Some(RawProfile {
        name: name.to_owned(),
        pos,
        kind,
    })
}

/// The fields of a `generated` profile (`m` its mapping, `pos` where it is declared): its
/// wavelengths, spectrum, interpolation and optional end; `None` when one cannot be read.
fn generated_profile(
    mut m: MapReader,
    what: &str,
    pos: Pos,
    diag: &mut Diagnostics,
) -> Option<RawProfileKind> {
    let wavelengths = m
        .required("wavelengths", diag)
        .and_then(|n| read_pair(n, &format!("{what}.wavelengths"), diag));
    let psd = m
        .required("psd", diag)
        .and_then(|n| psd(n, &format!("{what}.psd"), diag));
    let interpolation = match m.string("interpolation", diag) {
        None => (Interpolation::default(), pos),
        Some((k, p)) => match Interpolation::from_keyword(&k) {
            Some(i) => (i, p),
            None => {
                let allowed: Vec<&str> = Interpolation::ALL.iter().map(|(_, k)| *k).collect();
                diag.push(
                    p,
                    format!(
                        "{what}.interpolation: `{k}`; allowed: {} (default linear)",
                        allowed.join(", ")
                    ),
                );
                return None;
            }
        },
    };
    let until = m.get("until").and_then(|n| {
        let mut u = MapReader::new(n, &format!("{what}.until"), diag)?;
        let x = u.required_expr("x", diag);
        let taper = u.required_expr("taper", diag);
        u.finish(&["x", "taper"], diag);
        Some((x?, taper?))
    });
    m.finish(
        &["kind", "psd", "wavelengths", "interpolation", "until"],
        diag,
    );
    let wavelengths = wavelengths?;
    if !(wavelengths[0] > 0.0 && wavelengths[0] < wavelengths[1]) {
        diag.push(
            pos,
            format!("{what}.wavelengths: need 0 < min < max (m), found {wavelengths:?}"),
        );
        return None;
    }
    Some(RawProfileKind::Generated {
        psd: psd?,
        wavelengths,
        interpolation,
        until,
    })
}

/// The weighted terms of a `combination` profile (`m` its mapping).
fn combination_profile(mut m: MapReader, what: &str, diag: &mut Diagnostics) -> RawProfileKind {
    let mut terms = Vec::new();
    if let Some(n) = m.required("of", diag) {
        if let Some(mut om) = MapReader::new(n, &format!("{what}.of"), diag) {
            for (k, v) in om.entries() {
                if let Some(w) =
                    crate::reader::read_number(v, &format!("{what}.of.{}", k.name), diag)
                {
                    terms.push(((k.name.clone(), k.pos), w));
                }
            }
            if terms.is_empty() && n.as_map().is_some() {
                diag.push(
                    n.pos,
                    format!("{what}.of: at least one profile with its weight"),
                );
            }
        }
    }
    m.finish(&["kind", "of"], diag);
    RawProfileKind::Combination { terms }
}

/// `{iso8608: C}`, `{fra: {class: 5, irregularity: vertical}}`, or
/// `{unit: "mm^2 m" | "m^3", segments: [{f_start, a, n}, ...]}`; returns the spectrum in the
/// generator's unit (segments with `a` in mm^2 m).
fn psd(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<RawPsd> {
    let mut m = MapReader::new(node, what, diag)?;
    if let Some(n) = m.get("fra") {
        m.finish(&["fra"], diag);
        return fra(n, &format!("{what}.fra"), diag);
    }
    if let Some((class, p)) = m.string("iso8608", diag) {
        m.finish(&["iso8608"], diag);
        let Some(&(_, g0)) = ISO8608_CLASSES.iter().find(|c| c.0 == class) else {
            let known: Vec<&str> = ISO8608_CLASSES.iter().map(|c| c.0).collect();
            diag.push(
                p,
                format!(
                    "{what}.iso8608: unknown road class `{class}`; allowed: {}",
                    known.join(", ")
                ),
            );
            return None;
        };
        // G_d(n) = g0 (n / 0.1)^-2 = (g0 0.01) n^-2 m^3 = (g0 0.01 1e6) n^-2 mm^2 m.
        return Some(RawPsd::PowerLaw(vec![RawPsdSegment {
            f_start: 0.0,
            a: g0 * 0.01 * 1e6,
            n: 2.0,
        }]));
    }
    let scale = match m.required_string("unit", diag) {
        Some((u, p)) => match u.as_str() {
            "mm^2 m" => 1.0,
            "m^3" => 1e6,
            other => {
                diag.push(p, format!("{what}.unit: `{other}`; allowed: \"mm^2 m\" (track spectra, mm^2/(1/m)), \"m^3\" (road spectra, m^2/(cycles/m))"));
                return None;
            }
        },
        None => return None,
    };
    let segments = m.required("segments", diag);
    m.finish(&["unit", "segments", "iso8608", "fra"], diag);
    let items = segments?.as_seq().or_else(|| {
        diag.push(
            node.pos,
            format!("{what}.segments: expected a list of {{f_start, a, n}}"),
        );
        None
    })?;
    let mut out = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let w = format!("{what}.segments[{i}]");
        let mut s = MapReader::new(item, &w, diag)?;
        let f_start = s.number("f_start", diag);
        let a = s.number("a", diag);
        let n = s.number("n", diag);
        s.finish(&["f_start", "a", "n"], diag);
        let (Some((f_start, fp)), Some((a, ap)), Some((n, _))) = (f_start, a, n) else {
            diag.push(item.pos, format!("{w}: needs f_start (1/m), a and n"));
            continue;
        };
        if i == 0 && f_start != 0.0 {
            diag.push(fp, format!("{w}.f_start: the first segment starts at 0"));
        }
        if i > 0 && f_start <= out.last().map_or(0.0, |s: &RawPsdSegment| s.f_start) {
            diag.push(
                fp,
                format!("{w}.f_start: must be above the previous segment's"),
            );
        }
        if a.is_nan() || a <= 0.0 {
            diag.push(ap, format!("{w}.a: must be > 0"));
        }
        out.push(RawPsdSegment {
            f_start,
            a: a * scale,
            n,
        });
    }
    if out.is_empty() {
        diag.push(node.pos, format!("{what}.segments: at least one segment"));
        return None;
    }
    Some(RawPsd::PowerLaw(out))
}

/// `{class: 1..6, irregularity: vertical | alignment | cross_level}`: an FRA track class's
/// spectrum ([`fra::fra_psd`]).
fn fra(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<RawPsd> {
    let mut m = MapReader::new(node, what, diag)?;
    let class = m.required("class", diag).and_then(|n| {
        crate::reader::read_number(n, &format!("{what}.class"), diag).map(|v| (v, n.pos))
    });
    let irregularity = m.required_string("irregularity", diag);
    m.finish(&["class", "irregularity"], diag);
    let classes = 1..=fra::FRA_CLASSES.len();
    let class = class.and_then(|(v, p)| {
        let found = classes.clone().find(|&c| c as f64 == v);
        if found.is_none() {
            let allowed: Vec<String> = classes.map(|c| c.to_string()).collect();
            diag.push(
                p,
                format!(
                    "{what}.class: {v}; allowed: {} (FRA track classes, 6 the best)",
                    allowed.join(", ")
                ),
            );
        }
        found
    });
    let kind = irregularity.and_then(|(k, p)| {
        let found = fra::FraIrregularity::from_keyword(&k);
        if found.is_none() {
            let allowed: Vec<&str> = fra::FraIrregularity::ALL.iter().map(|(_, k)| *k).collect();
            diag.push(
                p,
                format!(
                    "{what}.irregularity: unknown irregularity `{k}`; allowed: {}",
                    allowed.join(", ")
                ),
            );
        }
        found
    });
    fra::fra_psd(class?, kind?)
}

fn element(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawElement> {
    let what = format!("elements.{name}");
    let mut m = MapReader::new(node, &what, diag)?;
    let (kind, kpos) = m.required_string("kind", diag)?;
    if kind == "wheelset" {
        return wheelset(name, pos, m, diag);
    }
    let from = m.required_string("from", diag);
    let to = m.required_string("to", diag);
    let profile = m.string("profile", diag);
    let common = ["kind", "from", "to", "profile"];
    let mut directed = false;
    let (law, extra): (RawLaw, &[&str]) = match kind.as_str() {
        "spring_damper" => {
            directed = true;
            (
                RawLaw::SpringDamper {
                    k: m.required_expr("k", diag),
                    c: m.expr("c", diag),
                    preload: m.expr("preload", diag),
                },
                &["k", "c", "preload"],
            )
        }
        "hertz" => (
            RawLaw::Hertz {
                g: m.required_expr("g", diag),
                exponent: m.expr("exponent", diag),
            },
            &["g", "exponent"],
        ),
        "table" => {
            directed = true;
            let deflection = expr_list(&mut m, "deflection", &what, diag);
            let force = expr_list(&mut m, "force", &what, diag);
            if deflection.len() != force.len() || deflection.len() < 2 {
                diag.push(pos, format!("{what}: `deflection` and `force` need the same length, at least 2 (found {} and {})", deflection.len(), force.len()));
            }
            (
                RawLaw::Table {
                    deflection,
                    force,
                    c: m.expr("c", diag),
                },
                &["deflection", "force", "c"],
            )
        }
        other => {
            diag.push(
                kpos,
                format!("{what}.kind: `{other}`; allowed: spring_damper, hertz, table, wheelset"),
            );
            return None;
        }
    };
    let direction = if directed {
        direction(&mut m, &what, diag)
    } else {
        (Axis::Z, None)
    };
    let directions: &[&str] = if directed { &["direction"] } else { &[] };
    let allowed: Vec<&str> = common
        .iter()
        .chain(extra)
        .chain(directions)
        .copied()
        .collect();
    m.finish(&allowed, diag);
    Some(RawElement {
        name: name.to_owned(),
        pos,
        law,
        direction,
        from,
        to,
        profile,
    })
}

/// `kind: wheelset`: the wheelset body (`from`), the rail points, profiles and lateral rail
/// bodies of its left and right wheel (pairs), its dimensions, contact geometry, creep and
/// flange.
fn wheelset(name: &str, pos: Pos, mut m: MapReader, diag: &mut Diagnostics) -> Option<RawElement> {
    let what = format!("elements.{name}");
    let from = m.required_string("from", diag);
    let (rails, rails_pos) = wheel_names(&mut m, "rails", true, &what, pos, diag);
    let (profiles, _) = wheel_names(&mut m, "profiles", false, &what, pos, diag);
    let (lateral_rails, _) = wheel_names(&mut m, "lateral_rails", false, &what, pos, diag);
    let geometry = contact_geometry(&mut m, &what, pos, diag);
    let creep = m
        .required("creep", diag)
        .and_then(|n| creep(n, &format!("{what}.creep"), diag));
    let flange = m.get("flange").and_then(|n| {
        let mut f = MapReader::new(n, &format!("{what}.flange"), diag)?;
        let r = RawFlange {
            pos: n.pos,
            clearance: f.required_expr("clearance", diag),
            stiffness: f.required_expr("stiffness", diag),
        };
        f.finish(&["clearance", "stiffness"], diag);
        Some(r)
    });
    let w = RawWheelset {
        rails,
        profiles,
        lateral_rails,
        rails_pos,
        half_gauge: m.required_expr("half_gauge", diag),
        radius: m.required_expr("radius", diag),
        hertz: m.required_expr("hertz", diag),
        geometry,
        creep,
        flange,
    };
    m.finish(
        &[
            "kind",
            "from",
            "rails",
            "profiles",
            "lateral_rails",
            "half_gauge",
            "radius",
            "hertz",
            "conicity",
            "geometry",
            "creep",
            "flange",
        ],
        diag,
    );
    Some(RawElement {
        name: name.to_owned(),
        pos,
        law: RawLaw::Wheelset(Box::new(w)),
        direction: (Axis::Z, None),
        from,
        to: None,
        profile: None,
    })
}

/// A wheelset's list `key` of one name per wheel, `[left, right]` (refused unless 2), and
/// where it was written (the wheelset's `pos` when absent).
fn wheel_names(
    m: &mut MapReader,
    key: &str,
    required: bool,
    what: &str,
    pos: Pos,
    diag: &mut Diagnostics,
) -> (Vec<(String, Pos)>, Pos) {
    let node = if required {
        m.required(key, diag)
    } else {
        m.get(key)
    };
    let Some(node) = node else {
        return (Vec::new(), pos);
    };
    let names = read_names(node, &format!("{what}.{key}"), diag);
    if names.len() != 2 {
        diag.push(
            node.pos,
            format!(
                "{what}.{key}: one for each wheel, [left, right]: 2 names, found {}",
                names.len()
            ),
        );
    }
    (names, node.pos)
}

/// A wheelset's contact geometry: `conicity` or a `geometry` table, exactly one of them.
fn contact_geometry(
    m: &mut MapReader,
    what: &str,
    pos: Pos,
    diag: &mut Diagnostics,
) -> Option<RawGeometry> {
    let conicity = m.expr("conicity", diag);
    let table = m
        .get("geometry")
        .and_then(|n| geometry_table(n, &format!("{what}.geometry"), diag));
    match (conicity, table) {
        (Some(c), None) => Some(RawGeometry::Conicity(c)),
        (None, Some(t)) => Some(t),
        (None, None) => {
            diag.push(pos, format!("{what}: give the contact geometry: `conicity` (equivalent conicity, rad) or `geometry: {{shift, radius, angle}}`"));
            None
        }
        (Some(c), Some(_)) => {
            diag.push(
                c.pos,
                format!("{what}: give `conicity` or `geometry`, not both"),
            );
            None
        }
    }
}

/// A wheelset's `creep:` constants (`what` its path).
fn creep(n: &Node, what: &str, diag: &mut Diagnostics) -> Option<RawCreep> {
    let mut c = MapReader::new(n, what, diag)?;
    let r = RawCreep {
        pos: n.pos,
        young: c.required_expr("young", diag),
        poisson: c.required_expr("poisson", diag),
        friction: c.required_expr("friction", diag),
        rail_radius: c.required_expr("rail_radius", diag),
        wheel_profile_radius: c.expr("wheel_profile_radius", diag),
    };
    c.finish(
        &[
            "young",
            "poisson",
            "friction",
            "rail_radius",
            "wheel_profile_radius",
        ],
        diag,
    );
    Some(r)
}

/// The required list `key` of `m` (`what` its path), each item a number or an expression;
/// empty when absent or not a list (reported).
fn expr_list(m: &mut MapReader, key: &str, what: &str, diag: &mut Diagnostics) -> Vec<Field> {
    match m.required(key, diag) {
        Some(n) => match n.as_seq() {
            Some(items) => items
                .iter()
                .filter_map(|i| read_expr(i, &format!("{what}.{key}"), diag))
                .collect(),
            None => {
                diag.push(n.pos, format!("{what}.{key}: expected a list"));
                Vec::new()
            }
        },
        None => Vec::new(),
    }
}

/// `geometry: {shift: [...], radius: [...], angle: [...]}`, as many of each, at least 2.
fn geometry_table(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<RawGeometry> {
    let mut m = MapReader::new(node, what, diag)?;
    let shift = expr_list(&mut m, "shift", what, diag);
    let radius = expr_list(&mut m, "radius", what, diag);
    let angle = expr_list(&mut m, "angle", what, diag);
    m.finish(&["shift", "radius", "angle"], diag);
    if shift.len() < 2 || radius.len() != shift.len() || angle.len() != shift.len() {
        diag.push(
            node.pos,
            format!(
                "{what}: `shift`, `radius` and `angle` need the same length, at least 2 (found {}, {} and {})",
                shift.len(),
                radius.len(),
                angle.len()
            ),
        );
        return None;
    }
    Some(RawGeometry::Table {
        pos: node.pos,
        shift,
        radius,
        angle,
    })
}

fn index(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawIndex> {
    let what = format!("indices.{name}");
    let mut m = MapReader::new(node, &what, diag)?;
    let stat = m.required_string("stat", diag).and_then(|(s, p)| {
        match IndexStat::ALL.iter().find(|k| k.keyword() == s) {
            Some(k) => Some((*k, p)),
            None => {
                let known: Vec<&str> = IndexStat::ALL.iter().map(|k| k.keyword()).collect();
                diag.push(
                    p,
                    format!("{what}.stat: `{s}`; allowed: {}", known.join(", ")),
                );
                None
            }
        }
    });
    let limit = match m.get("limit") {
        None => None,
        Some(n) if n.is_null() => None,
        Some(n) => crate::reader::read_number(n, &format!("{what}.limit"), diag),
    };
    let i = RawIndex {
        name: name.to_owned(),
        pos,
        stat,
        channel: m.required_string("channel", diag),
        subtract: m.expr("subtract", diag),
        divide: m.expr("divide", diag),
        unit: m.string("unit", diag).map(|u| u.0),
        limit,
        doc: m.string("doc", diag).map(|d| d.0),
    };
    m.finish(
        &[
            "stat", "channel", "subtract", "divide", "unit", "limit", "doc",
        ],
        diag,
    );
    Some(i)
}

fn railway(node: &Node, diag: &mut Diagnostics) -> Option<RawRailway> {
    let mut m = MapReader::new(node, "railway", diag)?;
    let list = |m: &mut MapReader, key: &str, n: usize, diag: &mut Diagnostics| -> Vec<Named> {
        let Some(node) = m.required(key, diag) else {
            return Vec::new();
        };
        let names = read_names(node, &format!("railway.{key}"), diag);
        if names.len() != n {
            diag.push(node.pos, format!("railway.{key}: the railway indices are defined for a two-bogie, four-axle vehicle: {n} columns, found {}", names.len()));
        }
        names
    };
    let contact_forces = list(&mut m, "contact_forces", 4, diag);
    let bogies = list(&mut m, "bogies", 2, diag);
    let rails = list(&mut m, "rails", 4, diag);
    let car_body = m.required("car_body", diag).and_then(|n| {
        let mut c = MapReader::new(n, "railway.car_body", diag)?;
        let v = c.required_string("vertical", diag);
        let p = c.required_string("pitch", diag);
        c.finish(&["vertical", "pitch"], diag);
        Some((v?, p?))
    });
    let r = RawRailway {
        pos: node.pos,
        contact_forces,
        car_body,
        half_length: m.required_expr("half_length", diag),
        bogies,
        rails,
        static_wheel_load: m.required_expr("static_wheel_load", diag),
    };
    m.finish(
        &[
            "contact_forces",
            "car_body",
            "half_length",
            "bogies",
            "rails",
            "static_wheel_load",
        ],
        diag,
    );
    Some(r)
}

/// The `lateral` section.
fn lateral(node: &Node, diag: &mut Diagnostics) -> Option<RawLateral> {
    let mut m = MapReader::new(node, "lateral", diag)?;
    let wheelsets = m
        .required("wheelsets", diag)
        .map(|n| read_names(n, "lateral.wheelsets", diag))
        .unwrap_or_default();
    let car_body = m.required("car_body", diag).and_then(|n| {
        let mut c = MapReader::new(n, "lateral.car_body", diag)?;
        let l = c.required_string("lateral", diag);
        let y = c.required_string("yaw", diag);
        let r = c.required_string("roll", diag);
        c.finish(&["lateral", "yaw", "roll"], diag);
        Some([l?, y?, r?])
    });
    let limits = match m.get("limits") {
        None => RawLateralLimits::default(),
        Some(n) => {
            let mut l = MapReader::new(n, "lateral.limits", diag)?;
            let r = RawLateralLimits {
                derailment_quotient: l.number("derailment_quotient", diag),
                lateral_force: l.number("lateral_force", diag),
                sperling: l.number("sperling", diag),
                stability: l.number("stability", diag),
            };
            l.finish(
                &[
                    "derailment_quotient",
                    "lateral_force",
                    "sperling",
                    "stability",
                ],
                diag,
            );
            r
        }
    };
    let r = RawLateral {
        pos: node.pos,
        wheelsets,
        car_body,
        half_length: m.required_expr("half_length", diag),
        floor: m.required_expr("floor", diag),
        axle_load: m.required_expr("axle_load", diag),
        prudhomme: m.expr("prudhomme", diag),
        stability: m.string("stability", diag),
        limits,
    };
    m.finish(
        &[
            "wheelsets",
            "car_body",
            "half_length",
            "floor",
            "axle_load",
            "prudhomme",
            "stability",
            "limits",
        ],
        diag,
    );
    Some(r)
}
