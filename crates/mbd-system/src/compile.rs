//! Validation and compilation: names resolved once (parameters, bodies, points, beams,
//! profiles, elements), every problem reported with its line, then the flat [`System`].
//!
//! Checks, beyond the shapes checked by [`crate::schema`]:
//! - every name an expression uses is a parameter; every parameter is used; derived
//!   parameters form no cycle (the cycle is named);
//! - counts (`modes`, `supports.count`) are integers fixed for every sample;
//! - element ends and load points name a body, one of its points, a moving point or `ground`;
//!   an element's upper end is a body; a profile sits under a moving point;
//! - every body DOF is restrained: the stiffness the elements give the rigid DOFs, with the
//!   beams and the ground held, is positive definite at the nominal values (else every DOF
//!   whose pivot vanishes is named);
//! - every field is in its domain at the nominal values (a mass > 0, a damping >= 0, ...);
//!   [`System::instantiate`] checks each sample again;
//! - every column name (the naming rule of `docs/systems.md`) is unique, and `outputs` and
//!   `indices` name columns that exist.
//!
//! [`compile`] runs one phase per section of the description, each a method of a small
//! compilation context (the description, the parameter scope that records which names are
//! used, the problems found), so the problems are found in the order of the sections.

use crate::diag::Diagnostics;
use crate::expr::Expr;
use crate::reader::Field;
use crate::schema::{
    self, DofKind, Named, ParamKind, RawBeam, RawBody, RawDescription, RawLaw, RawLink,
    RawProfileKind, RawSupports,
};
use crate::system::*;
use crate::yaml::Pos;
use std::collections::{BTreeMap, HashMap};

/// A value overriding a parameter of the description for one run (`system_values`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum Override {
    /// A fixed parameter's value, or a sampled parameter's nominal value.
    Value(f64),
    /// A sampled parameter's range `[min, max]`.
    Range([f64; 2]),
}

struct Scope<'a> {
    names: HashMap<&'a str, usize>,
    used: Vec<bool>,
}

impl<'a> Scope<'a> {
    fn resolve(&mut self, f: &Field, what: &str, diag: &mut Diagnostics) -> Option<Expr> {
        let mut e = f.expr.clone();
        let names = &self.names;
        let resolved = e.resolve(&|n| names.get(n).copied());
        // The known names count as used even when another name is unknown (no follow-on
        // "never used" for them).
        self.mark_used(&f.expr);
        match resolved {
            Ok(()) => Some(e),
            Err(name) => {
                diag.push(
                    f.pos,
                    format!(
                        "{what}: unknown parameter `{name}`; parameters: {}",
                        self.known()
                    ),
                );
                None
            }
        }
    }

    fn mark_used(&mut self, e: &Expr) {
        for n in e.names() {
            if let Some(&i) = self.names.get(n) {
                self.used[i] = true;
            }
        }
    }

    /// The parameter names, sorted, for messages.
    fn known(&self) -> String {
        let mut known: Vec<&str> = self.names.keys().copied().collect();
        known.sort_unstable();
        known.join(", ")
    }

    fn opt(
        &mut self,
        f: &Option<Field>,
        default: f64,
        what: &str,
        diag: &mut Diagnostics,
    ) -> Option<Expr> {
        match f {
            Some(f) => self.resolve(f, what, diag),
            None => Some(Expr::Num(default)),
        }
    }

    fn req(&mut self, f: &Option<Field>, what: &str, diag: &mut Diagnostics) -> Option<Expr> {
        f.as_ref().and_then(|f| self.resolve(f, what, diag))
    }
}

/// Applies `overrides` to the parameter table (unknown names and derived parameters are
/// refused; the message names the allowed parameters).
pub fn apply_overrides(
    raw: &mut RawDescription,
    overrides: &BTreeMap<String, Override>,
) -> Result<(), String> {
    for (name, o) in overrides {
        let Some(p) = raw.parameters.iter_mut().find(|p| &p.name == name) else {
            let known: Vec<&str> = raw.parameters.iter().map(|p| p.name.as_str()).collect();
            return Err(format!(
                "system_values: `{name}` is not a parameter of the description; parameters: {}",
                known.join(", ")
            ));
        };
        match (&mut p.kind, o) {
            (ParamKind::Fixed { value }, Override::Value(v)) if v.is_finite() => *value = *v,
            (ParamKind::Sampled { nominal, range }, Override::Value(v))
                if v.is_finite() && range[0] <= *v && *v <= range[1] =>
            {
                *nominal = *v
            }
            (ParamKind::Sampled { nominal, range }, Override::Range([lo, hi]))
                if lo.is_finite() && hi.is_finite() && lo < hi && *lo <= *nominal && *nominal <= *hi =>
            {
                *range = [*lo, *hi]
            }
            (ParamKind::Derived { .. }, _) => {
                return Err(format!(
                    "system_values.{name}: `{name}` is derived from other parameters; override those"
                ))
            }
            (ParamKind::Fixed { .. }, _) => {
                return Err(format!("system_values.{name}: a fixed parameter takes a finite number"))
            }
            (ParamKind::Sampled { nominal, range }, _) => {
                return Err(format!(
                    "system_values.{name}: a sampled parameter takes a nominal value inside its range {range:?} or a range `[min, max]` containing the nominal {nominal}"
                ))
            }
        }
    }
    Ok(())
}

