//! The compiled system: every name resolved to an index, every field an expression over the
//! parameter table (the output of [`crate::compile`]). A [`System`] is turned into numbers for
//! one sample by [`System::instantiate`], giving a [`crate::model::Model`].

use crate::expr::Expr;
pub use crate::schema::Interpolation;
use crate::schema::{Axis, DofKind, IndexStat, Outside, RawPsd};

/// How a compiled parameter gets its value.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamSource {
    /// Drawn per sample, uniform on `range`.
    Sampled {
        /// Default of a design (nominal).
        nominal: f64,
        /// `[min, max]`.
        range: [f64; 2],
    },
    /// The same for every sample.
    Fixed(f64),
    /// From other parameters.
    Derived(Expr),
}

/// A parameter of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Name (a column of `params.parquet` when sampled).
    pub name: String,
    /// Unit, as written.
    pub unit: String,
    /// What it is.
    pub doc: Option<String>,
    /// Its source.
    pub source: ParamSource,
}

/// A rigid-body degree of freedom.
#[derive(Debug, Clone, PartialEq)]
pub struct Dof {
    /// Column name (`z_c`, `beta_c`).
    pub name: String,
    /// The body.
    pub body: usize,
    /// Kind.
    pub kind: DofKind,
}

/// A named attachment point of a body (m, from its centre: `x` forward, `y` right, `z` down;
/// `None` for 0).
#[derive(Debug, Clone, PartialEq)]
pub struct BodyPoint {
    /// Name.
    pub name: String,
    /// Longitudinal position.
    pub x: Expr,
    /// Lateral position.
    pub y: Option<Expr>,
    /// Vertical position.
    pub z: Option<Expr>,
}

/// A rigid body.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Name.
    pub name: String,
    /// What it is.
    pub doc: Option<String>,
    /// Mass (kg).
    pub mass: Expr,
    /// Pitch inertia (kg m^2), when it pitches.
    pub inertia: Option<Expr>,
    /// Roll inertia (kg m^2), when it rolls.
    pub roll_inertia: Option<Expr>,
    /// Yaw inertia (kg m^2), when it yaws.
    pub yaw_inertia: Option<Expr>,
    /// Whether the inertias were written as a map (`inertia: {roll, pitch, yaw}`): their
    /// fields are then `inertia.pitch` and so on, else the pitch inertia is `inertia`.
    pub inertia_map: bool,
    /// Index of its vertical DOF.
    pub z: Option<usize>,
    /// Index of its pitch DOF.
    pub pitch: Option<usize>,
    /// Index of its lateral DOF.
    pub y: Option<usize>,
    /// Index of its roll DOF.
    pub roll: Option<usize>,
    /// Index of its yaw DOF.
    pub yaw: Option<usize>,
    /// Index of its longitudinal DOF.
    pub x: Option<usize>,
    /// Named attachment points.
    pub points: Vec<BodyPoint>,
}

impl Body {
    /// The index of its DOF of kind `kind`, if it has one.
    pub fn dof(&self, kind: DofKind) -> Option<usize> {
        match kind {
            DofKind::Z => self.z,
            DofKind::Pitch => self.pitch,
            DofKind::Y => self.y,
            DofKind::Roll => self.roll,
            DofKind::Yaw => self.yaw,
            DofKind::X => self.x,
        }
    }

    /// Its DOF indices in state order.
    pub fn dofs(&self) -> Vec<usize> {
        let mut v: Vec<usize> = DofKind::ALL.iter().filter_map(|&k| self.dof(k)).collect();
        v.sort_unstable();
        v
    }

    /// Whether a force along `axis` at the point `end` (of this body) moves one of its DOFs:
    /// the translation along the axis, or a rotation with a lever arm that is not 0.
    pub fn moves_along(&self, axis: Axis, end: &End) -> bool {
        self.dof(axis.translation()).is_some()
            || axis.rotations().iter().any(|(k, coordinate, _)| {
                self.dof(*k).is_some() && end.coordinate(*coordinate).is_some_and(|c| !c.is_zero())
            })
    }

    /// The moment of inertia (kg m^2) of rotation `kind`, its expression if it has one.
    pub fn inertia_of(&self, kind: DofKind) -> Option<&Expr> {
        match kind {
            DofKind::Pitch => self.inertia.as_ref(),
            DofKind::Roll => self.roll_inertia.as_ref(),
            DofKind::Yaw => self.yaw_inertia.as_ref(),
            _ => None,
        }
    }

