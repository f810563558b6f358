//! Profiles, force elements (ends resolved to `ground`, a body, `body.point` or a moving
//! point; an element's upper end is a body; a profile sits under a moving point; each law's
//! coefficients) and the loads on bodies.

use super::*;

impl Compiler<'_, '_> {
    /// The profiles: generated (from a PSD) or harmonic.
    pub(super) fn profiles(&mut self) -> Vec<Profile> {
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
    pub(super) fn elements(&mut self, ends: &Ends, profiles: &[Profile]) -> Vec<Element> {
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
    pub(super) fn loads(&mut self, ends: &Ends) -> Vec<Load> {
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