/// Validates and compiles a parsed description; every problem found goes to `diag`.
///
/// The phases run in the order of the description's sections, so the problems are found in
/// that order: the parameter table, bodies and their DOFs, beams, the moving frame, sensors,
/// profiles, elements, loads, the columns (`outputs`), `indices`, `railway`, `indices_from`, the
/// parameters never used; then, when nothing was found, the checks at the nominal values.
pub fn compile(raw: &RawDescription, diag: &mut Diagnostics) -> Option<System> {
    let mut cx = Compiler::new(raw, diag);
    let parameters = cx.parameters();
    let derived_order = derived_order(raw, &parameters, cx.diag);
    let (bodies, dofs) = cx.bodies();
    let beams = cx.beams(&parameters, &derived_order);
    let (points, speed) = cx.moving(&beams);
    let sensors = cx.sensors(&beams);
    let profiles = cx.profiles();
    let ends = Ends {
        bodies: &bodies,
        points: &points,
    };
    let elements = cx.elements(&ends, &profiles);
    let loads = cx.loads(&ends);
    cx.mark_derived_used(&parameters);
    let table = channel_table(&bodies, &dofs, &points, &sensors, &elements, raw, cx.diag);
    let channels = stored_channels(&dofs, &table, raw, cx.diag);
    let indices = cx.indices(&channels);
    let railway = cx.railway(&channels);
    let indices_from = cx.indices_from();
    cx.report_unused();
    let assembly = assemble(&bodies, &dofs, &elements, &loads);
    let sampled_list = parameters
        .iter()
        .filter(|p| matches!(p.source, ParamSource::Sampled { .. }))
        .map(|p| p.name.clone())
        .collect();
    let system = System {
        name: raw.name.clone(),
        doc: raw.doc.clone(),
        parameters,
        derived_order,
        bodies,
        dofs,
        beams,
        speed,
        points,
        sensors,
        profiles,
        elements,
        loads,
        assembly,
        channels,
        indices,
        railway,
        indices_from,
        sampled_list,
    };
    if !diag.is_empty() {
        return None;
    }
    crate::checks::nominal_checks(&system, raw, diag);
    diag.is_empty().then_some(system)
}

/// One compilation in progress: the description, its parameter scope (which names are used)
/// and the problems found so far.
struct Compiler<'a, 'd> {
    raw: &'a RawDescription,
    scope: Scope<'a>,
    diag: &'d mut Diagnostics,
}

/// What an end name can resolve to: the compiled bodies (with their points) and moving points.
struct Ends<'s> {
    bodies: &'s [Body],
    points: &'s [MovingPoint],
}

impl<'a, 'd> Compiler<'a, 'd> {
    /// The scope of the parameter names, each name checked (not reserved, not starting with
    /// a digit).
    fn new(raw: &'a RawDescription, diag: &'d mut Diagnostics) -> Self {
        let mut scope = Scope {
            names: HashMap::new(),
            used: vec![false; raw.parameters.len()],
        };
        for (i, p) in raw.parameters.iter().enumerate() {
            if crate::expr::is_reserved(&p.name) {
                diag.push(
                    p.pos,
                    format!(
                        "parameters.{}: `{}` is reserved (a constant or function of expressions)",
                        p.name, p.name
                    ),
                );
            }
            if p.name.starts_with(|c: char| c.is_ascii_digit()) {
                diag.push(
                    p.pos,
                    format!(
                        "parameters.{}: a parameter name starts with a letter or `_`",
                        p.name
                    ),
                );
            }
            scope.names.insert(&p.name, i);
        }
        Compiler { raw, scope, diag }
    }

    /// A required field, `fallback` where it is absent or fails (the system is refused then).
    fn req_or(&mut self, f: &Option<Field>, what: &str, fallback: f64) -> Expr {
        self.scope
            .req(f, what, self.diag)
            .unwrap_or(Expr::Num(fallback))
    }

    /// An optional field, `default` where it is absent or fails.
    fn opt_or(&mut self, f: &Option<Field>, default: f64, what: &str) -> Expr {
        self.scope
            .opt(f, default, what, self.diag)
            .unwrap_or(Expr::Num(default))
    }

    /// The parameter table: sampled, fixed and derived sources (a derived expression naming
    /// an unknown parameter becomes a NaN fixed value, its known names counted as used).
    fn parameters(&mut self) -> Vec<Parameter> {
        let mut parameters = Vec::with_capacity(self.raw.parameters.len());
        for p in &self.raw.parameters {
            let source = match &p.kind {
                ParamKind::Sampled { nominal, range } => ParamSource::Sampled {
                    nominal: *nominal,
                    range: *range,
                },
                ParamKind::Fixed { value } => ParamSource::Fixed(*value),
                ParamKind::Derived { expr } => {
                    let mut e = expr.expr.clone();
                    let names = &self.scope.names;
                    match e.resolve(&|n| names.get(n).copied()) {
                        Ok(()) => ParamSource::Derived(e),
                        Err(name) => {
                            self.diag.push(
                                expr.pos,
                                format!(
                                    "parameters.{}.expr: unknown parameter `{name}`; parameters: {}",
                                    p.name,
                                    self.scope.known()
                                ),
                            );
                            self.scope.mark_used(&expr.expr);
                            ParamSource::Fixed(f64::NAN)
                        }
                    }
                }
            };
            parameters.push(Parameter {
                name: p.name.clone(),
                unit: p.unit.clone(),
                doc: p.doc.clone(),
                source,
            });
        }
        parameters
    }

    /// The bodies with their points, and the DOFs in body order (each body's in the order
    /// written).
    fn bodies(&mut self) -> (Vec<Body>, Vec<Dof>) {
        let mut bodies = Vec::new();
        let mut dofs = Vec::new();
        for b in &self.raw.bodies {
            let what = format!("bodies.{}", b.name);
            let mass = self.scope.req(&b.mass, &format!("{what}.mass"), self.diag);
            let inertia = self.inertia(b, &what);
            let mut body = Body {
                name: b.name.clone(),
                doc: b.doc.clone(),
                mass: mass.unwrap_or(Expr::Num(f64::NAN)),
                inertia,
                z: None,
                pitch: None,
                points: Vec::new(),
            };
            for (kind, _) in &b.dofs {
                let i = dofs.len();
                dofs.push(Dof {
                    name: format!("{}_{}", kind.symbol(), b.name),
                    body: bodies.len(),
                    kind: *kind,
                });
                match kind {
                    DofKind::Z => body.z = Some(i),
                    DofKind::Pitch => body.pitch = Some(i),
                }
            }
            for (name, _, x) in &b.points {
                if let Some(e) = self
                    .scope
                    .resolve(x, &format!("{what}.points.{name}"), self.diag)
                {
                    body.points.push((name.clone(), e));
                }
            }
            bodies.push(body);
        }
        (bodies, dofs)
    }

