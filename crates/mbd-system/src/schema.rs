//! The description as written: every section read from the YAML tree into typed records that
//! keep their positions (the *parse* step). Names are not resolved here (that is
//! [`crate::compile`]); only the shape of each entry is checked.
//!
//! Sections (`docs/systems.md` documents each field with its unit):
//! `format` (1), `name`, `doc`, `parameters`, `bodies`, `beams`, `moving`, `sensors`,
//! `profiles`, `elements`, `loads`, `outputs`, `indices`, `railway`, `indices_from`.

use crate::diag::Diagnostics;
use crate::reader::{read_expr, read_names, read_pair, valid_name, Field, MapReader};
use crate::system::Interpolation;
use crate::yaml::{Node, Pos};

/// The only format version this crate reads.
pub const FORMAT_VERSION: i64 = 1;

/// A name and where it was written.
pub type Named = (String, Pos);

/// How a parameter gets its value.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamKind {
    /// Drawn per sample, uniform on `range`; `nominal` is the default of a design.
    Sampled {
        /// Default value.
        nominal: f64,
        /// `[min, max]`.
        range: [f64; 2],
    },
    /// One value for every sample.
    Fixed {
        /// The value.
        value: f64,
    },
    /// Computed from other parameters.
    Derived {
        /// The expression.
        expr: Field,
    },
}

/// One entry of `parameters`.
#[derive(Debug, Clone, PartialEq)]
pub struct RawParameter {
    /// Its name.
    pub name: String,
    /// Where it was declared.
    pub pos: Pos,
    /// Unit, as text (`kg`, `N s/m`, `1`).
    pub unit: String,
    /// What it is.
    pub doc: Option<String>,
    /// Sampled, fixed or derived.
    pub kind: ParamKind,
}

/// Kinds of rigid-body degrees of freedom.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum DofKind {
    /// Vertical displacement (m, positive downward); column `z_<body>`.
    Z,
    /// Pitch rotation (rad, positive nose-up: the front rises); column `beta_<body>`.
    Pitch,
}

impl DofKind {
    /// The keyword in `dofs:`.
    pub fn keyword(self) -> &'static str {
        match self {
            DofKind::Z => "z",
            DofKind::Pitch => "pitch",
        }
    }

    /// The column prefix (`z`, `beta`).
    pub fn symbol(self) -> &'static str {
        match self {
            DofKind::Z => "z",
            DofKind::Pitch => "beta",
        }
    }

    /// Unit of the displacement.
    pub fn unit(self) -> &'static str {
        match self {
            DofKind::Z => "m",
            DofKind::Pitch => "rad",
        }
    }
}

/// One entry of `bodies`.
#[derive(Debug, Clone, PartialEq)]
pub struct RawBody {
    /// Its name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// Mass (kg).
    pub mass: Option<Field>,
    /// Pitch inertia about the centre (kg m^2), with a pitch DOF.
    pub inertia: Option<Field>,
    /// Its DOFs in the order written.
    pub dofs: Vec<(DofKind, Pos)>,
    /// Attachment points: name and longitudinal position `x` (m, forward positive).
    pub points: Vec<(String, Pos, Field)>,
    /// What it is.
    pub doc: Option<String>,
}

/// A spring-damper link of a support chain (`k` N/m, `c` N s/m).
#[derive(Debug, Clone, PartialEq)]
pub struct RawLink {
    /// Where.
    pub pos: Pos,
    /// Stiffness.
    pub k: Option<Field>,
    /// Damping (absent: 0).
    pub c: Option<Field>,
}

/// One level of a support chain.
#[derive(Debug, Clone, PartialEq)]
pub struct RawLevel {
    /// Name (sleeper, ballast, ...).
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// Mass per support (kg).
    pub mass: Option<Field>,
    /// The link to the level above (the beam for the first level).
    pub link: Option<RawLink>,
    /// Shear coupling to the neighbouring supports' masses of this level.
    pub shear: Option<RawLink>,
}

