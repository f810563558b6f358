//! One sample's model in numbers: the [`System`] with every expression evaluated for one set of
//! parameter values, each field checked against its domain. This is what the engine runs.
//!
//! Units are SI; displacements positive downward, pitch positive nose-up, `x` forward. A body
//! point at `x` moves down by `u = z + c beta` with `c = -x` (a nose-up pitch lifts the front).

use crate::expr::Expr;
use crate::sampled::{Sampled, SampledError};
use crate::schema::Outside;
use crate::schema::{Axis, DofKind};
use crate::system::{
    Beam, End, Geometry, Interpolation, Law, ParamSource, Profile, Source, Supports, System,
};

/// Largest equivalent conicity a wheelset may declare (rad): 0.05-0.4 in service (EN 15302),
/// beyond 0.6 the linearised geometry of a tread no longer describes a wheel on a rail.
pub const MAX_CONICITY: f64 = 0.6;

/// A field out of its domain: which, its value and what is allowed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("`{path}` = {value} is out of range: {allowed}")]
pub struct FieldError {
    /// Dotted path of the field (`bodies.c.mass`).
    pub path: String,
    /// Its value.
    pub value: f64,
    /// What is allowed.
    pub allowed: String,
    /// The sampled parameters its value is computed from (through the description's
    /// expressions and derived parameters), in declaration order: what a user changed to get
    /// here, named in their own words.
    pub sources: Vec<String>,
}

/// The rigid-DOF participation of a body point along an element's axis: `u = q_t + c_1 q_r1
/// + c_2 q_r2`, `q_t` the translation along the axis and `q_r1`, `q_r2` the rotations that
/// move the point along it with their lever arms (vertical: `u = z - x beta + y phi`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointTerms {
    /// The body's translation DOF along the axis (`z` for a vertical element).
    pub z: Option<usize>,
    /// The first rotation and its coefficient (pitch with `c = -x` for a vertical element).
    pub pitch: Option<(usize, f64)>,
    /// The second rotation and its coefficient (roll with `c = y` for a vertical element).
    pub roll: Option<(usize, f64)>,
}

impl PointTerms {
    /// `u = q_t + c_1 q_r1 + c_2 q_r2` of the rigid state `q` (left to right, as written).
    #[inline]
    pub fn displacement(&self, q: &[f64]) -> f64 {
        let u = match (self.z, self.pitch) {
            (Some(z), Some((p, c))) => q[z] + c * q[p],
            (Some(z), None) => q[z],
            (None, Some((p, c))) => c * q[p],
            (None, None) => 0.0,
        };
        match self.roll {
            Some((r, c)) => u + c * q[r],
            None => u,
        }
    }

    /// Every DOF with its coefficient.
    pub fn terms(&self) -> impl Iterator<Item = (usize, f64)> {
        self.z
            .map(|z| (z, 1.0))
            .into_iter()
            .chain(self.pitch)
            .chain(self.roll)
    }
}

/// An end of an element or the point of a load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModelEnd {
    /// Fixed ground.
    Ground,
    /// A body point.
    Body(PointTerms),
    /// Moving point `i`.
    Moving(usize),
}

/// A force law in numbers.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelLaw {
    /// `f = preload + k d + c d'` (N).
    SpringDamper {
        /// N/m.
        k: f64,
        /// N s/m.
        c: f64,
        /// N.
        preload: f64,
    },
    /// `f = (d / g)^exponent` for `d > 0`, else 0 (N).
    Hertz {
        /// m/N^(1/exponent).
        g: f64,
        /// Exponent.
        exponent: f64,
    },
    /// `f = table(d) + c d'` (N), linear between points, end slopes beyond.
    Table {
        /// Deflections (m), strictly increasing.
        deflection: Vec<f64>,
        /// Forces (N).
        force: Vec<f64>,
        /// N s/m.
        c: f64,
    },
    /// One wheel of a wheelset: vertically `(d / g)^(3/2)` for `d > 0` (N), its tangential
    /// forces computed by the engine from the wheelset's motion.
    Wheel(Box<ModelWheel>),
}

/// The contact geometry of a wheelset in numbers (the right wheel's).
#[derive(Debug, Clone, PartialEq)]
pub enum ModelGeometry {
    /// Equivalent conicity `gamma` (rad): `rho(u) = gamma u`, `tan delta = gamma`.
    Conicity(f64),
    /// Against the shift `u` (m, increasing): rolling-radius change (m), contact angle (rad).
    Table {
        /// Shifts (m).
        shift: Vec<f64>,
        /// Rolling-radius changes (m).
        radius: Vec<f64>,
        /// Contact angles (rad).
        angle: Vec<f64>,
    },
}