    /// A body's pitch inertia: required with a pitch DOF, refused without one.
    fn inertia(&mut self, b: &RawBody, what: &str) -> Option<Expr> {
        let pitches = b.dofs.iter().any(|d| d.0 == DofKind::Pitch);
        match (&b.inertia, pitches) {
            (Some(f), true) => self.scope.resolve(f, &format!("{what}.inertia"), self.diag),
            (None, true) => {
                self.diag.push(
                    b.pos,
                    format!("{what}: a body with a pitch DOF needs `inertia` (kg m^2)"),
                );
                None
            }
            (Some(f), false) => {
                self.diag.push(
                    f.pos,
                    format!(
                        "{what}.inertia: the body has no pitch DOF (dofs: [z, pitch] to add one)"
                    ),
                );
                None
            }
            (None, false) => None,
        }
    }

    /// The beams, their counts (`modes`, `supports.count`) evaluated from the parameters that
    /// are the same for every sample.
    fn beams(&mut self, parameters: &[Parameter], derived_order: &[usize]) -> Vec<Beam> {
        let structural = structural_values(parameters, derived_order);
        let counts = Counts {
            parameters,
            structural: &structural,
        };
        self.raw
            .beams
            .iter()
            .map(|b| self.beam(b, &counts))
            .collect()
    }

    /// One beam: its modes, its supports (fewer modes than supports), then its fields.
    fn beam(&mut self, b: &RawBeam, counts: &Counts) -> Beam {
        let what = format!("beams.{}", b.name);
        let modes = self.count(&b.modes, &what, "modes", counts);
        let supports = b.supports.as_ref().map(|s| self.supports(s, &what, counts));
        if let Some(s) = &supports {
            if s.count >= 2 && modes >= s.count {
                self.diag.push(b.pos, format!("{what}.modes: {modes} modes need fewer than supports.count = {} supports (discrete sine orthogonality)", s.count));
            }
        }
        Beam {
            name: b.name.clone(),
            doc: b.doc.clone(),
            length: self.req_or(&b.length, &format!("{what}.length"), f64::NAN),
            modes,
            mass_per_length: self.req_or(
                &b.mass_per_length,
                &format!("{what}.mass_per_length"),
                f64::NAN,
            ),
            bending_stiffness: self.req_or(
                &b.bending_stiffness,
                &format!("{what}.bending_stiffness"),
                f64::NAN,
            ),
            damping_ratio: self.opt_or(&b.damping_ratio, 0.0, &format!("{what}.damping_ratio")),
            outside: b.outside,
            supports,
        }
    }

    /// A count field of a beam (`what.field`), 0 where it is absent or fails.
    fn count(&mut self, f: &Option<Field>, what: &str, field: &str, counts: &Counts) -> usize {
        let Some(f) = f else { return 0 };
        let Some(e) = self.scope.resolve(f, &format!("{what}.{field}"), self.diag) else {
            return 0;
        };
        match structural_count(&e, counts.parameters, counts.structural) {
            Ok(n) => n,
            Err(why) => {
                self.diag.push(f.pos, format!("{what}.{field}: {why}"));
                0
            }
        }
    }