/// Discrete periodic supports of a beam.
#[derive(Debug, Clone, PartialEq)]
pub struct RawSupports {
    /// Where.
    pub pos: Pos,
    /// Spacing (m).
    pub spacing: Option<Field>,
    /// Number of supports.
    pub count: Option<Field>,
    /// Position of the first support (m, default 0).
    pub first: Option<Field>,
    /// Levels from the beam down.
    pub levels: Vec<RawLevel>,
    /// The link of the last level to the ground.
    pub ground: Option<RawLink>,
}

/// What a point off a beam sees.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outside {
    /// A point may never leave the beam (checked before the run).
    Refuse,
    /// Off the beam, a point rests on rigid level ground (approach embankments of a bridge).
    Rigid,
}

/// One entry of `beams`: a simply supported Euler-Bernoulli beam by modal superposition.
#[derive(Debug, Clone, PartialEq)]
pub struct RawBeam {
    /// Name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// Length `L` (m).
    pub length: Option<Field>,
    /// Number of modes.
    pub modes: Option<Field>,
    /// Mass per length (kg/m).
    pub mass_per_length: Option<Field>,
    /// Bending stiffness `E I` (N m^2).
    pub bending_stiffness: Option<Field>,
    /// Modal damping ratio (every mode), default 0.
    pub damping_ratio: Option<Field>,
    /// Points off the beam.
    pub outside: Outside,
    /// Discrete supports.
    pub supports: Option<RawSupports>,
    /// What it is.
    pub doc: Option<String>,
}

/// A point of the moving frame.
#[derive(Debug, Clone, PartialEq)]
pub struct RawMovingPoint {
    /// Name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// The beam it runs on, or `ground`.
    pub on: Option<Named>,
    /// Position relative to the frame origin (m, forward positive).
    pub offset: Option<Field>,
}

/// The frame moving along the beams at `speed`.
#[derive(Debug, Clone, PartialEq)]
pub struct RawMoving {
    /// Where.
    pub pos: Pos,
    /// Speed (m/s).
    pub speed: Option<Field>,
    /// Its points.
    pub points: Vec<RawMovingPoint>,
}

/// A fixed measuring point on a beam.
#[derive(Debug, Clone, PartialEq)]
pub struct RawSensor {
    /// Name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// The beam.
    pub on: Option<Named>,
    /// Position along the beam (m).
    pub x: Option<Field>,
}

/// A displacement spectrum, piecewise power law `S(f) = a f^-n` from `f_start` (1/m).
#[derive(Debug, Clone, PartialEq)]
pub struct RawPsdSegment {
    /// Lower bound (1/m).
    pub f_start: f64,
    /// Coefficient, in the profile's `unit`.
    pub a: f64,
    /// Exponent.
    pub n: f64,
}

/// How a profile is made.
#[derive(Debug, Clone, PartialEq)]
pub enum RawProfileKind {
    /// One random-phase realisation per sample, from a spectrum.
    Generated {
        /// Segments, their coefficient in mm^2 m (`a` scaled from `unit`).
        segments: Vec<RawPsdSegment>,
        /// Wavelength band `[min, max]` (m).
        wavelengths: [f64; 2],
        /// `interpolation:` (default linear) and where it is given (the profile's entry when
        /// not).
        interpolation: (Interpolation, Pos),
    },
    /// `eta(x) = amplitude sin(2 pi x / wavelength + phase)` (an analytic test input).
    Harmonic {
        /// Amplitude (m).
        amplitude: Option<Field>,
        /// Wavelength (m).
        wavelength: Option<Field>,
        /// Phase (rad), default 0.
        phase: Option<Field>,
    },
}

/// One entry of `profiles`: a vertical profile along the track or road (m, positive downward:
/// a dip).
#[derive(Debug, Clone, PartialEq)]
pub struct RawProfile {
    /// Name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// How it is made.
    pub kind: RawProfileKind,
}

/// The force law of an element.
#[derive(Debug, Clone, PartialEq)]
pub enum RawLaw {
    /// `f = preload + k d + c d'` (Kelvin-Voigt, two-sided).
    SpringDamper {
        /// Stiffness (N/m).
        k: Option<Field>,
        /// Damping (N s/m), default 0.
        c: Option<Field>,
        /// Force at zero deflection (N), default 0.
        preload: Option<Field>,
    },
    /// `f = (d / g)^exponent` for `d > 0`, else 0 (one-sided Hertz contact).
    Hertz {
        /// Contact constant `G` (m/N^(1/exponent)).
        g: Option<Field>,
        /// Exponent, default 3/2.
        exponent: Option<Field>,
    },
    /// `f = table(d) + c d'`, the table linearly interpolated and extended by its end slopes.
    Table {
        /// Deflections (m), increasing.
        deflection: Vec<Field>,
        /// Forces (N).
        force: Vec<Field>,
        /// Damping (N s/m), default 0.
        c: Option<Field>,
    },
}