    /// The dotted path of the inertia of rotation `kind` (`bodies.c.inertia` for a plain
    /// pitch inertia, `bodies.c.inertia.roll` in the map form).
    pub fn inertia_path(&self, kind: DofKind) -> String {
        if self.inertia_map {
            format!("bodies.{}.inertia.{}", self.name, kind.keyword())
        } else {
            format!("bodies.{}.inertia", self.name)
        }
    }
}

/// One end of an element or the point of a load.
#[derive(Debug, Clone, PartialEq)]
pub enum End {
    /// Fixed ground.
    Ground,
    /// A point of a body: its offset from the body's centre (m; `None` for 0).
    Body {
        /// The body.
        body: usize,
        /// Longitudinal position of the point (m, forward).
        x: Option<Expr>,
        /// Lateral position (m, to the right).
        y: Option<Expr>,
        /// Vertical position (m, downward).
        z: Option<Expr>,
    },
    /// A point of the moving frame.
    Moving(usize),
}

impl End {
    /// The centre of body `body`.
    pub fn centre(body: usize) -> Self {
        End::Body {
            body,
            x: None,
            y: None,
            z: None,
        }
    }

    /// The offset coordinate `axis` (0 `x`, 1 `y`, 2 `z`) of a body point.
    pub fn coordinate(&self, axis: usize) -> Option<&Expr> {
        match self {
            End::Body { x, y, z, .. } => [x, y, z][axis].as_ref(),
            _ => None,
        }
    }
}

/// A link of a support chain: stiffness and damping expressions.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// Stiffness (N/m).
    pub k: Expr,
    /// Damping (N s/m).
    pub c: Expr,
}

/// A level of a support chain.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// Name.
    pub name: String,
    /// Mass per support (kg).
    pub mass: Expr,
    /// Link to the level above.
    pub link: Link,
    /// Shear link to the neighbouring supports of this level.
    pub shear: Option<Link>,
}

/// Periodic supports.
#[derive(Debug, Clone, PartialEq)]
pub struct Supports {
    /// Spacing (m).
    pub spacing: Expr,
    /// Number of supports (a fixed integer).
    pub count: usize,
    /// First support position (m).
    pub first: Expr,
    /// Levels from the beam down.
    pub levels: Vec<Level>,
    /// Last level to ground.
    pub ground: Link,
}

/// A modal beam.
#[derive(Debug, Clone, PartialEq)]
pub struct Beam {
    /// Name.
    pub name: String,
    /// What it is.
    pub doc: Option<String>,
    /// Length (m).
    pub length: Expr,
    /// Number of modes (a fixed integer).
    pub modes: usize,
    /// Mass per length (kg/m).
    pub mass_per_length: Expr,
    /// Bending stiffness (N m^2).
    pub bending_stiffness: Expr,
    /// Modal damping ratio.
    pub damping_ratio: Expr,
    /// Points off the beam.
    pub outside: Outside,
    /// Supports.
    pub supports: Option<Supports>,
}

/// A point of the moving frame.
#[derive(Debug, Clone, PartialEq)]
pub struct MovingPoint {
    /// Name.
    pub name: String,
    /// The beam it runs on (`None`: rigid ground).
    pub beam: Option<usize>,
    /// Offset from the frame origin (m, forward).
    pub offset: Expr,
}

/// A fixed point of a beam where the deflection is measured.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    /// Name.
    pub name: String,
    /// The beam.
    pub beam: usize,
    /// Position (m).
    pub x: Expr,
}

/// Where a generated profile starts (m): it covers `[GENERATED_PROFILE_START, length)`, its
/// `length` a control of the stage that makes it (`mbd_dataset::profile`).
pub const GENERATED_PROFILE_START: f64 = 0.0;