    /// A beam's periodic supports: the count, the levels (shear on the last one only), the
    /// spacing, the first support and the link to the ground.
    fn supports(&mut self, s: &RawSupports, what: &str, counts: &Counts) -> Supports {
        let w = format!("{what}.supports");
        let count = self.count(&s.count, what, "supports.count", counts);
        if s.levels.is_empty() {
            self.diag.push(
                s.pos,
                format!("{w}.levels: at least one level (a mass under each support)"),
            );
        }
        let n_levels = s.levels.len();
        let levels = s
            .levels
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let lw = format!("{w}.levels[{i}]");
                if l.shear.is_some() && i + 1 != n_levels {
                    self.diag.push(l.pos, format!("{lw}.shear: shear coupling is supported on the last level (the one on the ground) only"));
                }
                Level {
                    name: l.name.clone(),
                    mass: self.req_or(&l.mass, &format!("{lw}.mass"), f64::NAN),
                    link: self.link(l.link.as_ref(), &format!("{lw}.link")),
                    shear: l
                        .shear
                        .as_ref()
                        .map(|s| self.link(Some(s), &format!("{lw}.shear"))),
                }
            })
            .collect();
        Supports {
            spacing: self.req_or(&s.spacing, &format!("{w}.spacing"), f64::NAN),
            count,
            first: self.opt_or(&s.first, 0.0, &format!("{w}.first")),
            levels,
            ground: self.link(s.ground.as_ref(), &format!("{w}.ground")),
        }
    }

    /// A spring-damper link (an absent one: NaN stiffness, the system is refused anyway).
    fn link(&mut self, l: Option<&RawLink>, what: &str) -> Link {
        match l {
            Some(l) => Link {
                k: self.req_or(&l.k, &format!("{what}.k"), f64::NAN),
                c: self.opt_or(&l.c, 0.0, &format!("{what}.c")),
            },
            None => Link {
                k: Expr::Num(f64::NAN),
                c: Expr::Num(0.0),
            },
        }
    }

    /// The moving frame: its points (each on a beam or the ground) and its speed (0 without
    /// a frame).
    fn moving(&mut self, beams: &[Beam]) -> (Vec<MovingPoint>, Expr) {
        let Some(m) = &self.raw.moving else {
            return (Vec::new(), Expr::Num(0.0));
        };
        let mut points = Vec::new();
        for p in &m.points {
            let what = format!("moving.points.{}", p.name);
            let beam = match &p.on {
                Some((on, _)) if on == "ground" => None,
                // A point meant for a beam keeps its column `z_<point>` (no follow-on problem
                // in `outputs`); the system is refused anyway.
                Some((on, pos)) => Some(
                    self.beam_on(beams, on, *pos, &what, "; or `ground`")
                        .unwrap_or(beams.len()),
                ),
                None => None,
            };
            points.push(MovingPoint {
                name: p.name.clone(),
                beam,
                offset: self.req_or(&p.offset, &format!("{what}.offset"), 0.0),
            });
        }
        let speed = self.req_or(&m.speed, "moving.speed", 0.0);
        (points, speed)
    }

    /// The index of the beam named `on` (`what.on`); an unknown name is reported with the
    /// beams and `alternatives`.
    fn beam_on(
        &mut self,
        beams: &[Beam],
        on: &str,
        pos: Pos,
        what: &str,
        alternatives: &str,
    ) -> Option<usize> {
        let found = beams.iter().position(|b| b.name == on);
        if found.is_none() {
            self.diag.push(
                pos,
                format!(
                    "{what}.on: unknown beam `{on}`; beams: {}{alternatives}",
                    names(self.raw.beams.iter().map(|b| &b.name))
                ),
            );
        }
        found
    }

    /// The sensors: a beam and a position on it.
    fn sensors(&mut self, beams: &[Beam]) -> Vec<Sensor> {
        let mut sensors = Vec::new();
        for s in &self.raw.sensors {
            let what = format!("sensors.{}", s.name);
            // A sensor whose beam or position fails keeps its columns (no follow-on problem
            // in `outputs`); the system is refused anyway.
            let beam = match &s.on {
                Some((on, pos)) => self.beam_on(beams, on, *pos, &what, ""),
                None => None,
            };
            let x = self.req_or(&s.x, &format!("{what}.x"), f64::NAN);
            sensors.push(Sensor {
                name: s.name.clone(),
                beam: beam.unwrap_or(beams.len()),
                x,
            });
        }
        sensors
    }

    /// The profiles: generated (from a PSD) or harmonic.
    fn profiles(&mut self) -> Vec<Profile> {
        let mut profiles = Vec::new();
        for p in &self.raw.profiles {
            let what = format!("profiles.{}", p.name);
            profiles.push(match &p.kind {
                RawProfileKind::Generated {
                    segments,
                    wavelengths,
                    interpolation,
                } => Profile::Generated {
                    name: p.name.clone(),
                    segments: segments.clone(),
                    wavelengths: *wavelengths,
                    interpolation: interpolation.0,
                },
                RawProfileKind::Harmonic {
                    amplitude,
                    wavelength,
                    phase,
                } => Profile::Harmonic {
                    name: p.name.clone(),
                    amplitude: self.req_or(amplitude, &format!("{what}.amplitude"), 0.0),
                    wavelength: self.req_or(wavelength, &format!("{what}.wavelength"), 1.0),
                    phase: self.opt_or(phase, 0.0, &format!("{what}.phase")),
                },
            });
        }
        profiles
    }

    /// The elements: ends, profile and law of each.
    fn elements(&mut self, ends: &Ends, profiles: &[Profile]) -> Vec<Element> {
        let mut elements = Vec::new();
        for e in &self.raw.elements {
            let what = format!("elements.{}", e.name);
            let from = self.end(ends, &e.from, &what, "from");
            let to = self.end(ends, &e.to, &what, "to");
            if let (Some(f), Some(t)) = (&from, &to) {
                if !matches!(f, End::Body { .. }) {
                    self.diag.push(
                        e.pos,
                        format!("{what}.from: the upper end of an element is a body or body point"),
                    );
                }
                if f == t {
                    self.diag
                        .push(e.pos, format!("{what}: `from` and `to` are the same point"));
                }
            }
            let profile = e
                .profile
                .as_ref()
                .map(|named| self.element_profile(named, to.as_ref(), ends, profiles, &what));
            let law = self.law(&e.law, &what);
            // An element whose end fails keeps its columns (no follow-on problem in
            // `outputs`); the system is refused anyway.
            elements.push(Element {
                name: e.name.clone(),
                law,
                from: from.unwrap_or(End::Ground),
                to: to.unwrap_or(End::Ground),
                profile,
            });
        }
        elements
    }

    /// The end `what.field` of an element or load, where it is given and resolves.
    fn end(&mut self, ends: &Ends, named: &Option<Named>, what: &str, field: &str) -> Option<End> {
        named
            .as_ref()
            .and_then(|(n, p)| ends.resolve(n, *p, &format!("{what}.{field}"), self.diag))
    }

    /// The profile of an element: under a moving point `to`, and one of the profiles (an
    /// unknown one keeps the column `eta_<element>`; the system is refused anyway).
    fn element_profile(
        &mut self,
        (name, pos): &Named,
        to: Option<&End>,
        ends: &Ends,
        profiles: &[Profile],
        what: &str,
    ) -> usize {
        if to.is_some_and(|t| !matches!(t, End::Moving(_))) {
            self.diag.push(
                *pos,
                format!(
                    "{what}.profile: a profile lies under a moving point; `to` must be one ({})",
                    names(ends.points.iter().map(|p| &p.name))
                ),
            );
        }
        profiles
            .iter()
            .position(|p| p.name() == name)
            .unwrap_or_else(|| {
                self.diag.push(
                    *pos,
                    format!(
                        "{what}.profile: unknown profile `{name}`; profiles: {}",
                        names(profiles.iter().map(|p| p.name()))
                    ),
                );
                profiles.len()
            })
    }

    /// An element's force law.
    fn law(&mut self, law: &RawLaw, what: &str) -> Law {
        match law {
            RawLaw::SpringDamper { k, c, preload } => Law::SpringDamper {
                k: self.req_or(k, &format!("{what}.k"), f64::NAN),
                c: self.opt_or(c, 0.0, &format!("{what}.c")),
                preload: self.opt_or(preload, 0.0, &format!("{what}.preload")),
            },
            RawLaw::Hertz { g, exponent } => Law::Hertz {
                g: self.req_or(g, &format!("{what}.g"), f64::NAN),
                exponent: self.opt_or(exponent, 1.5, &format!("{what}.exponent")),
            },
            RawLaw::Table {
                deflection,
                force,
                c,
            } => Law::Table {
                deflection: self.each(deflection, &format!("{what}.deflection")),
                force: self.each(force, &format!("{what}.force")),
                c: self.opt_or(c, 0.0, &format!("{what}.c")),
            },
        }
    }

    /// Every field of a list that resolves (a failed one is reported).
    fn each(&mut self, fields: &[Field], what: &str) -> Vec<Expr> {
        fields
            .iter()
            .filter_map(|f| self.scope.resolve(f, what, self.diag))
            .collect()
    }

    /// The loads: a point that is not the ground, and a force (a load with either failed is
    /// left out; the system is refused anyway).
    fn loads(&mut self, ends: &Ends) -> Vec<Load> {
        let mut loads = Vec::new();
        for l in &self.raw.loads {
            let what = format!("loads.{}", l.name);
            let at = self.end(ends, &l.at, &what, "at");
            if let Some(End::Moving(pi)) = &at {
                if ends.points[*pi].beam.is_none() {
                    self.diag.push(
                        l.pos,
                        format!("{what}.at: a load on a point on the ground acts on nothing"),
                    );
                }
            }
            if matches!(at, Some(End::Ground)) {
                self.diag.push(
                    l.pos,
                    format!("{what}.at: a load on the ground acts on nothing"),
                );
            }
            let force = self
                .scope
                .req(&l.force, &format!("{what}.force"), self.diag);
            if let (Some(at), Some(force)) = (at, force) {
                loads.push(Load {
                    name: l.name.clone(),
                    at,
                    force,
                });
            }
        }
        loads
    }

    /// Counts the parameters a derived parameter reads as used.
    fn mark_derived_used(&mut self, parameters: &[Parameter]) {
        for p in parameters {
            if let ParamSource::Derived(e) = &p.source {
                let mut ids = Vec::new();
                collect_ids(e, &mut ids);
                for j in ids {
                    self.scope.used[j] = true;
                }
            }
        }
    }

    /// The indices: a stored column, a statistic, `subtract` and `divide` (an index with a
    /// part missing or failed is left out; the system is refused anyway).
    fn indices(&mut self, channels: &[Channel]) -> Vec<Index> {
        let mut indices = Vec::new();
        for ix in &self.raw.indices {
            let what = format!("indices.{}", ix.name);
            let channel = ix.channel.as_ref().and_then(|named| {
                stored_column(channels, named, &format!("{what}.channel"), self.diag)
            });
            let subtract =
                self.scope
                    .opt(&ix.subtract, 0.0, &format!("{what}.subtract"), self.diag);
            let divide = self
                .scope
                .opt(&ix.divide, 1.0, &format!("{what}.divide"), self.diag);
            if let (Some(channel), Some((stat, _)), Some(subtract), Some(divide)) =
                (channel, ix.stat, subtract, divide)
            {
                let unit = ix.unit.clone().unwrap_or_else(|| {
                    if matches!(divide, Expr::Num(v) if v == 1.0) {
                        channels[channel].unit.clone()
                    } else {
                        "1".to_owned()
                    }
                });
                indices.push(Index {
                    name: ix.name.clone(),
                    doc: ix.doc.clone(),
                    stat,
                    channel,
                    subtract,
                    divide,
                    unit,
                    limit: ix.limit,
                });
            }
        }
        indices
    }

    /// `indices_from` (s): finite and at least 0; 0 when absent.
    fn indices_from(&mut self) -> f64 {
        match self.raw.indices_from {
            Some((v, _)) if v.is_finite() && v >= 0.0 => v,
            Some((v, pos)) => {
                self.diag.push(
                    pos,
                    format!("indices_from: {v} is out of range: a time in s, finite and >= 0"),
                );
                0.0
            }
            None => 0.0,
        }
    }

    /// The `railway` section: the stored columns its indices read and its two values (none
    /// where a part fails).
    fn railway(&mut self, channels: &[Channel]) -> Option<Railway> {
        let r = self.raw.railway.as_ref()?;
        let diag = &mut *self.diag;
        let mut cols = |v: &[Named]| -> Option<Vec<usize>> {
            v.iter()
                .map(|n| stored_column(channels, n, "railway", diag))
                .collect()
        };
        let contact_forces = cols(&r.contact_forces);
        let bogies = cols(&r.bogies);
        let rails = cols(&r.rails);
        let (cv, cp) = match &r.car_body {
            Some((v, p)) => (
                stored_column(channels, v, "railway", self.diag),
                stored_column(channels, p, "railway", self.diag),
            ),
            None => (None, None),
        };
        let half_length = self
            .scope
            .req(&r.half_length, "railway.half_length", self.diag);
        let static_wheel_load =
            self.scope
                .req(&r.static_wheel_load, "railway.static_wheel_load", self.diag);
        Some(Railway {
            contact_forces: contact_forces?,
            car_body_vertical: cv?,
            car_body_pitch: cp?,
            half_length: half_length?,
            bogies: bogies?,
            rails: rails?,
            static_wheel_load: static_wheel_load?,
        })
    }

    /// Reports every parameter never used.
    fn report_unused(&mut self) {
        for (i, p) in self.raw.parameters.iter().enumerate() {
            if !self.scope.used[i] {
                self.diag.push(
                    p.pos,
                    format!(
                        "parameters.{}: declared but never used (remove it, or use it in a field)",
                        p.name
                    ),
                );
            }
        }
    }
}