/// One wheel of a wheelset in numbers (see [`crate::system::Wheel`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelWheel {
    /// `-1` for the left wheel, `+1` for the right one.
    pub side: f64,
    /// The wheelset's lateral DOF.
    pub y: usize,
    /// Its roll DOF.
    pub roll: usize,
    /// Its yaw DOF.
    pub yaw: usize,
    /// Its longitudinal DOF, if it has one.
    pub x: Option<usize>,
    /// The lateral DOF of the body carrying the rail, if any.
    pub rail: Option<usize>,
    /// `e0` (m).
    pub half_gauge: f64,
    /// `r0` (m).
    pub radius: f64,
    /// Hertz constant `G` (m/N^(2/3)).
    pub hertz: f64,
    /// Geometry.
    pub geometry: ModelGeometry,
    /// Young's modulus (Pa).
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Coefficient of friction.
    pub friction: f64,
    /// Rail head transverse radius (m).
    pub rail_radius: f64,
    /// Wheel tread transverse radius (m), `None` for a straight tread.
    pub wheel_profile_radius: Option<f64>,
    /// Flange clearance (m) and stiffness (N/m).
    pub flange: Option<(f64, f64)>,
}

impl ModelWheel {
    /// The incidences of the wheel's tangential motion on `n` rigid DOFs: lateral (the
    /// contact point's lateral motion relative to the rail, `y - r0 phi - y_rail`) and
    /// longitudinal (`x - s e0 psi`): a tangential stiffness or damping `k` adds `k b b^T`.
    pub fn tangential_incidence(&self, n: usize) -> [Vec<f64>; 2] {
        let mut lateral = vec![0.0; n];
        lateral[self.y] += 1.0;
        lateral[self.roll] -= self.radius;
        if let Some(r) = self.rail {
            lateral[r] -= 1.0;
        }
        let mut longitudinal = vec![0.0; n];
        longitudinal[self.yaw] -= self.side * self.half_gauge;
        if let Some(x) = self.x {
            longitudinal[x] += 1.0;
        }
        [lateral, longitudinal]
    }
}

impl ModelLaw {
    /// The force (N) at deflection `d` (m) and rate `dv` (m/s).
    #[inline]
    pub fn force(&self, d: f64, dv: f64) -> f64 {
        match self {
            ModelLaw::SpringDamper { k, c, preload } => {
                if *preload == 0.0 {
                    k * d + c * dv
                } else {
                    preload + k * d + c * dv
                }
            }
            ModelLaw::Hertz { g, exponent } => hertz(d, *g, *exponent),
            ModelLaw::Table {
                deflection,
                force,
                c,
            } => table(deflection, force, d) + c * dv,
            ModelLaw::Wheel(w) => hertz(d, w.hertz, 1.5),
        }
    }

    /// `df/dd` at `d` (N/m): the tangent stiffness.
    pub fn stiffness(&self, d: f64) -> f64 {
        match self {
            ModelLaw::SpringDamper { k, .. } => *k,
            ModelLaw::Hertz { g, exponent } => {
                if d > 0.0 {
                    exponent / g * (d / g).powf(exponent - 1.0)
                } else {
                    0.0
                }
            }
            ModelLaw::Table {
                deflection, force, ..
            } => {
                let i = segment(deflection, d);
                (force[i + 1] - force[i]) / (deflection[i + 1] - deflection[i])
            }
            ModelLaw::Wheel(w) => ModelLaw::Hertz {
                g: w.hertz,
                exponent: 1.5,
            }
            .stiffness(d),
        }
    }

    /// `df/dd'` (N s/m).
    pub fn damping(&self) -> f64 {
        match self {
            ModelLaw::SpringDamper { c, .. } | ModelLaw::Table { c, .. } => *c,
            ModelLaw::Hertz { .. } | ModelLaw::Wheel(_) => 0.0,
        }
    }

    /// The deflection (m) at which the static force is `f` (N), for a law that can carry it.
    pub fn static_deflection(&self, f: f64) -> Option<f64> {
        match self {
            ModelLaw::SpringDamper { k, preload, .. } => {
                if *k > 0.0 {
                    Some((f - preload) / k)
                } else {
                    (f == *preload).then_some(0.0)
                }
            }
            ModelLaw::Wheel(w) => ModelLaw::Hertz {
                g: w.hertz,
                exponent: 1.5,
            }
            .static_deflection(f),
            ModelLaw::Hertz { g, exponent } => {
                if f > 0.0 {
                    Some(if *exponent == 1.5 {
                        g * f.powf(2.0 / 3.0)
                    } else {
                        g * f.powf(1.0 / exponent)
                    })
                } else if f == 0.0 {
                    Some(0.0)
                } else {
                    None
                }
            }
            ModelLaw::Table {
                deflection, force, ..
            } => {
                // Monotone tables only: the segment whose force range holds f.
                let n = force.len();
                (0..n - 1).find_map(|i| {
                    let (f0, f1) = (force[i], force[i + 1]);
                    let inside = (f0..=f1).contains(&f) || (f1..=f0).contains(&f);
                    let ends = (i == 0 && (f < f0.min(f1))) || (i == n - 2 && f > f0.max(f1));
                    (inside || ends).then(|| {
                        deflection[i] + (f - f0) * (deflection[i + 1] - deflection[i]) / (f1 - f0)
                    })
                })
            }
        }
    }