impl RawLaw {
    /// The keyword of `kind:`.
    pub fn keyword(&self) -> &'static str {
        match self {
            RawLaw::SpringDamper { .. } => "spring_damper",
            RawLaw::Hertz { .. } => "hertz",
            RawLaw::Table { .. } => "table",
        }
    }
}

/// One entry of `elements`: a force element between two points, compression positive when
/// `from` moves down relative to `to`.
#[derive(Debug, Clone, PartialEq)]
pub struct RawElement {
    /// Name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// Its law.
    pub law: RawLaw,
    /// Upper end (a body point).
    pub from: Option<Named>,
    /// Lower end (a body point, a moving point or `ground`).
    pub to: Option<Named>,
    /// A profile under the lower end (a moving point).
    pub profile: Option<Named>,
}

/// One entry of `loads`: a constant downward force (N) at a point.
#[derive(Debug, Clone, PartialEq)]
pub struct RawLoad {
    /// Name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// The point (a body point or a moving point).
    pub at: Option<Named>,
    /// Force (N, downward positive).
    pub force: Option<Field>,
}

/// Statistics an index takes of a channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IndexStat {
    /// Largest value.
    Max,
    /// Smallest value.
    Min,
    /// Largest absolute value.
    MaxAbs,
    /// Root mean square.
    Rms,
    /// Largest minus smallest.
    PeakToPeak,
}

impl IndexStat {
    /// Keyword in the description.
    pub fn keyword(self) -> &'static str {
        match self {
            IndexStat::Max => "max",
            IndexStat::Min => "min",
            IndexStat::MaxAbs => "max_abs",
            IndexStat::Rms => "rms",
            IndexStat::PeakToPeak => "peak_to_peak",
        }
    }

    /// Every statistic.
    pub const ALL: [IndexStat; 5] = [
        IndexStat::Max,
        IndexStat::Min,
        IndexStat::MaxAbs,
        IndexStat::Rms,
        IndexStat::PeakToPeak,
    ];
}

/// One entry of `indices`: `stat(channel - subtract) / divide`, with an optional upper limit.
#[derive(Debug, Clone, PartialEq)]
pub struct RawIndex {
    /// Name (a column of the indices tables).
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// The statistic.
    pub stat: Option<(IndexStat, Pos)>,
    /// The channel (a stored column name).
    pub channel: Option<Named>,
    /// A value subtracted from the channel first (a static level), default 0.
    pub subtract: Option<Field>,
    /// A value the statistic is divided by (a static reference), default 1.
    pub divide: Option<Field>,
    /// Unit of the index, as text.
    pub unit: Option<String>,
    /// Pass when the index is at most this.
    pub limit: Option<f64>,
    /// What it is.
    pub doc: Option<String>,
}

/// The `railway` section: which stored columns the railway indices (`docs/indices.md`: wheel
/// loads, Sperling, car-body and bogie accelerations, rail deflection) read.
#[derive(Debug, Clone, PartialEq)]
pub struct RawRailway {
    /// Where.
    pub pos: Pos,
    /// The contact force of each wheel, front to rear (4).
    pub contact_forces: Vec<Named>,
    /// The car body's vertical and pitch accelerations.
    pub car_body: Option<(Named, Named)>,
    /// Half the distance between the bogie centres (m), for the accelerations over them.
    pub half_length: Option<Field>,
    /// Each bogie frame's vertical acceleration, front then rear (2).
    pub bogies: Vec<Named>,
    /// The rail deflection under each wheel (4).
    pub rails: Vec<Named>,
    /// The static wheel load (N) the wheel load reduction refers to.
    pub static_wheel_load: Option<Field>,
}