/// The parameters and the values of those that are the same for every sample: what a count
/// is evaluated from.
struct Counts<'p> {
    parameters: &'p [Parameter],
    structural: &'p [Option<f64>],
}

impl Ends<'_> {
    /// Resolves an end: `ground`, `body`, `body.point` or a moving point; an unknown name
    /// is reported with what exists.
    fn resolve(&self, name: &str, pos: Pos, what: &str, diag: &mut Diagnostics) -> Option<End> {
        if name == "ground" {
            return Some(End::Ground);
        }
        let (body_name, point) = match name.split_once('.') {
            Some((b, p)) => (b, Some(p)),
            None => (name, None),
        };
        if let Some(bi) = self.bodies.iter().position(|b| b.name == body_name) {
            let x = match point {
                None => None,
                Some(p) => match self.bodies[bi].points.iter().find(|(n, _)| n == p) {
                    Some((_, x)) => Some(x.clone()),
                    None => {
                        diag.push(
                            pos,
                            format!(
                                "{what}: body `{body_name}` has no point `{p}`; its points: {}",
                                names(self.bodies[bi].points.iter().map(|p| &p.0))
                            ),
                        );
                        return None;
                    }
                },
            };
            return Some(End::Body { body: bi, x });
        }
        if point.is_none() {
            if let Some(pi) = self.points.iter().position(|p| p.name == name) {
                return Some(End::Moving(pi));
            }
        }
        diag.push(
            pos,
            format!(
                "{what}: unknown point `{name}`; expected `ground`, a body ({}), `body.point`, or a moving point ({})",
                names(self.bodies.iter().map(|b| &b.name)),
                names(self.points.iter().map(|p| &p.name))
            ),
        );
        None
    }
}

