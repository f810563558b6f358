//! The structure of a description: bodies and their DOFs, beams (modes, supports, links),
//! moving points (the speed of the moving frame) and sensors. Counts (`modes`,
//! `supports.count`) must be integers fixed for every sample.

use super::parameters::{structural_count, structural_values};
use super::*;

impl Compiler<'_, '_> {
    /// The bodies with their points, and the DOFs in body order (each body's in the order
    /// written).
    pub(super) fn bodies(&mut self) -> (Vec<Body>, Vec<Dof>) {
        let mut bodies = Vec::new();
        let mut dofs = Vec::new();
        for b in &self.raw.bodies {
            let what = format!("bodies.{}", b.name);
            let mass = self.scope.req(&b.mass, &format!("{what}.mass"), self.diag);
            let mut body = Body {
                name: b.name.clone(),
                doc: b.doc.clone(),
                mass: mass.unwrap_or(Expr::Num(f64::NAN)),
                inertia: None,
                roll_inertia: None,
                yaw_inertia: None,
                inertia_map: !b.inertia_scalar && !b.inertia.is_empty(),
                z: None,
                pitch: None,
                y: None,
                roll: None,
                yaw: None,
                x: None,
                points: Vec::new(),
            };
            self.inertias(b, &what, &mut body);
            for (kind, _) in &b.dofs {
                let i = dofs.len();
                dofs.push(Dof {
                    name: format!("{}_{}", kind.symbol(), b.name),
                    body: bodies.len(),
                    kind: *kind,
                });
                let slot = match kind {
                    DofKind::Z => &mut body.z,
                    DofKind::Pitch => &mut body.pitch,
                    DofKind::Y => &mut body.y,
                    DofKind::Roll => &mut body.roll,
                    DofKind::Yaw => &mut body.yaw,
                    DofKind::X => &mut body.x,
                };
                *slot = Some(i);
            }
            for p in &b.points {
                let w = format!("{what}.points.{}", p.name);
                let x = self.scope.resolve(&p.x, &w, self.diag);
                let y =
                    p.y.as_ref()
                        .and_then(|f| self.scope.resolve(f, &w, self.diag));
                let z =
                    p.z.as_ref()
                        .and_then(|f| self.scope.resolve(f, &w, self.diag));
                if let Some(x) = x {
                    body.points.push(BodyPoint {
                        name: p.name.clone(),
                        x,
                        y: y.filter(|e| !e.is_zero()),
                        z: z.filter(|e| !e.is_zero()),
                    });
                }
            }
            bodies.push(body);
        }
        (bodies, dofs)
    }

    /// A body's moments of inertia: one for each rotation DOF (required), none for a rotation
    /// it does not have (refused).
    fn inertias(&mut self, b: &RawBody, what: &str, body: &mut Body) {
        for kind in [DofKind::Roll, DofKind::Pitch, DofKind::Yaw] {
            let has_dof = b.dofs.iter().any(|d| d.0 == kind);
            let given = b.inertia.iter().find(|(k, _)| *k == kind).map(|(_, f)| f);
            let field = if b.inertia_scalar {
                format!("{what}.inertia")
            } else {
                format!("{what}.inertia.{}", kind.keyword())
            };
            let value = match (given, has_dof) {
                (Some(f), true) => self.scope.resolve(f, &field, self.diag),
                (None, true) => {
                    let how = if kind == DofKind::Pitch {
                        "`inertia` (kg m^2)".to_owned()
                    } else {
                        format!("`inertia: {{{}: ...}}` (kg m^2)", kind.keyword())
                    };
                    self.diag.push(
                        b.inertia_pos.unwrap_or(b.pos),
                        format!("{what}: a body with a {} DOF needs {how}", kind.keyword()),
                    );
                    None
                }
                (Some(f), false) => {
                    self.diag.push(
                        f.pos,
                        format!(
                            "{field}: the body has no {} DOF (add `{}` to its `dofs`)",
                            kind.keyword(),
                            kind.keyword()
                        ),
                    );
                    None
                }
                (None, false) => None,
            };
            match kind {
                DofKind::Roll => body.roll_inertia = value,
                DofKind::Pitch => body.inertia = value,
                _ => body.yaw_inertia = value,
            }
        }
    }

    /// The beams, their counts (`modes`, `supports.count`) evaluated from the parameters that
    /// are the same for every sample.
    pub(super) fn beams(&mut self, parameters: &[Parameter], derived_order: &[usize]) -> Vec<Beam> {
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
    pub(super) fn moving(&mut self, beams: &[Beam]) -> (Vec<MovingPoint>, Expr) {
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
    pub(super) fn sensors(&mut self, beams: &[Beam]) -> Vec<Sensor> {
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
}

/// The parameters and the values of those that are the same for every sample: what a count
/// is evaluated from.
struct Counts<'p> {
    parameters: &'p [Parameter],
    structural: &'p [Option<f64>],
}