/// A description as written.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawDescription {
    /// The system's name.
    pub name: String,
    /// What it is.
    pub doc: Option<String>,
    /// `parameters`.
    pub parameters: Vec<RawParameter>,
    /// `bodies`.
    pub bodies: Vec<RawBody>,
    /// `beams`.
    pub beams: Vec<RawBeam>,
    /// `moving`.
    pub moving: Option<RawMoving>,
    /// `sensors`.
    pub sensors: Vec<RawSensor>,
    /// `profiles`.
    pub profiles: Vec<RawProfile>,
    /// `elements`.
    pub elements: Vec<RawElement>,
    /// `loads`.
    pub loads: Vec<RawLoad>,
    /// `outputs`: stored channels beyond the body DOFs.
    pub outputs: Vec<Named>,
    /// `indices`.
    pub indices: Vec<RawIndex>,
    /// `railway`.
    pub railway: Option<RawRailway>,
    /// `indices_from` (s) and where it was written.
    pub indices_from: Option<(f64, Pos)>,
}

const TOP: [&str; 15] = [
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
    let mut section = |name: &str, diag: &mut Diagnostics| -> Vec<(String, Pos, Node)> {
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
    };
    let parameters = section("parameters", diag);
    let bodies = section("bodies", diag);
    let beams = section("beams", diag);
    let sensors = section("sensors", diag);
    let profiles = section("profiles", diag);
    let elements = section("elements", diag);
    let loads = section("loads", diag);
    let indices = section("indices", diag);
    out.parameters = parameters
        .iter()
        .filter_map(|(n, p, v)| parameter(n, *p, v, diag))
        .collect();
    out.bodies = bodies
        .iter()
        .filter_map(|(n, p, v)| body(n, *p, v, diag))
        .collect();
    out.beams = beams
        .iter()
        .filter_map(|(n, p, v)| beam(n, *p, v, diag))
        .collect();
    out.sensors = sensors
        .iter()
        .filter_map(|(n, p, v)| {
            let mut m = MapReader::new(v, &format!("sensors.{n}"), diag)?;
            let s = RawSensor {
                name: n.clone(),
                pos: *p,
                on: m.required_string("on", diag),
                x: m.required_expr("x", diag),
            };
            m.finish(&["on", "x"], diag);
            Some(s)
        })
        .collect();
    out.profiles = profiles
        .iter()
        .filter_map(|(n, p, v)| profile(n, *p, v, diag))
        .collect();
    out.elements = elements
        .iter()
        .filter_map(|(n, p, v)| element(n, *p, v, diag))
        .collect();
    out.loads = loads
        .iter()
        .filter_map(|(n, p, v)| {
            let mut m = MapReader::new(v, &format!("loads.{n}"), diag)?;
            let l = RawLoad {
                name: n.clone(),
                pos: *p,
                at: m.required_string("at", diag),
                force: m.required_expr("force", diag),
            };
            m.finish(&["at", "force"], diag);
            Some(l)
        })
        .collect();
    out.indices = indices
        .iter()
        .filter_map(|(n, p, v)| index(n, *p, v, diag))
        .collect();
    if let Some(node) = top.get("moving") {
        out.moving = moving(node, diag);
    }
    if let Some(node) = top.get("outputs") {
        out.outputs = read_names(node, "outputs", diag);
    }
    if let Some(node) = top.get("railway") {
        out.railway = railway(node, diag);
    }
    out.indices_from = top.number("indices_from", diag);
    top.finish(&TOP, diag);
    out
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
    let inertia = m.expr("inertia", diag);
    let doc = m.string("doc", diag).map(|d| d.0);
    let mut dofs = Vec::new();
    if let Some(n) = m.required("dofs", diag) {
        for (kw, p) in read_names(n, &format!("{what}.dofs"), diag) {
            let kind = match kw.as_str() {
                "z" => DofKind::Z,
                "pitch" => DofKind::Pitch,
                other => {
                    diag.push(
                        p,
                        format!("{what}.dofs: unknown DOF `{other}`; allowed: z (vertical), pitch"),
                    );
                    continue;
                }
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
                format!("{what}.dofs: a body needs at least one DOF (z, pitch)"),
            );
        }
    }
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
                if let Some(f) = read_expr(v, &format!("{what}.points.{}", k.name), diag) {
                    points.push((k.name.clone(), k.pos, f));
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
        dofs,
        points,
        doc,
    })
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