/// The index of the stored column `name` (`what` in the message when there is none).
fn stored_column(
    channels: &[Channel],
    (name, pos): &Named,
    what: &str,
    diag: &mut Diagnostics,
) -> Option<usize> {
    let found = channels.iter().position(|c| &c.name == name);
    if found.is_none() {
        diag.push(
            *pos,
            format!(
                "{what}: `{name}` is not a stored column; stored: {}",
                names(channels.iter().map(|c| &c.name))
            ),
        );
    }
    found
}

/// Names for a message, `none` for none.
fn names<S: AsRef<str>>(it: impl Iterator<Item = S>) -> String {
    let v: Vec<String> = it.map(|s| s.as_ref().to_owned()).collect();
    if v.is_empty() {
        "none".to_owned()
    } else {
        v.join(", ")
    }
}

/// Topological order of the derived parameters; a cycle is reported with its path.
fn derived_order(raw: &RawDescription, params: &[Parameter], diag: &mut Diagnostics) -> Vec<usize> {
    let n = params.len();
    let mut state = vec![0u8; n]; // 0 new, 1 on the path, 2 done
    let mut order = Vec::new();
    fn visit(
        i: usize,
        params: &[Parameter],
        state: &mut [u8],
        path: &mut Vec<usize>,
        order: &mut Vec<usize>,
    ) -> Result<(), Vec<usize>> {
        if state[i] == 2 {
            return Ok(());
        }
        if state[i] == 1 {
            let start = path.iter().position(|&j| j == i).unwrap_or(0);
            let mut cycle = path[start..].to_vec();
            cycle.push(i);
            return Err(cycle);
        }
        state[i] = 1;
        path.push(i);
        if let ParamSource::Derived(e) = &params[i].source {
            let mut deps = Vec::new();
            collect_ids(e, &mut deps);
            for d in deps {
                visit(d, params, state, path, order)?;
            }
            order.push(i);
        }
        path.pop();
        state[i] = 2;
        Ok(())
    }
    for i in 0..n {
        let mut path = Vec::new();
        if let Err(cycle) = visit(i, params, &mut state, &mut path, &mut order) {
            let names: Vec<&str> = cycle.iter().map(|&j| params[j].name.as_str()).collect();
            diag.push(
                raw.parameters[cycle[0]].pos,
                format!(
                    "parameters: derived parameters form a cycle: {}",
                    names.join(" -> ")
                ),
            );
            for &j in &cycle {
                state[j] = 2;
            }
        }
    }
    order
}

pub(crate) fn collect_ids(e: &Expr, out: &mut Vec<usize>) {
    match e {
        Expr::Num(_) => {}
        Expr::Var(_, id) => out.extend(*id),
        Expr::Neg(a) => collect_ids(a, out),
        Expr::Bin(_, a, b) => {
            collect_ids(a, out);
            collect_ids(b, out);
        }
        Expr::Call(_, args) => args.iter().for_each(|a| collect_ids(a, out)),
    }
}

/// Values of the parameters that are the same for every sample (fixed, or derived only from
/// fixed ones); `None` for those that vary.
fn structural_values(params: &[Parameter], order: &[usize]) -> Vec<Option<f64>> {
    let mut v: Vec<Option<f64>> = params
        .iter()
        .map(|p| match p.source {
            ParamSource::Fixed(x) => Some(x),
            _ => None,
        })
        .collect();
    for &i in order {
        if let ParamSource::Derived(e) = &params[i].source {
            let mut ids = Vec::new();
            collect_ids(e, &mut ids);
            if ids.iter().all(|&j| v[j].is_some()) {
                let vals: Vec<f64> = v.iter().map(|x| x.unwrap_or(f64::NAN)).collect();
                v[i] = Some(e.eval(&vals));
            }
        }
    }
    v
}

fn structural_count(
    e: &Expr,
    params: &[Parameter],
    fixed: &[Option<f64>],
) -> Result<usize, String> {
    let mut ids = Vec::new();
    collect_ids(e, &mut ids);
    if let Some(&j) = ids.iter().find(|&&j| fixed[j].is_none()) {
        return Err(format!(
            "a count must be the same for every sample, but `{}` varies (sampled, or derived from a sampled parameter)",
            params[j].name
        ));
    }
    let vals: Vec<f64> = fixed.iter().map(|x| x.unwrap_or(f64::NAN)).collect();
    let v = e.eval(&vals);
    if !(v.is_finite() && v >= 1.0 && v.fract() == 0.0 && v <= 1e7) {
        return Err(format!("a count must be an integer in [1, 1e7], found {v}"));
    }
    Ok(v as usize)
}