    /// Whether this is a contact law.
    pub fn is_contact(&self) -> bool {
        matches!(self, ModelLaw::Hertz { .. } | ModelLaw::Wheel(_))
    }

    /// The wheel, for a wheel of a wheelset.
    pub fn wheel(&self) -> Option<&ModelWheel> {
        match self {
            ModelLaw::Wheel(w) => Some(w),
            _ => None,
        }
    }
}

/// Hertz force `(d / g)^e` for `d > 0`, else 0; for `e = 3/2` computed as `x sqrt(x)`.
#[inline]
pub fn hertz(d: f64, g: f64, exponent: f64) -> f64 {
    if d > 0.0 {
        let x = d / g;
        if exponent == 1.5 {
            x * x.sqrt()
        } else {
            x.powf(exponent)
        }
    } else {
        0.0
    }
}

fn segment(xs: &[f64], d: f64) -> usize {
    xs.partition_point(|&x| x <= d).clamp(1, xs.len() - 1) - 1
}

fn table(xs: &[f64], fs: &[f64], d: f64) -> f64 {
    let i = segment(xs, d);
    fs[i] + (d - xs[i]) * (fs[i + 1] - fs[i]) / (xs[i + 1] - xs[i])
}

/// A force element in numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelElement {
    /// Its law.
    pub law: ModelLaw,
    /// Upper end.
    pub from: ModelEnd,
    /// Lower end.
    pub to: ModelEnd,
    /// Profile under the lower end.
    pub profile: Option<usize>,
}

impl ModelElement {
    /// Its incidence on `n` rigid DOFs: `b` with `d = b . q + ...` for the rigid state `q`
    /// (the body terms of the upper end counted +1, of the lower end -1, a pitch by its lever
    /// arm), so a stiffness `k` adds `k b b^T` to the rigid stiffness matrix.
    pub fn incidence(&self, n: usize) -> Vec<f64> {
        let mut b = vec![0.0; n];
        for (end, sign) in [(&self.from, 1.0), (&self.to, -1.0)] {
            if let ModelEnd::Body(t) = end {
                for (i, c) in t.terms() {
                    b[i] += sign * c;
                }
            }
        }
        b
    }
}

/// A constant load in numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelLoad {
    /// Where.
    pub at: ModelEnd,
    /// Force (N, downward).
    pub force: f64,
}

/// A coefficient group in numbers (see [`crate::system::Group`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelGroup {
    /// Common coefficient (`None`: 1).
    pub coefficient: Option<f64>,
    /// Sources and signs.
    pub terms: Vec<(Source, f64)>,
}

/// A support-chain level in numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelLevel {
    /// Mass per support (kg).
    pub mass: f64,
    /// Link to the level above: stiffness (N/m), damping (N s/m).
    pub k: f64,
    /// See `k`.
    pub c: f64,
    /// Shear to the neighbours: stiffness and damping.
    pub shear: Option<(f64, f64)>,
}

/// Periodic supports in numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelSupports {
    /// Spacing (m).
    pub spacing: f64,
    /// Count.
    pub count: usize,
    /// First support (m).
    pub first: f64,
    /// Levels from the beam down.
    pub levels: Vec<ModelLevel>,
    /// Last level to ground: stiffness, damping.
    pub ground: (f64, f64),
}

/// A modal beam in numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelBeam {
    /// Length (m).
    pub length: f64,
    /// Modes.
    pub modes: usize,
    /// kg/m.
    pub mass_per_length: f64,
    /// N m^2.
    pub bending_stiffness: f64,
    /// Modal damping ratio.
    pub damping_ratio: f64,
    /// Points off the beam.
    pub outside: Outside,
    /// Supports.
    pub supports: Option<ModelSupports>,
}

/// A profile in numbers.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelProfile {
    /// A weighted sum of other profiles (indices, weights), each generated or harmonic.
    Combination(Vec<(usize, f64)>),
    /// Supplied per sample (the `irregularity` stage's profile), read between its points
    /// by `interpolation`.
    Generated {
        /// How the points are read between them.
        interpolation: Interpolation,
    },
    /// `amplitude sin(2 pi x / wavelength + phase)`.
    Harmonic {
        /// m.
        amplitude: f64,
        /// m.
        wavelength: f64,
        /// rad.
        phase: f64,
    },
}

/// One sample's model.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// Every parameter's value, in table order.
    pub values: Vec<f64>,
    /// Mass or inertia of each DOF.
    pub dof_mass: Vec<f64>,
    /// Elements.
    pub elements: Vec<ModelElement>,
    /// Loads.
    pub loads: Vec<ModelLoad>,
    /// Per DOF, its generalised force groups.
    pub assembly: Vec<Vec<ModelGroup>>,
    /// Beams.
    pub beams: Vec<ModelBeam>,
    /// Frame speed (m/s).
    pub speed: f64,
    /// Moving points: beam and offset (m).
    pub points: Vec<(Option<usize>, f64)>,
    /// Sensors: beam and position (m).
    pub sensors: Vec<(usize, f64)>,
    /// Profiles.
    pub profiles: Vec<ModelProfile>,
    /// Per profile, where a generated one's irregularity ends and the taper before it
    /// (`[x, taper]`, m), when it does.
    pub profile_ends: Vec<Option<[f64; 2]>>,
}