/// A compiled profile.
#[derive(Debug, Clone, PartialEq)]
pub enum Profile {
    /// Random-phase per sample (the `irregularity` stage makes it), covering
    /// `[GENERATED_PROFILE_START, length)`.
    Generated {
        /// Name.
        name: String,
        /// The spectrum, `S(f)` in mm^2/(1/m).
        psd: RawPsd,
        /// Wavelength band (m).
        wavelengths: [f64; 2],
        /// How the points are read between them.
        interpolation: Interpolation,
        /// Where the irregularity ends (m) and the taper before it (m), when it does.
        until: Option<(Expr, Expr)>,
    },
    /// A weighted sum of other profiles (each generated or harmonic).
    Combination {
        /// Name.
        name: String,
        /// The profiles (indices) and their weights.
        terms: Vec<(usize, f64)>,
    },
    /// Analytic harmonic.
    Harmonic {
        /// Name.
        name: String,
        /// Amplitude (m).
        amplitude: Expr,
        /// Wavelength (m).
        wavelength: Expr,
        /// Phase (rad).
        phase: Expr,
    },
}

impl Profile {
    /// The profile's name.
    pub fn name(&self) -> &str {
        match self {
            Profile::Generated { name, .. }
            | Profile::Harmonic { name, .. }
            | Profile::Combination { name, .. } => name,
        }
    }
}

/// A side of a wheelset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The left wheel (at `y = -e0`).
    Left,
    /// The right wheel (at `y = +e0`).
    Right,
}

impl Side {
    /// Both sides, left first (the order of a wheelset's pairs).
    pub const BOTH: [Side; 2] = [Side::Left, Side::Right];

    /// `-1` for the left wheel, `+1` for the right one: the sign of its lateral position.
    pub fn sign(self) -> f64 {
        match self {
            Side::Left => -1.0,
            Side::Right => 1.0,
        }
    }

    /// The suffix of the wheel's element name (`l`, `r`).
    pub fn suffix(self) -> &'static str {
        match self {
            Side::Left => "l",
            Side::Right => "r",
        }
    }
}

/// The contact geometry of a wheelset (the right wheel's; the left mirrors it).
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// Equivalent conicity (rad).
    Conicity(Expr),
    /// Rolling-radius change (m) and contact angle (rad) against the shift (m).
    Table {
        /// Shifts (m).
        shift: Vec<Expr>,
        /// Rolling-radius changes (m).
        radius: Vec<Expr>,
        /// Contact angles (rad).
        angle: Vec<Expr>,
    },
}

/// One wheel of a wheelset (`kind: wheelset`, compiled into one element per wheel): its
/// vertical contact is the element's Hertz law between the wheelset at `y = s e0` and its
/// rail point; its creep, normal and flange forces act in the track plane
/// (`docs/model.md`, "Wheelset on two rails").
#[derive(Debug, Clone, PartialEq)]
pub struct Wheel {
    /// The declared wheelset element (its fields are `elements.<wheelset>.<field>`).
    pub wheelset: String,
    /// Which wheel.
    pub side: Side,
    /// The wheelset body.
    pub body: usize,
    /// The body carrying this wheel's rail laterally (its `y` DOF), when declared.
    pub rail: Option<usize>,
    /// Half the distance between the contact points `e0` (m).
    pub half_gauge: Expr,
    /// Nominal rolling radius `r0` (m).
    pub radius: Expr,
    /// Hertz constant `G` (m/N^(2/3)).
    pub hertz: Expr,
    /// Contact geometry.
    pub geometry: Geometry,
    /// Young's modulus (Pa).
    pub young: Expr,
    /// Poisson's ratio.
    pub poisson: Expr,
    /// Coefficient of friction.
    pub friction: Expr,
    /// Transverse radius of the rail head (m).
    pub rail_radius: Expr,
    /// Transverse radius of the wheel tread (m), `None` for a straight tread.
    pub wheel_profile_radius: Option<Expr>,
    /// Flange clearance (m) and stiffness (N/m).
    pub flange: Option<(Expr, Expr)>,
}

/// A compiled force law.
#[derive(Debug, Clone, PartialEq)]
pub enum Law {
    /// `f = preload + k d + c d'`.
    SpringDamper {
        /// N/m.
        k: Expr,
        /// N s/m.
        c: Expr,
        /// N.
        preload: Expr,
    },
    /// `f = (max(d, 0) / g)^exponent`.
    Hertz {
        /// m/N^(1/exponent).
        g: Expr,
        /// Exponent.
        exponent: Expr,
    },
    /// `f = table(d) + c d'`.
    Table {
        /// Deflections (m).
        deflection: Vec<Expr>,
        /// Forces (N).
        force: Vec<Expr>,
        /// Damping (N s/m).
        c: Expr,
    },
    /// One wheel of a wheelset on its rail: the vertical force is Hertz's `(d / G)^(3/2)`.
    Wheel(Box<Wheel>),
}