/// Every column the naming rule gives (stored or not): name, unit, quantity, role.
fn channel_table(
    bodies: &[Body],
    dofs: &[Dof],
    points: &[MovingPoint],
    sensors: &[Sensor],
    elements: &[Element],
    raw: &RawDescription,
    diag: &mut Diagnostics,
) -> Vec<Channel> {
    let mut out = Vec::new();
    // Who produces each column, for messages: what and its name.
    let mut owners: Vec<(&str, &str)> = Vec::new();
    let mut push = |name: String, unit: &str, quantity: Quantity, role: Role| {
        out.push(Channel {
            name,
            unit: unit.to_owned(),
            quantity,
            role,
        });
        owners.push(match quantity {
            Quantity::Dof(i, _) => ("body", bodies[dofs[i].body].name.as_str()),
            Quantity::Point(i) => ("moving point", points[i].name.as_str()),
            Quantity::Sensor(i, _) => ("sensor", sensors[i].name.as_str()),
            Quantity::Excitation(i)
            | Quantity::ExcitationRate(i)
            | Quantity::Force(i)
            | Quantity::Deflection(i) => ("element", elements[i].name.as_str()),
        });
    };
    for (i, d) in dofs.iter().enumerate() {
        let (u, v, a) = match d.kind {
            DofKind::Z => ("m", "m/s", "m/s^2"),
            DofKind::Pitch => ("rad", "rad/s", "rad/s^2"),
        };
        push(d.name.clone(), u, Quantity::Dof(i, 0), Role::Solution);
        push(
            format!("{}_v", d.name),
            v,
            Quantity::Dof(i, 1),
            Role::Velocity,
        );
        push(
            format!("{}_a", d.name),
            a,
            Quantity::Dof(i, 2),
            Role::Acceleration,
        );
    }
    for (i, p) in points.iter().enumerate() {
        if p.beam.is_some() {
            push(
                format!("z_{}", p.name),
                "m",
                Quantity::Point(i),
                Role::Solution,
            );
        }
    }
    for (i, s) in sensors.iter().enumerate() {
        push(
            format!("z_{}", s.name),
            "m",
            Quantity::Sensor(i, 0),
            Role::Solution,
        );
        push(
            format!("z_{}_v", s.name),
            "m/s",
            Quantity::Sensor(i, 1),
            Role::Other,
        );
        push(
            format!("z_{}_a", s.name),
            "m/s^2",
            Quantity::Sensor(i, 2),
            Role::Other,
        );
    }
    for (i, e) in elements.iter().enumerate() {
        if e.profile.is_some() {
            push(
                format!("eta_{}", e.name),
                "m",
                Quantity::Excitation(i),
                Role::Excitation,
            );
        }
        if e.reads_profile_rate() {
            push(
                format!("eta_{}_v", e.name),
                "m/s",
                Quantity::ExcitationRate(i),
                Role::Excitation,
            );
        }
        let sym = if e.law.is_contact() { "p" } else { "f" };
        push(
            format!("{sym}_{}", e.name),
            "N",
            Quantity::Force(i),
            Role::Force,
        );
        push(
            format!("d_{}", e.name),
            "m",
            Quantity::Deflection(i),
            Role::Other,
        );
    }
    report_column_clashes(&out, &owners, raw, diag);
    out
}

/// Unique column names: a collision (a body `c_v` beside a body `c`, a sensor named like a
/// body) is reported once per pair of producers (`owners`, one per column), at the later
/// declaration.
fn report_column_clashes(
    columns: &[Channel],
    owners: &[(&str, &str)],
    raw: &RawDescription,
    diag: &mut Diagnostics,
) {
    let mut seen: HashMap<&str, usize> = HashMap::new();
    let mut clashes: Vec<(usize, usize, Vec<&str>)> = Vec::new();
    for (i, c) in columns.iter().enumerate() {
        match seen.get(c.name.as_str()) {
            Some(&j) => match clashes
                .iter_mut()
                .find(|(a, b, _)| owners[*a] == owners[j] && owners[*b] == owners[i])
            {
                Some(clash) => clash.2.push(&c.name),
                None => clashes.push((j, i, vec![&c.name])),
            },
            None => {
                seen.insert(&c.name, i);
            }
        }
    }
    for (j, i, columns) in clashes {
        let (first, second) = (owners[j], owners[i]);
        let also = if columns.len() > 1 {
            let rest: Vec<String> = columns[1..].iter().map(|c| format!("`{c}`")).collect();
            format!(" (also {})", rest.join(", "))
        } else {
            String::new()
        };
        diag.push(
            declared(raw, first).max(declared(raw, second)),
            format!(
                "column `{}` is produced by both {} `{}` and {} `{}`{also}; rename one of them",
                columns[0], first.0, first.1, second.0, second.1
            ),
        );
    }
}

/// Where the producer of a column (its kind and name) is declared.
fn declared(raw: &RawDescription, (kind, name): (&str, &str)) -> Pos {
    let found = match kind {
        "body" => raw.bodies.iter().find(|b| b.name == name).map(|b| b.pos),
        "moving point" => raw
            .moving
            .as_ref()
            .and_then(|m| m.points.iter().find(|p| p.name == name).map(|p| p.pos)),
        "sensor" => raw.sensors.iter().find(|s| s.name == name).map(|s| s.pos),
        _ => raw.elements.iter().find(|e| e.name == name).map(|e| e.pos),
    };
    found.unwrap_or_default()
}