impl System {
    /// Every parameter's value from a design of this system, the fixed values and the
    /// derived expressions; a design of another system is refused.
    pub fn values(&self, design: &Sampled) -> Result<Vec<f64>, SampledError> {
        self.check_design(design)?;
        let mut sampled = design.as_slice().iter().copied();
        let mut v: Vec<f64> = self
            .parameters
            .iter()
            .map(|p| match p.source {
                ParamSource::Sampled { .. } => sampled
                    .next()
                    .expect("checked: one value per sampled parameter"),
                ParamSource::Fixed(x) => x,
                ParamSource::Derived(_) => f64::NAN,
            })
            .collect();
        for &i in &self.derived_order {
            if let ParamSource::Derived(e) = &self.parameters[i].source {
                v[i] = e.eval(&v);
            }
        }
        Ok(v)
    }

    /// The design at the nominal values of the sampled parameters.
    pub fn nominal(&self) -> Sampled {
        let nominal: Vec<f64> = self
            .parameters
            .iter()
            .filter_map(|p| match p.source {
                ParamSource::Sampled { nominal, .. } => Some(nominal),
                _ => None,
            })
            .collect();
        self.sampled_values(nominal)
            .expect("one nominal value per sampled parameter")
    }

    /// The sampling ranges of the sampled parameters.
    pub fn ranges(&self) -> Vec<[f64; 2]> {
        self.parameters
            .iter()
            .filter_map(|p| match p.source {
                ParamSource::Sampled { range, .. } => Some(range),
                _ => None,
            })
            .collect()
    }

    /// The model of one design, every field checked; the first field out of its domain is the
    /// error (a design of another system is refused as the field `parameters`).
    pub fn instantiate(&self, design: &Sampled) -> Result<Model, FieldError> {
        self.instantiate_all(design)
            .map_err(|errors| errors.into_iter().next().expect("at least one"))
    }

    /// [`System::instantiate`], reporting every field out of its domain (in the order of the
    /// description's sections), not only the first: the checks of a description at its
    /// nominal values list all of them at once.
    pub fn instantiate_all(&self, design: &Sampled) -> Result<Model, Vec<FieldError>> {
        let v = self.values(design).map_err(|e| {
            vec![FieldError {
                path: "parameters".to_owned(),
                value: design.len() as f64,
                allowed: e.to_string(),
                sources: Vec::new(),
            }]
        })?;
        let non_finite: Vec<FieldError> = self
            .parameters
            .iter()
            .enumerate()
            .filter(|&(i, _)| !v[i].is_finite())
            .map(|(i, p)| FieldError {
                path: format!("parameters.{}", p.name),
                value: v[i],
                allowed: "finite".to_owned(),
                sources: self.sampled_sources([i]),
            })
            .collect();
        if !non_finite.is_empty() {
            return Err(non_finite);
        }
        let mut c = Checker {
            system: self,
            values: &v,
            errors: Vec::new(),
        };
        let dof_mass = c.bodies();
        let elements = c.elements();
        let loads = c.loads();
        let assembly = c.assembly();
        let (beams, length_valid) = c.beams();
        let speed = if self.elements.iter().any(|e| e.law.wheel().is_some()) {
            // The creepages divide by the speed.
            c.positive(|| "moving.speed".to_owned(), &self.speed)
        } else {
            c.non_negative(|| "moving.speed".to_owned(), &self.speed)
        };
        let points = c.points();
        let sensors = c.sensors(&beams, &length_valid);
        let profiles = c.profiles();
        let profile_ends = c.profile_ends();
        if !c.errors.is_empty() {
            // A wheelset's two wheels share its fields: one report per field.
            let mut errors: Vec<FieldError> = Vec::with_capacity(c.errors.len());
            for e in c.errors {
                if !errors
                    .iter()
                    .any(|k| k.path == e.path && k.value.to_bits() == e.value.to_bits())
                {
                    errors.push(e);
                }
            }
            return Err(errors);
        }
        Ok(Model {
            values: v,
            dof_mass,
            elements,
            loads,
            assembly,
            beams,
            speed,
            points,
            sensors,
            profiles,
            profile_ends,
        })
    }
}

/// The domain checks of one instantiation: each records a field out of its domain (its path
/// and the sampled parameters it comes from, built only then) and passes the value on. The
/// phases of [`System::instantiate_all`] (one per section of the description) are its
/// methods too.
struct Checker<'a> {
    system: &'a System,
    values: &'a [f64],
    errors: Vec<FieldError>,
}

