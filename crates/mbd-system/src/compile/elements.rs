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
                RawProfileKind::Combination { terms } => Profile::Combination {
                    name: p.name.clone(),
                    terms: terms
                        .iter()
                        .filter_map(|((n, pos), w)| self.combined(n, *pos, *w, &what))
                        .collect(),
                },
                RawProfileKind::Generated {
                    psd,
                    wavelengths,
                    interpolation,
                    until,
                } => Profile::Generated {
                    name: p.name.clone(),
                    psd: psd.clone(),
                    wavelengths: *wavelengths,
                    interpolation: interpolation.0,
                    until: until.as_ref().map(|(x, taper)| {
                        (
                            self.req_or(&Some(x.clone()), &format!("{what}.until.x"), f64::NAN),
                            self.req_or(
                                &Some(taper.clone()),
                                &format!("{what}.until.taper"),
                                f64::NAN,
                            ),
                        )
                    }),
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

    /// A term of a combination: a generated or harmonic profile of the description.
    fn combined(&mut self, name: &str, pos: Pos, weight: f64, what: &str) -> Option<(usize, f64)> {
        let found = self.raw.profiles.iter().position(|p| p.name == name);
        match found.map(|i| (i, &self.raw.profiles[i].kind)) {
            Some((_, RawProfileKind::Combination { .. })) => {
                self.diag.push(pos, format!("{what}.of: `{name}` is itself a combination; combine generated or harmonic profiles"));
                None
            }
            Some((i, _)) => Some((i, weight)),
            None => {
                self.diag.push(
                    pos,
                    format!(
                        "{what}.of: unknown profile `{name}`; profiles: {}",
                        names(self.raw.profiles.iter().map(|p| &p.name))
                    ),
                );
                None
            }
        }
    }

    /// The elements: ends, profile and law of each.
    pub(super) fn elements(&mut self, ends: &Ends, profiles: &[Profile]) -> Vec<Element> {
        let mut elements = Vec::new();
        for e in &self.raw.elements {
            let what = format!("elements.{}", e.name);
            if let RawLaw::Wheelset(w) = &e.law {
                elements.extend(self.wheelset(e, w, ends, profiles, &what));
                continue;
            }
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
            let direction = e.direction.0;
            for end in [&from, &to].into_iter().flatten() {
                self.spatial_on_planar(ends, end, direction, e.direction.1.unwrap_or(e.pos), &what);
            }
            // An element whose end fails keeps its columns (no follow-on problem in
            // `outputs`); the system is refused anyway.
            elements.push(Element {
                name: e.name.clone(),
                law,
                from: from.unwrap_or(End::Ground),
                to: to.unwrap_or(End::Ground),
                profile,
                direction,
            });
        }
        elements
    }

    /// Refuses an element or load acting along a horizontal axis on a body none of whose DOFs
    /// that axis moves (a lateral spring on a body with only `z` and `pitch`): it would act on
    /// nothing there.
    fn spatial_on_planar(&mut self, ends: &Ends, end: &End, axis: Axis, pos: Pos, what: &str) {
        let End::Body { body, .. } = end else {
            return;
        };
        let b = &ends.bodies[*body];
        if axis != Axis::Z && !b.moves_along(axis, end) {
            let dofs: Vec<&str> = DofKind::ALL
                .iter()
                .filter(|k| b.dof(**k).is_some())
                .map(|k| k.keyword())
                .collect();
            let needed: Vec<&str> = std::iter::once(axis.translation())
                .chain(axis.rotations().iter().map(|r| r.0))
                .map(|k| k.keyword())
                .collect();
            self.diag.push(
                pos,
                format!(
                    "{what}.direction: `{}` acts on a planar body: body `{}` has the DOFs [{}], none of which a force along {} moves; give it one of {} or drop `direction`",
                    axis.keyword(),
                    b.name,
                    dofs.join(", "),
                    axis.keyword(),
                    needed.join(", ")
                ),
            );
        }
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
            RawLaw::Wheelset(_) => unreachable!("wheelsets are compiled by `wheelset`"),
        }
    }

    /// A wheelset: one element per wheel (`<name>_l`, `<name>_r`), each a vertical contact
    /// from the wheelset at `y = -/+ e0` to its rail point, with the wheel's tangential law.
    fn wheelset(
        &mut self,
        e: &RawElement,
        w: &RawWheelset,
        ends: &Ends,
        profiles: &[Profile],
        what: &str,
    ) -> Vec<Element> {
        let body = self.wheelset_body(e, ends, what);
        let rails = self.wheelset_rails(w, ends, what);
        let wheel_profiles: Vec<usize> = w
            .profiles
            .iter()
            .map(|named| {
                let to = Some(End::Moving(0));
                self.element_profile(named, to.as_ref(), ends, profiles, what)
            })
            .collect();
        let lateral: Vec<Option<usize>> = w
            .lateral_rails
            .iter()
            .map(|(n, p)| self.lateral_rail(n, *p, ends, what))
            .collect();
        let law = self.wheel_law(e, w, body, what);
        Side::BOTH
            .iter()
            .enumerate()
            .map(|(i, &side)| {
                let wheel = Wheel {
                    side,
                    rail: lateral.get(i).copied().flatten(),
                    ..law.clone()
                };
                let lever = match side {
                    Side::Left => Expr::Neg(Box::new(law.half_gauge.clone())),
                    Side::Right => law.half_gauge.clone(),
                };
                Element {
                    name: format!("{}_{}", e.name, side.suffix()),
                    law: Law::Wheel(Box::new(wheel)),
                    from: match body {
                        Some(b) => End::Body {
                            body: b,
                            x: None,
                            y: Some(lever),
                            z: None,
                        },
                        None => End::Ground,
                    },
                    to: rails.get(i).cloned().flatten().unwrap_or(End::Ground),
                    profile: wheel_profiles.get(i).copied(),
                    direction: Axis::Z,
                }
            })
            .collect()
    }

    /// The rail points of a wheelset's wheels, each refused unless it is a moving point.
    fn wheelset_rails(&mut self, w: &RawWheelset, ends: &Ends, what: &str) -> Vec<Option<End>> {
        let rails: Vec<Option<End>> = w
            .rails
            .iter()
            .map(|(n, p)| ends.resolve(n, *p, &format!("{what}.rails"), self.diag))
            .collect();
        for (end, (n, p)) in rails.iter().zip(&w.rails) {
            if end.as_ref().is_some_and(|t| !matches!(t, End::Moving(_))) {
                self.diag.push(*p, format!("{what}.rails: `{n}` is not a moving point; a wheel rolls on a rail point (`moving.points`: {})", names(ends.points.iter().map(|p| &p.name))));
            }
        }
        rails
    }

    /// The law both wheels of a wheelset share (the left side's, without a lateral rail):
    /// gauge, radius, Hertz constant, geometry, creep and flange fields.
    fn wheel_law(
        &mut self,
        e: &RawElement,
        w: &RawWheelset,
        body: Option<usize>,
        what: &str,
    ) -> Wheel {
        let half_gauge = self.req_or(&w.half_gauge, &format!("{what}.half_gauge"), f64::NAN);
        let radius = self.req_or(&w.radius, &format!("{what}.radius"), f64::NAN);
        let hertz = self.req_or(&w.hertz, &format!("{what}.hertz"), f64::NAN);
        let geometry = match &w.geometry {
            Some(RawGeometry::Conicity(c)) => Geometry::Conicity(self.req_or(
                &Some(c.clone()),
                &format!("{what}.conicity"),
                f64::NAN,
            )),
            Some(RawGeometry::Table {
                shift,
                radius,
                angle,
                ..
            }) => Geometry::Table {
                shift: self.each(shift, &format!("{what}.geometry.shift")),
                radius: self.each(radius, &format!("{what}.geometry.radius")),
                angle: self.each(angle, &format!("{what}.geometry.angle")),
            },
            None => Geometry::Conicity(Expr::Num(f64::NAN)),
        };
        let creep = w.creep.as_ref();
        let mut creep_field = |key: &str, field: fn(&RawCreep) -> &Option<Field>| {
            let written = creep.and_then(|c| field(c).clone());
            self.req_or(&written, &format!("{what}.creep.{key}"), f64::NAN)
        };
        let young = creep_field("young", |c| &c.young);
        let poisson = creep_field("poisson", |c| &c.poisson);
        let friction = creep_field("friction", |c| &c.friction);
        let rail_radius = creep_field("rail_radius", |c| &c.rail_radius);
        let wheel_profile_radius = creep
            .is_some_and(|c| c.wheel_profile_radius.is_some())
            .then(|| creep_field("wheel_profile_radius", |c| &c.wheel_profile_radius));
        let flange = w.flange.as_ref().map(|f| {
            (
                self.req_or(&f.clearance, &format!("{what}.flange.clearance"), f64::NAN),
                self.req_or(&f.stiffness, &format!("{what}.flange.stiffness"), f64::NAN),
            )
        });
        Wheel {
            wheelset: e.name.clone(),
            side: Side::Left,
            body: body.unwrap_or(0),
            rail: None,
            half_gauge,
            radius,
            hertz,
            geometry,
            young,
            poisson,
            friction,
            rail_radius,
            wheel_profile_radius,
            flange,
        }
    }

    /// The wheelset body of a wheelset element: a body's centre with the DOFs `y`, `z`,
    /// `roll` and `yaw` (and no `pitch`: the wheelset's spin enters only through the
    /// creepages).
    fn wheelset_body(&mut self, e: &RawElement, ends: &Ends, what: &str) -> Option<usize> {
        let (name, pos) = e.from.as_ref()?;
        let end = ends.resolve(name, *pos, &format!("{what}.from"), self.diag)?;
        let End::Body { body, x: None, .. } = end else {
            self.diag.push(*pos, format!("{what}.from: a wheelset acts on a body's centre (its wheelset), not on `{name}`"));
            return None;
        };
        let b = &ends.bodies[body];
        let needed = [DofKind::Y, DofKind::Z, DofKind::Roll, DofKind::Yaw];
        let missing: Vec<&str> = needed
            .iter()
            .filter(|k| b.dof(**k).is_none())
            .map(|k| k.keyword())
            .collect();
        if !missing.is_empty() {
            self.diag.push(*pos, format!("{what}.from: the wheelset body `{name}` needs the DOFs y, z, roll and yaw (a spatial body); it lacks {}", missing.join(", ")));
            return None;
        }
        if b.pitch.is_some() {
            self.diag.push(*pos, format!("{what}.from: the wheelset body `{name}` has a pitch DOF: a wheelset's rotation about its axle is its rolling, which enters only through the creepages; remove `pitch` from its `dofs`"));
            return None;
        }
        Some(body)
    }

    /// A body carrying a rail laterally: a body with a `y` DOF.
    fn lateral_rail(&mut self, name: &str, pos: Pos, ends: &Ends, what: &str) -> Option<usize> {
        let found = ends.bodies.iter().position(|b| b.name == name);
        match found {
            Some(b) if ends.bodies[b].y.is_some() => Some(b),
            Some(_) => {
                self.diag.push(pos, format!("{what}.lateral_rails: body `{name}` has no `y` DOF to carry the rail laterally"));
                None
            }
            None => {
                self.diag.push(
                    pos,
                    format!(
                        "{what}.lateral_rails: unknown body `{name}`; bodies: {}",
                        names(ends.bodies.iter().map(|b| &b.name))
                    ),
                );
                None
            }
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
            if let Some(at) = &at {
                self.spatial_on_planar(
                    ends,
                    at,
                    l.direction.0,
                    l.direction.1.unwrap_or(l.pos),
                    &what,
                );
            }
            if let (Some(at), Some(force)) = (at, force) {
                loads.push(Load {
                    name: l.name.clone(),
                    at,
                    force,
                    direction: l.direction.0,
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
            return match point {
                None => Some(End::centre(bi)),
                Some(p) => match self.bodies[bi].points.iter().find(|q| q.name == p) {
                    Some(q) => Some(End::Body {
                        body: bi,
                        x: Some(q.x.clone()),
                        y: q.y.clone(),
                        z: q.z.clone(),
                    }),
                    None => {
                        diag.push(
                            pos,
                            format!(
                                "{what}: body `{body_name}` has no point `{p}`; its points: {}",
                                names(self.bodies[bi].points.iter().map(|p| &p.name))
                            ),
                        );
                        None
                    }
                },
            };
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