impl Law {
    /// Whether this is a contact law (its force column is `p_<name>`).
    pub fn is_contact(&self) -> bool {
        matches!(self, Law::Hertz { .. } | Law::Wheel(_))
    }

    /// The wheel, for a wheel of a wheelset.
    pub fn wheel(&self) -> Option<&Wheel> {
        match self {
            Law::Wheel(w) => Some(w),
            _ => None,
        }
    }

    /// Whether the force reads the deflection's rate: a damping `c` that is not a literal 0
    /// (a spring-damper or table given `c`; Hertz contacts have none).
    pub fn is_damped(&self) -> bool {
        match self {
            Law::SpringDamper { c, .. } | Law::Table { c, .. } => !c.is_zero(),
            Law::Hertz { .. } | Law::Wheel(_) => false,
        }
    }
}

/// A force element.
#[derive(Debug, Clone, PartialEq)]
pub struct Element {
    /// Name.
    pub name: String,
    /// Force law.
    pub law: Law,
    /// Upper end.
    pub from: End,
    /// Lower end.
    pub to: End,
    /// Profile under the lower end.
    pub profile: Option<usize>,
    /// The axis it acts along.
    pub direction: Axis,
}

impl Element {
    /// Whether the element reads the rate of its profile (a damped law on a profile): its
    /// profile's rate is then a stored column beside the profile's.
    pub fn reads_profile_rate(&self) -> bool {
        self.profile.is_some() && self.law.is_damped()
    }
}

/// A constant load.
#[derive(Debug, Clone, PartialEq)]
pub struct Load {
    /// Name.
    pub name: String,
    /// Where it acts.
    pub at: End,
    /// Force (N, positive along `direction`).
    pub force: Expr,
    /// The axis it pushes along.
    pub direction: Axis,
}

/// What produces a generalised force term.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The force of element `i`.
    Element(usize),
    /// The load `i`.
    Load(usize),
}

/// Terms of one DOF's generalised force that share a coefficient magnitude: the DOF receives
/// `coefficient * sum_j sign_j source_j`, one multiplication per group (so `l_c (F_s1 - F_s2)`
/// is computed as written by hand).
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// The common coefficient; `None` for 1.
    pub coefficient: Option<Expr>,
    /// Sources with their signs (+1 or -1).
    pub terms: Vec<(Source, f64)>,
}

/// What a stored channel holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// DOF `i`: displacement (0), velocity (1) or acceleration (2).
    Dof(usize, u8),
    /// Deflection of the beam under moving point `i` (m).
    Point(usize),
    /// Sensor `i`: deflection (0), velocity (1) or acceleration (2).
    Sensor(usize, u8),
    /// The profile under element `i` (m).
    Excitation(usize),
    /// The rate `d eta / dt` of the profile under element `i` (m/s), stored for an element
    /// whose law reads it ([`Element::reads_profile_rate`]).
    ExcitationRate(usize),
    /// The force of element `i` (N).
    Force(usize),
    /// The deflection of element `i` (m).
    Deflection(usize),
    /// The lateral force `Y` (N) of the rail on wheel `i` (a wheel of a wheelset), positive
    /// toward the track's centre: the `Y` of the derailment quotient `Y/Q`.
    WheelLateral(usize),
    /// The flange contact force (N, >= 0) of wheel `i`.
    Flange(usize),
    /// The longitudinal creep force (N, on the wheel, positive forward) of wheel `i`.
    Creep(usize),
    /// The lateral shift (m) of wheel `i` relative to its rail, positive toward its flange.
    Shift(usize),
}

/// Learning role of a channel (the tensors of `docs/learning.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// A displacement the operator predicts (a "solution" of Table 4).
    Solution,
    /// Exact first derivative of a DOF.
    Velocity,
    /// Exact second derivative of a DOF.
    Acceleration,
    /// An excitation (an operator input).
    Excitation,
    /// An element force the operator predicts.
    Force,
    /// Stored for reading only.
    Other,
}

/// A stored column of the simulation output.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// Column name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// What it holds.
    pub quantity: Quantity,
    /// Its learning role.
    pub role: Role,
}