impl Checker<'_> {
    /// Records `path` = `x` unless it is finite and `ok`; `from` are the expressions `x` and
    /// the condition read (for [`FieldError::sources`]).
    fn check(
        &mut self,
        path: impl FnOnce() -> String,
        x: f64,
        ok: bool,
        allowed: impl FnOnce() -> String,
        from: &[&Expr],
    ) -> f64 {
        if !(x.is_finite() && ok) {
            self.errors.push(FieldError {
                path: path(),
                value: x,
                allowed: allowed(),
                sources: self
                    .system
                    .sampled_sources(from.iter().flat_map(|e| e.parameters())),
            });
        }
        x
    }

    /// The value of `e`, checked finite and > 0.
    fn positive(&mut self, path: impl FnOnce() -> String, e: &Expr) -> f64 {
        let x = e.eval(self.values);
        self.check(path, x, x > 0.0, || "finite and > 0".to_owned(), &[e])
    }

    /// The value of `e`, checked finite and >= 0.
    fn non_negative(&mut self, path: impl FnOnce() -> String, e: &Expr) -> f64 {
        let x = e.eval(self.values);
        self.check(path, x, x >= 0.0, || "finite and >= 0".to_owned(), &[e])
    }

    /// The value of `e`, checked finite.
    fn finite(&mut self, path: impl FnOnce() -> String, e: &Expr) -> f64 {
        let x = e.eval(self.values);
        self.check(path, x, true, || "finite".to_owned(), &[e])
    }

    /// The value of `e`, unchecked.
    fn eval(&self, e: &Expr) -> f64 {
        e.eval(self.values)
    }

    /// The mass or inertia of each DOF (masses and inertias > 0, body points finite).
    fn bodies(&mut self) -> Vec<f64> {
        let system = self.system;
        let mut dof_mass = vec![0.0; system.dofs.len()];
        for b in &system.bodies {
            let m = self.positive(|| format!("bodies.{}.mass", b.name), &b.mass);
            for kind in DofKind::ALL {
                let Some(i) = b.dof(kind) else { continue };
                dof_mass[i] = match b.inertia_of(kind) {
                    Some(j) => self.positive(|| b.inertia_path(kind), j),
                    None => m,
                };
            }
            for p in &b.points {
                let path = || format!("bodies.{}.points.{}", b.name, p.name);
                self.finite(path, &p.x);
                for c in [&p.y, &p.z].into_iter().flatten() {
                    self.finite(path, c);
                }
            }
        }
        dof_mass
    }

    /// An end in numbers along `axis`: a body point's rigid-DOF participation (no rotation
    /// term where the lever arm is 0).
    fn end(&self, e: &End, axis: Axis) -> ModelEnd {
        match e {
            End::Ground => ModelEnd::Ground,
            End::Moving(i) => ModelEnd::Moving(*i),
            End::Body { body, .. } => {
                let b = &self.system.bodies[*body];
                let [first, second] = axis.rotations().map(|(kind, coordinate, sign)| {
                    let lever = e.coordinate(coordinate).filter(|c| !c.is_zero())?;
                    let c = if sign < 0.0 {
                        -self.eval(lever)
                    } else {
                        self.eval(lever)
                    };
                    b.dof(kind).map(|d| (d, c))
                });
                ModelEnd::Body(PointTerms {
                    z: b.dof(axis.translation()),
                    pitch: first,
                    roll: second,
                })
            }
        }
    }

    /// The elements: each law checked, the ends in numbers.
    fn elements(&mut self) -> Vec<ModelElement> {
        let system = self.system;
        let mut elements = Vec::with_capacity(system.elements.len());
        for e in &system.elements {
            let law = self.law(&e.name, &e.law);
            elements.push(ModelElement {
                law,
                from: self.end(&e.from, e.direction),
                to: self.end(&e.to, e.direction),
                profile: e.profile,
            });
        }
        elements
    }

    /// The law of element `name`: stiffness and damping >= 0, a Hertz constant and
    /// exponent > 0, a table's points.
    fn law(&mut self, name: &str, law: &Law) -> ModelLaw {
        let w = || format!("elements.{name}");
        match law {
            Law::SpringDamper {
                k,
                c: damping,
                preload,
            } => ModelLaw::SpringDamper {
                k: self.non_negative(|| format!("{}.k", w()), k),
                c: self.non_negative(|| format!("{}.c", w()), damping),
                preload: self.finite(|| format!("{}.preload", w()), preload),
            },
            Law::Hertz { g, exponent } => ModelLaw::Hertz {
                g: self.positive(|| format!("{}.g", w()), g),
                exponent: self.positive(|| format!("{}.exponent", w()), exponent),
            },
            Law::Table {
                deflection,
                force,
                c: damping,
            } => {
                let (d, f) = self.table(&w, deflection, force);
                ModelLaw::Table {
                    deflection: d,
                    force: f,
                    c: self.non_negative(|| format!("{}.c", w()), damping),
                }
            }
            Law::Wheel(wheel) => ModelLaw::Wheel(Box::new(self.wheel(wheel))),
        }
    }

    /// A wheel in numbers, every field of its wheelset checked (the paths name the declared
    /// wheelset, `elements.<wheelset>.<field>`): dimensions > 0, the conicity in (0, 0.6], a
    /// geometry table's shifts increasing and angles within (-pi/2, pi/2), the materials, a
    /// friction coefficient > 0 and a flange clearance >= 0.
    fn wheel(&mut self, wheel: &crate::system::Wheel) -> ModelWheel {
        let w = || format!("elements.{}", wheel.wheelset);
        let b = &self.system.bodies[wheel.body];
        let geometry = match &wheel.geometry {
            Geometry::Conicity(c) => {
                let g = self.eval(c);
                ModelGeometry::Conicity(self.check(
                    || format!("{}.conicity", w()),
                    g,
                    g > 0.0 && g <= MAX_CONICITY,
                    || {
                        format!(
                            "in (0, {MAX_CONICITY}] rad (equivalent conicity; 0.05-0.4 in service)"
                        )
                    },
                    &[c],
                ))
            }
            Geometry::Table {
                shift,
                radius,
                angle,
            } => {
                let u: Vec<f64> = shift.iter().map(|e| self.eval(e)).collect();
                for (i, pair) in u.windows(2).enumerate() {
                    self.check(
                        || format!("{}.geometry.shift[{}]", w(), i + 1),
                        pair[1],
                        pair[1] > pair[0],
                        || "finite and above the previous shift".to_owned(),
                        &[&shift[i], &shift[i + 1]],
                    );
                }
                let r: Vec<f64> = radius
                    .iter()
                    .enumerate()
                    .map(|(i, e)| self.finite(|| format!("{}.geometry.radius[{i}]", w()), e))
                    .collect();
                let a: Vec<f64> = angle
                    .iter()
                    .enumerate()
                    .map(|(i, e)| {
                        let v = self.eval(e);
                        self.check(
                            || format!("{}.geometry.angle[{i}]", w()),
                            v,
                            v.abs() < std::f64::consts::FRAC_PI_2,
                            || "in (-pi/2, pi/2) rad".to_owned(),
                            &[e],
                        )
                    })
                    .collect();
                ModelGeometry::Table {
                    shift: u,
                    radius: r,
                    angle: a,
                }
            }
        };
        let poisson = self.eval(&wheel.poisson);
        ModelWheel {
            side: wheel.side.sign(),
            y: b.y.expect("checked: a wheelset body has y"),
            roll: b.roll.expect("checked: a wheelset body rolls"),
            yaw: b.yaw.expect("checked: a wheelset body yaws"),
            x: b.x,
            rail: wheel.rail.and_then(|r| self.system.bodies[r].y),
            half_gauge: self.positive(|| format!("{}.half_gauge", w()), &wheel.half_gauge),
            radius: self.positive(|| format!("{}.radius", w()), &wheel.radius),
            hertz: self.positive(|| format!("{}.hertz", w()), &wheel.hertz),
            geometry,
            young: self.positive(|| format!("{}.creep.young", w()), &wheel.young),
            poisson: self.check(
                || format!("{}.creep.poisson", w()),
                poisson,
                (0.0..=0.5).contains(&poisson),
                || "in [0, 0.5] (the range of Kalker's table)".to_owned(),
                &[&wheel.poisson],
            ),
            friction: self.positive(|| format!("{}.creep.friction", w()), &wheel.friction),
            rail_radius: self.positive(|| format!("{}.creep.rail_radius", w()), &wheel.rail_radius),
            wheel_profile_radius: wheel.wheel_profile_radius.as_ref().map(|e| {
                let v = self.eval(e);
                self.check(
                    || format!("{}.creep.wheel_profile_radius", w()),
                    v,
                    v != 0.0,
                    || "finite and not 0 (m; negative for a hollow tread)".to_owned(),
                    &[e],
                )
            }),
            flange: wheel.flange.as_ref().map(|(c, k)| {
                (
                    self.non_negative(|| format!("{}.flange.clearance", w()), c),
                    self.non_negative(|| format!("{}.flange.stiffness", w()), k),
                )
            }),
        }
    }

    /// A table law's deflections and forces (`w()` the element's path): as many of each, at
    /// least 2, the deflections increasing, the forces finite.
    fn table(
        &mut self,
        w: &dyn Fn() -> String,
        deflection: &[Expr],
        force: &[Expr],
    ) -> (Vec<f64>, Vec<f64>) {
        let d: Vec<f64> = deflection.iter().map(|e| self.eval(e)).collect();
        let f: Vec<f64> = force.iter().map(|e| self.eval(e)).collect();
        self.check(
            || format!("{}.deflection", w()),
            d.len() as f64,
            d.len() >= 2 && d.len() == f.len(),
            || "as many points as `force`, at least 2".to_owned(),
            &[],
        );
        for (i, pair) in d.windows(2).enumerate() {
            self.check(
                || format!("{}.deflection[{}]", w(), i + 1),
                pair[1],
                pair[1] > pair[0],
                || "finite and above the previous point".to_owned(),
                &[&deflection[i], &deflection[i + 1]],
            );
        }
        for (i, x) in force.iter().enumerate() {
            self.finite(|| format!("{}.force[{i}]", w()), x);
        }
        (d, f)
    }

    /// The loads: a finite force at a point in numbers.
    fn loads(&mut self) -> Vec<ModelLoad> {
        let system = self.system;
        let mut loads = Vec::with_capacity(system.loads.len());
        for l in &system.loads {
            loads.push(ModelLoad {
                at: self.end(&l.at, l.direction),
                force: self.finite(|| format!("loads.{}.force", l.name), &l.force),
            });
        }
        loads
    }

    /// The generalised-force groups of each DOF, their coefficients evaluated.
    fn assembly(&self) -> Vec<Vec<ModelGroup>> {
        self.system
            .assembly
            .iter()
            .map(|groups| {
                groups
                    .iter()
                    .map(|g| ModelGroup {
                        coefficient: g.coefficient.as_ref().map(|e| self.eval(e)),
                        terms: g.terms.clone(),
                    })
                    .collect()
            })
            .collect()
    }

    /// The beams, and whether each one's length is valid (the sensors on it are checked
    /// against it).
    fn beams(&mut self) -> (Vec<ModelBeam>, Vec<bool>) {
        let system = self.system;
        let mut beams = Vec::with_capacity(system.beams.len());
        let mut length_valid = Vec::with_capacity(system.beams.len());
        for b in &system.beams {
            let w = || format!("beams.{}", b.name);
            let before = self.errors.len();
            let length = self.positive(|| format!("{}.length", w()), &b.length);
            length_valid.push(self.errors.len() == before);
            let supports = b
                .supports
                .as_ref()
                .map(|s| self.supports(&w, b, s, length, before));
            let zeta = self.eval(&b.damping_ratio);
            beams.push(ModelBeam {
                length,
                modes: b.modes,
                mass_per_length: self
                    .positive(|| format!("{}.mass_per_length", w()), &b.mass_per_length),
                bending_stiffness: self.positive(
                    || format!("{}.bending_stiffness", w()),
                    &b.bending_stiffness,
                ),
                damping_ratio: self.check(
                    || format!("{}.damping_ratio", w()),
                    zeta,
                    (0.0..1.0).contains(&zeta),
                    || "in [0, 1)".to_owned(),
                    &[&b.damping_ratio],
                ),
                outside: b.outside,
                supports,
            });
        }
        (beams, length_valid)
    }

    /// The supports of beam `b` (`w()` its path, `length` its length, `before` the number of
    /// errors before it): spacing, start, every support inside the beam, the levels and the
    /// link to the ground.
    fn supports(
        &mut self,
        w: &dyn Fn() -> String,
        b: &Beam,
        s: &Supports,
        length: f64,
        before: usize,
    ) -> ModelSupports {
        let spacing = self.positive(|| format!("{}.supports.spacing", w()), &s.spacing);
        let first = self.non_negative(|| format!("{}.supports.first", w()), &s.first);
        let last = first + (s.count.max(1) - 1) as f64 * spacing;
        // Only with a valid length, spacing and start (no follow-on problem).
        if self.errors.len() == before {
            self.check(
                || format!("{}.supports.count", w()),
                s.count as f64,
                last < length,
                || format!("supports from {first} m every {spacing} m must end inside the beam (length {length} m)"),
                &[&b.length, &s.spacing, &s.first],
            );
        }
        let mut levels = Vec::new();
        for (i, l) in s.levels.iter().enumerate() {
            let lw = || format!("{}.supports.levels[{i}]", w());
            levels.push(ModelLevel {
                mass: self.positive(|| format!("{}.mass", lw()), &l.mass),
                k: self.positive(|| format!("{}.link.k", lw()), &l.link.k),
                c: self.non_negative(|| format!("{}.link.c", lw()), &l.link.c),
                shear: l.shear.as_ref().map(|sh| {
                    (
                        self.non_negative(|| format!("{}.shear.k", lw()), &sh.k),
                        self.non_negative(|| format!("{}.shear.c", lw()), &sh.c),
                    )
                }),
            });
        }
        ModelSupports {
            spacing,
            count: s.count,
            first,
            levels,
            ground: (
                self.positive(|| format!("{}.supports.ground.k", w()), &s.ground.k),
                self.non_negative(|| format!("{}.supports.ground.c", w()), &s.ground.c),
            ),
        }
    }

    /// The moving points: beam and finite offset.
    fn points(&mut self) -> Vec<(Option<usize>, f64)> {
        let system = self.system;
        let mut points = Vec::with_capacity(system.points.len());
        for p in &system.points {
            points.push((
                p.beam,
                self.finite(|| format!("moving.points.{}.offset", p.name), &p.offset),
            ));
        }
        points
    }

    /// The sensors: each on its beam (checked only where the beam's length is valid).
    fn sensors(&mut self, beams: &[ModelBeam], length_valid: &[bool]) -> Vec<(usize, f64)> {
        let system = self.system;
        let mut sensors = Vec::with_capacity(system.sensors.len());
        for s in &system.sensors {
            let x = self.eval(&s.x);
            let path = || format!("sensors.{}.x", s.name);
            match beams.get(s.beam) {
                Some(beam) if length_valid[s.beam] => {
                    let length = beam.length;
                    self.check(
                        path,
                        x,
                        (0.0..=length).contains(&x),
                        || format!("on the beam: in [0, {length}] m"),
                        &[&s.x, &system.beams[s.beam].length],
                    );
                }
                // Its beam's length is out of its domain, reported already.
                Some(_) => {}
                None => {
                    self.check(path, x, false, || "on a beam".to_owned(), &[&s.x]);
                }
            }
            sensors.push((s.beam, x));
        }
        sensors
    }

    /// Where each generated profile's irregularity ends: `x` >= 0 and a taper > 0 no longer
    /// than `x`.
    fn profile_ends(&mut self) -> Vec<Option<[f64; 2]>> {
        let system = self.system;
        system
            .profiles
            .iter()
            .map(|p| match p {
                Profile::Generated {
                    name,
                    until: Some((x, taper)),
                    ..
                } => {
                    let x = self.non_negative(|| format!("profiles.{name}.until.x"), x);
                    let t = self.eval(taper);
                    let t = self.check(
                        || format!("profiles.{name}.until.taper"),
                        t,
                        t > 0.0 && t <= x,
                        || format!("> 0 and at most until.x = {x} m"),
                        &[taper],
                    );
                    Some([x, t])
                }
                _ => None,
            })
            .collect()
    }

    /// The profiles: a harmonic one's amplitude and phase finite, its wavelength > 0.
    fn profiles(&mut self) -> Vec<ModelProfile> {
        let system = self.system;
        let mut profiles = Vec::with_capacity(system.profiles.len());
        for p in &system.profiles {
            profiles.push(match p {
                Profile::Combination { terms, .. } => ModelProfile::Combination(terms.clone()),
                Profile::Generated { interpolation, .. } => ModelProfile::Generated {
                    interpolation: *interpolation,
                },
                Profile::Harmonic {
                    name,
                    amplitude,
                    wavelength,
                    phase,
                } => ModelProfile::Harmonic {
                    amplitude: self.finite(|| format!("profiles.{name}.amplitude"), amplitude),
                    wavelength: self.positive(|| format!("profiles.{name}.wavelength"), wavelength),
                    phase: self.finite(|| format!("profiles.{name}.phase"), phase),
                },
            });
        }
        profiles
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The incidence is the deflection's gradient: `b . q` equals the upper end's
    /// displacement minus the lower end's for any rigid state.
    #[test]
    fn incidence_is_the_deflection_gradient() {
        let upper = PointTerms {
            z: Some(0),
            pitch: Some((1, -2.5)),
            roll: None,
        };
        let lower = PointTerms {
            z: Some(2),
            pitch: None,
            roll: None,
        };
        let el = |to| ModelElement {
            law: ModelLaw::SpringDamper {
                k: 1.0,
                c: 0.0,
                preload: 0.0,
            },
            from: ModelEnd::Body(upper),
            to,
            profile: None,
        };
        let q = [0.3, -0.02, 0.1, 7.0];
        let dot = |b: Vec<f64>| b.iter().zip(q).map(|(b, q)| b * q).sum::<f64>();
        let to_body = el(ModelEnd::Body(lower));
        assert_eq!(to_body.incidence(4), [1.0, -2.5, -1.0, 0.0]);
        assert!(
            (dot(to_body.incidence(4)) - (upper.displacement(&q) - lower.displacement(&q))).abs()
                < 1e-15
        );
        assert_eq!(el(ModelEnd::Ground).incidence(4), [1.0, -2.5, 0.0, 0.0]);
        assert_eq!(el(ModelEnd::Moving(0)).incidence(2), [1.0, -2.5]);
    }

    #[test]
    fn laws_forces_stiffness_and_static_deflection_agree() {
        let sd = ModelLaw::SpringDamper {
            k: 2e5,
            c: 1e3,
            preload: 500.0,
        };
        assert_eq!(sd.force(1e-3, 0.1), 500.0 + 200.0 + 100.0);
        assert_eq!(sd.static_deflection(700.0), Some(1e-3));
        let h = ModelLaw::Hertz {
            g: 5.18e-8,
            exponent: 1.5,
        };
        let d = h.static_deflection(7e4).unwrap();
        assert!((h.force(d, 0.0) - 7e4).abs() < 1e-6);
        assert_eq!(h.force(-1e-6, 0.0), 0.0);
        // Tangent stiffness equals the difference quotient.
        let eps = 1e-10;
        let fd = (h.force(d + eps, 0.0) - h.force(d - eps, 0.0)) / (2.0 * eps);
        assert!((h.stiffness(d) - fd).abs() < 1e-4 * fd);
        let t = ModelLaw::Table {
            deflection: vec![0.0, 1e-3, 2e-3],
            force: vec![0.0, 100.0, 400.0],
            c: 0.0,
        };
        assert_eq!(t.force(1.5e-3, 0.0), 250.0);
        assert_eq!(t.force(3e-3, 0.0), 700.0); // end slope extended
        assert_eq!(t.force(-1e-3, 0.0), -100.0);
        assert_eq!(t.stiffness(1.5e-3), 3e5);
        assert!((t.static_deflection(250.0).unwrap() - 1.5e-3).abs() < 1e-15);
    }
}