/// ISO 8608 road classes: `G_d(n0)` (m^3) at `n0 = 0.1` cycles/m, the geometric mean of each
/// class; `G_d(n) = G_d(n0) (n / n0)^-2`.
pub const ISO8608_CLASSES: [(&str, f64); 8] = [
    ("A", 16e-6),
    ("B", 64e-6),
    ("C", 256e-6),
    ("D", 1024e-6),
    ("E", 4096e-6),
    ("F", 16384e-6),
    ("G", 65536e-6),
    ("H", 262144e-6),
];

fn profile(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawProfile> {
    let what = format!("profiles.{name}");
    let mut m = MapReader::new(node, &what, diag)?;
    let kind = match m.required_string("kind", diag) {
        Some((k, p)) => match k.as_str() {
            "generated" => {
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
                            let allowed: Vec<&str> =
                                Interpolation::ALL.iter().map(|(_, k)| *k).collect();
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
                m.finish(&["kind", "psd", "wavelengths", "interpolation"], diag);
                let wavelengths = wavelengths?;
                if !(wavelengths[0] > 0.0 && wavelengths[0] < wavelengths[1]) {
                    diag.push(
                        pos,
                        format!(
                            "{what}.wavelengths: need 0 < min < max (m), found {wavelengths:?}"
                        ),
                    );
                    return None;
                }
                RawProfileKind::Generated {
                    segments: psd?,
                    wavelengths,
                    interpolation,
                }
            }
            "harmonic" => {
                let k = RawProfileKind::Harmonic {
                    amplitude: m.required_expr("amplitude", diag),
                    wavelength: m.required_expr("wavelength", diag),
                    phase: m.expr("phase", diag),
                };
                m.finish(&["kind", "amplitude", "wavelength", "phase"], diag);
                k
            }
            other => {
                diag.push(p, format!("{what}.kind: `{other}`; allowed: generated (random-phase from a spectrum, one per sample), harmonic (analytic)"));
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

/// `{iso8608: C}`, or `{unit: "mm^2 m" | "m^3", segments: [{f_start, a, n}, ...]}`; returns the
/// segments with `a` in mm^2 m (the generator's unit).
fn psd(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<Vec<RawPsdSegment>> {
    let mut m = MapReader::new(node, what, diag)?;
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
        return Some(vec![RawPsdSegment {
            f_start: 0.0,
            a: g0 * 0.01 * 1e6,
            n: 2.0,
        }]);
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
    m.finish(&["unit", "segments", "iso8608"], diag);
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
    Some(out)
}

fn element(name: &str, pos: Pos, node: &Node, diag: &mut Diagnostics) -> Option<RawElement> {
    let what = format!("elements.{name}");
    let mut m = MapReader::new(node, &what, diag)?;
    let (kind, kpos) = m.required_string("kind", diag)?;
    let from = m.required_string("from", diag);
    let to = m.required_string("to", diag);
    let profile = m.string("profile", diag);
    let common = ["kind", "from", "to", "profile"];
    let (law, extra): (RawLaw, &[&str]) = match kind.as_str() {
        "spring_damper" => (
            RawLaw::SpringDamper {
                k: m.required_expr("k", diag),
                c: m.expr("c", diag),
                preload: m.expr("preload", diag),
            },
            &["k", "c", "preload"],
        ),
        "hertz" => (
            RawLaw::Hertz {
                g: m.required_expr("g", diag),
                exponent: m.expr("exponent", diag),
            },
            &["g", "exponent"],
        ),
        "table" => {
            let list = |m: &mut MapReader, key: &str, diag: &mut Diagnostics| -> Vec<Field> {
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
            };
            let deflection = list(&mut m, "deflection", diag);
            let force = list(&mut m, "force", diag);
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
                format!("{what}.kind: `{other}`; allowed: spring_damper, hertz, table"),
            );
            return None;
        }
    };
    let allowed: Vec<&str> = common.iter().chain(extra).copied().collect();
    m.finish(&allowed, diag);
    Some(RawElement {
        name: name.to_owned(),
        pos,
        law,
        from,
        to,
        profile,
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