/// A simple index of a channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Index {
    /// Name.
    pub name: String,
    /// What it is.
    pub doc: Option<String>,
    /// Statistic.
    pub stat: IndexStat,
    /// The stored channel (index into [`System::channels`]).
    pub channel: usize,
    /// Subtracted first.
    pub subtract: Expr,
    /// Divisor.
    pub divide: Expr,
    /// Unit.
    pub unit: String,
    /// Pass when at most this.
    pub limit: Option<f64>,
}

/// The railway indices' columns (indices into [`System::channels`]) and constants.
#[derive(Debug, Clone, PartialEq)]
pub struct Railway {
    /// Contact force of each wheel (4).
    pub contact_forces: Vec<usize>,
    /// Car-body vertical acceleration.
    pub car_body_vertical: usize,
    /// Car-body pitch acceleration.
    pub car_body_pitch: usize,
    /// Half the bogie-centre distance (m).
    pub half_length: Expr,
    /// Bogie-frame vertical accelerations (2).
    pub bogies: Vec<usize>,
    /// Rail deflection under each wheel (4).
    pub rails: Vec<usize>,
    /// Static wheel load (N).
    pub static_wheel_load: Expr,
}

/// Limits of the lateral indices (`None`: no limit); a value passes at or below its limit.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LateralLimits {
    /// Of the derailment quotient's 2 m sliding mean.
    pub derailment_quotient: Option<f64>,
    /// Of the wheelset lateral force over the Prud'homme limit.
    pub lateral_force: Option<f64>,
    /// Of the lateral Sperling index at each car-body point.
    pub sperling: Option<f64>,
    /// Of the lateral oscillation's growth rate (1/s).
    pub stability: Option<f64>,
}

/// The lateral indices' binding (indices into [`System::channels`]) and constants.
#[derive(Debug, Clone, PartialEq)]
pub struct Lateral {
    /// Per wheel, front to rear and left before right: its `Y` and `Q` columns.
    pub wheels: Vec<[usize; 2]>,
    /// The car body's lateral, yaw and roll accelerations.
    pub car_body: [usize; 3],
    /// Half the distance between the bogie centres (m).
    pub half_length: Expr,
    /// Height of the measuring points, `z` below the car body's centre (m).
    pub floor: Expr,
    /// The static axle load `P0` (N).
    pub axle_load: Expr,
    /// `alpha` of the Prud'homme limit.
    pub prudhomme: Expr,
    /// The column whose oscillation after the irregularity gives the stability index.
    pub stability: usize,
    /// The stored excitation columns (the irregularity has ended where all are zero).
    pub excitations: Vec<usize>,
    /// Limits.
    pub limits: LateralLimits,
}

/// A validated, compiled description.
#[derive(Debug, Clone, PartialEq)]
pub struct System {
    /// The system's name.
    pub name: String,
    /// What it is.
    pub doc: Option<String>,
    /// The parameter table in declaration order.
    pub parameters: Vec<Parameter>,
    /// Derived parameters in evaluation order.
    pub derived_order: Vec<usize>,
    /// Rigid bodies.
    pub bodies: Vec<Body>,
    /// Their DOFs (bodies in order, each body's DOFs as written).
    pub dofs: Vec<Dof>,
    /// Beams.
    pub beams: Vec<Beam>,
    /// Speed of the moving frame (m/s).
    pub speed: Expr,
    /// Points of the moving frame.
    pub points: Vec<MovingPoint>,
    /// Sensors.
    pub sensors: Vec<Sensor>,
    /// Profiles.
    pub profiles: Vec<Profile>,
    /// Elements.
    pub elements: Vec<Element>,
    /// Loads.
    pub loads: Vec<Load>,
    /// Per DOF, its generalised force as coefficient groups.
    pub assembly: Vec<Vec<Group>>,
    /// The stored channels in column order.
    pub channels: Vec<Channel>,
    /// Indices.
    pub indices: Vec<Index>,
    /// The railway indices' binding, when declared.
    pub railway: Option<Railway>,
    /// The lateral indices' binding, when declared.
    pub lateral: Option<Lateral>,
    /// Time (s) from which the indices read a record (`indices_from`, default 0): what comes
    /// before is the simulation's start-up, which the indices leave out.
    pub indices_from: f64,
    /// The sampled parameters' names in declaration order, shared by every design of this
    /// system ([`crate::sampled::Sampled`]); fixed when the description is compiled.
    pub(crate) sampled_list: std::sync::Arc<[String]>,
}