/// The stored columns: DOF displacements, the listed displacement columns, DOF velocities,
/// DOF accelerations, then the other listed columns in their listed order, each profile column
/// `eta_<element>` followed by its rate `eta_<element>_v` where the element reads it.
fn stored_channels(
    dofs: &[Dof],
    table: &[Channel],
    raw: &RawDescription,
    diag: &mut Diagnostics,
) -> Vec<Channel> {
    let find = |name: &str| table.iter().find(|c| c.name == name);
    let mut listed: Vec<&Channel> = Vec::new();
    for (name, pos) in &raw.outputs {
        match find(name) {
            Some(c) if matches!(c.quantity, Quantity::Dof(..)) => {
                diag.push(
                    *pos,
                    format!("outputs: `{name}` is a body DOF column, always stored"),
                );
            }
            Some(c) if matches!(c.quantity, Quantity::ExcitationRate(..)) => {
                diag.push(
                    *pos,
                    format!(
                        "outputs: `{name}` is a profile's rate, stored with its profile's column; list that one"
                    ),
                );
            }
            Some(c) => {
                if listed.iter().any(|l| l.name == c.name) {
                    diag.push(*pos, format!("outputs: `{name}` listed twice"));
                } else {
                    listed.push(c);
                }
            }
            None => {
                let available: Vec<&str> = table
                    .iter()
                    .filter(|c| {
                        !matches!(c.quantity, Quantity::Dof(..) | Quantity::ExcitationRate(..))
                    })
                    .map(|c| c.name.as_str())
                    .collect();
                diag.push(
                    *pos,
                    format!(
                        "outputs: no column `{name}`; available: {}",
                        available.join(", ")
                    ),
                );
            }
        }
    }
    let mut out = Vec::new();
    let dof_col = |i: usize, d: u8| {
        table
            .iter()
            .find(|c| c.quantity == Quantity::Dof(i, d))
            .cloned()
    };
    out.extend((0..dofs.len()).filter_map(|i| dof_col(i, 0)));
    out.extend(
        listed
            .iter()
            .filter(|c| c.role == Role::Solution)
            .map(|c| (*c).clone()),
    );
    out.extend((0..dofs.len()).filter_map(|i| dof_col(i, 1)));
    out.extend((0..dofs.len()).filter_map(|i| dof_col(i, 2)));
    for c in listed.iter().filter(|c| c.role != Role::Solution) {
        out.push((*c).clone());
        if let Quantity::Excitation(e) = c.quantity {
            out.extend(
                table
                    .iter()
                    .find(|r| r.quantity == Quantity::ExcitationRate(e))
                    .cloned(),
            );
        }
    }
    out
}

/// Per DOF, the generalised force as coefficient groups, accumulated in a fixed order by kind:
/// spring-dampers and tables, then loads, then contacts, each in declaration order.
fn assemble(
    bodies: &[Body],
    dofs: &[Dof],
    elements: &[Element],
    loads: &[Load],
) -> Vec<Vec<Group>> {
    let mut out: Vec<Vec<Group>> = vec![Vec::new(); dofs.len()];
    // A force `F` (downward) applied at a point `x` of a body: `F` on z, `-x F` on pitch.
    let mut add = |end: &End, applied_sign: f64, source: Source| {
        let End::Body { body, x } = end else { return };
        let b = &bodies[*body];
        if let Some(z) = b.z {
            push_term(&mut out[z], None, applied_sign, source);
        }
        if let (Some(p), Some(x)) = (b.pitch, x) {
            if !x.is_zero() {
                let (s, magnitude) = x.split_sign();
                push_term(
                    &mut out[p],
                    Some(magnitude.clone()),
                    -applied_sign * s,
                    source,
                );
            }
        }
    };
    let order = elements
        .iter()
        .enumerate()
        .filter(|(_, e)| !e.law.is_contact())
        .map(|(i, _)| Some(i))
        .chain(std::iter::once(None))
        .chain(
            elements
                .iter()
                .enumerate()
                .filter(|(_, e)| e.law.is_contact())
                .map(|(i, _)| Some(i)),
        );
    for item in order {
        match item {
            Some(i) => {
                // The element pushes its upper end up (-f) and its lower end down (+f).
                add(&elements[i].from, -1.0, Source::Element(i));
                add(&elements[i].to, 1.0, Source::Element(i));
            }
            None => {
                for (i, l) in loads.iter().enumerate() {
                    add(&l.at, 1.0, Source::Load(i));
                }
            }
        }
    }
    out
}

fn push_term(groups: &mut Vec<Group>, coefficient: Option<Expr>, sign: f64, source: Source) {
    let key = coefficient.as_ref().map(|e| e.to_string());
    match groups
        .iter_mut()
        .find(|g| g.coefficient.as_ref().map(|e| e.to_string()) == key)
    {
        Some(g) => g.terms.push((source, sign)),
        None => groups.push(Group {
            coefficient,
            terms: vec![(source, sign)],
        }),
    }
}

/// Parses, validates and compiles a description text (`file` names it in messages), with
/// `overrides` applied to its parameter table.
pub fn load_str(
    text: &str,
    file: &str,
    overrides: &BTreeMap<String, Override>,
) -> Result<System, Diagnostics> {
    let mut diag = Diagnostics {
        file: file.to_owned(),
        items: Vec::new(),
    };
    let root = match crate::yaml::parse(text) {
        Ok(r) => r,
        Err(e) => {
            diag.push(e.pos, format!("not valid YAML: {}", e.message));
            return Err(diag);
        }
    };
    let mut raw = schema::read(&root, &mut diag);
    if !diag.is_empty() {
        return Err(diag);
    }
    if let Err(message) = apply_overrides(&mut raw, overrides) {
        diag.push(Pos { line: 1, col: 1 }, message);
        return Err(diag);
    }
    match compile(&raw, &mut diag) {
        Some(s) if diag.is_empty() => Ok(s),
        _ => Err(diag),
    }
}