impl System {
    /// Index of parameter `name`.
    pub fn parameter(&self, name: &str) -> Option<usize> {
        self.parameters.iter().position(|p| p.name == name)
    }

    /// Indices of the sampled parameters, in declaration order (the columns of
    /// `params.parquet` and the order of each sample's draws).
    pub fn sampled(&self) -> Vec<usize> {
        self.parameters
            .iter()
            .enumerate()
            .filter(|(_, p)| matches!(p.source, ParamSource::Sampled { .. }))
            .map(|(i, _)| i)
            .collect()
    }

    /// Names of the sampled parameters that parameters `roots` are computed from: a sampled
    /// root itself, and through derived parameters every sampled one their expressions read
    /// (in declaration order, each once). A fixed parameter contributes none.
    pub fn sampled_sources(&self, roots: impl IntoIterator<Item = usize>) -> Vec<String> {
        let mut reached = vec![false; self.parameters.len()];
        let mut todo: Vec<usize> = roots.into_iter().collect();
        while let Some(i) = todo.pop() {
            if std::mem::replace(&mut reached[i], true) {
                continue;
            }
            if let ParamSource::Derived(e) = &self.parameters[i].source {
                todo.extend(e.parameters());
            }
        }
        self.parameters
            .iter()
            .zip(reached)
            .filter(|(p, r)| *r && matches!(p.source, ParamSource::Sampled { .. }))
            .map(|(p, _)| p.name.clone())
            .collect()
    }

    /// Names of the sampled parameters, in declaration order.
    pub fn sampled_names(&self) -> Vec<&str> {
        self.sampled_list.iter().map(String::as_str).collect()
    }

    /// The stored channel called `name`.
    pub fn channel(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c.name == name)
    }

    /// The name of the stored column holding `quantity`, if one does (a rigid moving point has
    /// no deflection column, an element without a profile no excitation column).
    pub fn column_of(&self, quantity: Quantity) -> Option<&str> {
        self.channels
            .iter()
            .find(|c| c.quantity == quantity)
            .map(|c| c.name.as_str())
    }

    /// The DOFs that have an equation when a learner predicts the columns `outputs` and is
    /// given `inputs`: every element acting on the DOF has both ends among the rigid DOFs (all
    /// predicted), the ground, points on the ground, or moving points whose deflection column
    /// `z_<point>` is predicted, and its profile column `eta_<element>`, if any, is an input.
    pub fn equation_dofs(&self, outputs: &[&str], inputs: &[&str]) -> Vec<usize> {
        let point_known = |p: usize| {
            self.points[p].beam.is_none()
                || self
                    .column_of(Quantity::Point(p))
                    .is_some_and(|c| outputs.contains(&c))
        };
        let closes = |i: usize, e: &Element| {
            let end_known = |end: &End| match end {
                End::Ground | End::Body { .. } => true,
                End::Moving(p) => point_known(*p),
            };
            end_known(&e.from)
                && end_known(&e.to)
                && (e.profile.is_none()
                    || self
                        .column_of(Quantity::Excitation(i))
                        .is_some_and(|c| inputs.contains(&c)))
        };
        // A wheel's tangential forces are not a coefficient group: the DOFs of its wheelset
        // and of the body carrying its rail have no equation a learner can check.
        let wheeled: Vec<usize> = self
            .elements
            .iter()
            .filter_map(|e| e.law.wheel())
            .flat_map(|w| {
                let rail = w.rail.and_then(|r| self.bodies[r].y);
                self.bodies[w.body].dofs().into_iter().chain(rail)
            })
            .collect();
        (0..self.dofs.len())
            .filter(|i| !wheeled.contains(i))
            .filter(|&i| {
                self.assembly[i]
                    .iter()
                    .flat_map(|g| &g.terms)
                    .all(|(s, _)| match s {
                        Source::Element(e) => closes(*e, &self.elements[*e]),
                        Source::Load(_) => true,
                    })
            })
            .collect()
    }

    /// The channels of a role, in column order.
    pub fn channels_of(&self, role: Role) -> Vec<usize> {
        (0..self.channels.len())
            .filter(|&i| self.channels[i].role == role)
            .collect()
    }
}
