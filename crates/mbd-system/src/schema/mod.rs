//! The description as written: every section read from the YAML tree into typed records that
//! keep their positions (the *parse* step). Names are not resolved here (that is
//! [`crate::compile`]); only the shape of each entry is checked.
//!
//! Sections (`docs/systems.md` documents each field with its unit):
//! `format` (1), `name`, `doc`, `parameters`, `bodies`, `beams`, `moving`, `sensors`,
//! `profiles`, `elements`, `loads`, `outputs`, `indices`, `railway`, `lateral`, `indices_from`.
//!
//! This module holds the records; `sections` the readers, one per section, and [`read`] the
//! whole description.

pub mod fra;
mod sections;

pub use sections::read;

use crate::reader::Field;
use crate::yaml::Pos;

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

/// Kinds of rigid-body degrees of freedom: small motions of a body in space, in the frame `x`
/// forward, `y` to the right, `z` down (right-handed), rotations about those axes by the
/// right-hand rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum DofKind {
    /// Vertical displacement (m, positive downward); column `z_<body>`.
    Z,
    /// Pitch rotation about `y` (rad, positive nose-up: the front rises); column `beta_<body>`.
    Pitch,
    /// Lateral displacement (m, positive to the right); column `y_<body>`.
    Y,
    /// Roll rotation about `x` (rad, positive when the right side goes down); column
    /// `phi_<body>`.
    Roll,
    /// Yaw rotation about `z` (rad, positive when the nose turns right); column `psi_<body>`.
    Yaw,
    /// Longitudinal displacement (m, positive forward); column `x_<body>`.
    X,
}

impl DofKind {
    /// Every kind, in the order a message lists them.
    pub const ALL: [DofKind; 6] = [
        DofKind::Z,
        DofKind::Pitch,
        DofKind::Y,
        DofKind::Roll,
        DofKind::Yaw,
        DofKind::X,
    ];

    /// The keyword in `dofs:`.
    pub fn keyword(self) -> &'static str {
        match self {
            DofKind::Z => "z",
            DofKind::Pitch => "pitch",
            DofKind::Y => "y",
            DofKind::Roll => "roll",
            DofKind::Yaw => "yaw",
            DofKind::X => "x",
        }
    }

    /// The kind of a `dofs:` keyword.
    pub fn from_keyword(keyword: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.keyword() == keyword)
    }

    /// The column prefix (`z`, `beta`, `y`, `phi`, `psi`, `x`).
    pub fn symbol(self) -> &'static str {
        match self {
            DofKind::Z => "z",
            DofKind::Pitch => "beta",
            DofKind::Y => "y",
            DofKind::Roll => "phi",
            DofKind::Yaw => "psi",
            DofKind::X => "x",
        }
    }

    /// Whether the DOF is a rotation (rad) rather than a displacement (m).
    pub fn is_rotation(self) -> bool {
        matches!(self, DofKind::Pitch | DofKind::Roll | DofKind::Yaw)
    }

    /// Unit of the displacement.
    pub fn unit(self) -> &'static str {
        if self.is_rotation() {
            "rad"
        } else {
            "m"
        }
    }

    /// Unit of the generalised force of the DOF (its equation of motion's residual).
    pub fn force_unit(self) -> &'static str {
        if self.is_rotation() {
            "N m"
        } else {
            "N"
        }
    }
}

/// An axis of the body frame: the direction an element acts in or a load pushes along.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Axis {
    /// Longitudinal, positive forward.
    X,
    /// Lateral, positive to the right.
    Y,
    /// Vertical, positive downward (the default: every planar element).
    #[default]
    Z,
}

impl Axis {
    /// Every axis with its keyword.
    pub const ALL: [(Axis, &'static str); 3] = [(Axis::X, "x"), (Axis::Y, "y"), (Axis::Z, "z")];

    /// The keyword of `direction:`.
    pub fn keyword(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(a, _)| *a == self)
            .map_or("", |(_, k)| k)
    }

    /// The axis of a keyword.
    pub fn from_keyword(keyword: &str) -> Option<Self> {
        Self::ALL
            .iter()
            .find(|(_, k)| *k == keyword)
            .map(|(a, _)| *a)
    }

    /// The translation DOF along this axis.
    pub fn translation(self) -> DofKind {
        match self {
            Axis::X => DofKind::X,
            Axis::Y => DofKind::Y,
            Axis::Z => DofKind::Z,
        }
    }

    /// The two rotations that move a point along this axis, with the point's coordinate each
    /// multiplies and its sign: a small rotation `theta` moves the point `r = (x, y, z)` by
    /// `theta x r`, so along `z` by `roll y - pitch x`, along `y` by `yaw x - roll z`, along `x`
    /// by `pitch z - yaw y`. Coordinates are indexed 0 (`x`), 1 (`y`), 2 (`z`).
    pub fn rotations(self) -> [(DofKind, usize, f64); 2] {
        match self {
            Axis::Z => [(DofKind::Pitch, 0, -1.0), (DofKind::Roll, 1, 1.0)],
            Axis::Y => [(DofKind::Yaw, 0, 1.0), (DofKind::Roll, 2, -1.0)],
            Axis::X => [(DofKind::Pitch, 2, 1.0), (DofKind::Yaw, 1, -1.0)],
        }
    }
}

/// A named attachment point of a body: `x` forward, `y` to the right, `z` down of the body's
/// centre (m); a plain number is `x` alone.
#[derive(Debug, Clone, PartialEq)]
pub struct RawPoint {
    /// Its name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// Longitudinal position (m).
    pub x: Field,
    /// Lateral position (m), absent: 0.
    pub y: Option<Field>,
    /// Vertical position (m, downward), absent: 0.
    pub z: Option<Field>,
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
    /// Moments of inertia about the centre (kg m^2), one per rotation DOF: `inertia: j` is the
    /// pitch inertia, `inertia: {roll, pitch, yaw}` each axis's (principal axes; products of
    /// inertia are not modelled).
    pub inertia: Vec<(DofKind, Field)>,
    /// Whether `inertia` was written as a plain value (the pitch inertia) rather than a map.
    pub inertia_scalar: bool,
    /// Where `inertia` was written.
    pub inertia_pos: Option<Pos>,
    /// Its DOFs in the order written.
    pub dofs: Vec<(DofKind, Pos)>,
    /// Attachment points.
    pub points: Vec<RawPoint>,
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

/// How a generated profile is read between its points (`interpolation:` of a profile).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// Straight segments: continuous level, a slope that jumps at every point (the default).
    #[default]
    Linear,
    /// A not-a-knot cubic spline: continuous level, slope and curvature.
    Cubic,
}

impl Interpolation {
    /// Every interpolation with its keyword, in the order a message lists them.
    pub const ALL: [(Interpolation, &'static str); 2] = [
        (Interpolation::Linear, "linear"),
        (Interpolation::Cubic, "cubic"),
    ];

    /// The keyword of `interpolation:`.
    pub fn keyword(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(i, _)| *i == self)
            .map_or("", |(_, k)| k)
    }

    /// The interpolation of a keyword.
    pub fn from_keyword(keyword: &str) -> Option<Self> {
        Self::ALL
            .iter()
            .find(|(_, k)| *k == keyword)
            .map(|(i, _)| *i)
    }

    /// The fewest points the interpolation takes: 2 for a segment, 4 for a not-a-knot spline
    /// (its two end conditions each need two cells).
    pub fn min_points(self) -> usize {
        match self {
            Interpolation::Linear => 2,
            Interpolation::Cubic => 4,
        }
    }
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

/// The one-sided displacement spectrum of a generated profile in the generator's unit: `S(f)`
/// in mm^2/(1/m) of the spatial frequency `f` (1/m).
#[derive(Debug, Clone, PartialEq)]
pub enum RawPsd {
    /// Piecewise power law (a standard's segments, an ISO 8608 class), `a` in mm^2 m.
    PowerLaw(Vec<RawPsdSegment>),
    /// `S(f) = c / ((f^2 + p^2)(f^2 + q^2))` (an FRA track class, [`fra`]): `c` in
    /// mm^2 (1/m)^3, `p >= 0` and `q > 0` in 1/m.
    TwoPole {
        /// Numerator (mm^2 (1/m)^3).
        c: f64,
        /// First pole (1/m), 0 for a spectrum rising as `f^-2` at long wavelengths.
        p: f64,
        /// Second pole (1/m).
        q: f64,
    },
}

/// How a profile is made.
#[derive(Debug, Clone, PartialEq)]
pub enum RawProfileKind {
    /// One random-phase realisation per sample, from a spectrum.
    Generated {
        /// The spectrum, in the generator's unit (`a` of segments scaled from `unit`).
        psd: RawPsd,
        /// Wavelength band `[min, max]` (m).
        wavelengths: [f64; 2],
        /// `interpolation:` (default linear) and where it is given (the profile's entry when
        /// not).
        interpolation: (Interpolation, Pos),
        /// `until: {x, taper}`: the irregularity ends at `x` (m), faded out over the `taper`
        /// (m) before it; zero beyond.
        until: Option<(Field, Field)>,
    },
    /// A weighted sum of other (generated or harmonic) profiles, `sum_k w_k eta_k(x)`: a rail's
    /// vertical profile from the track's vertical profile and its cross-level.
    Combination {
        /// The profiles and their weights (literal numbers).
        terms: Vec<(Named, f64)>,
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
    /// A wheelset on two rails.
    Wheelset(Box<RawWheelset>),
}

impl RawLaw {
    /// The keyword of `kind:`.
    pub fn keyword(&self) -> &'static str {
        match self {
            RawLaw::SpringDamper { .. } => "spring_damper",
            RawLaw::Hertz { .. } => "hertz",
            RawLaw::Table { .. } => "table",
            RawLaw::Wheelset(_) => "wheelset",
        }
    }
}

/// The contact geometry of a wheelset's right wheel against its rail, as a function of the
/// wheelset's lateral shift relative to the rail (the left wheel mirrors it).
#[derive(Debug, Clone, PartialEq)]
pub enum RawGeometry {
    /// Conical treads of equivalent conicity `gamma` (rad): rolling radius `r0 + gamma u`,
    /// contact angle `atan gamma`.
    Conicity(Field),
    /// Tabulated against the shift `u` (m, toward the wheel's flange): rolling-radius change
    /// (m) and contact angle (rad), linear between the points, held beyond them.
    Table {
        /// Where the table was written.
        pos: Pos,
        /// Shifts (m), increasing.
        shift: Vec<Field>,
        /// Rolling-radius change at each shift (m).
        radius: Vec<Field>,
        /// Contact angle at each shift (rad).
        angle: Vec<Field>,
    },
}

/// Creep of a wheelset's contacts: materials, friction and the curvatures that fix the Hertz
/// contact ellipse.
#[derive(Debug, Clone, PartialEq)]
pub struct RawCreep {
    /// Where.
    pub pos: Pos,
    /// Young's modulus of wheel and rail (Pa).
    pub young: Option<Field>,
    /// Poisson's ratio of wheel and rail.
    pub poisson: Option<Field>,
    /// Coefficient of friction.
    pub friction: Option<Field>,
    /// Transverse radius of the rail head (m).
    pub rail_radius: Option<Field>,
    /// Transverse radius of the wheel tread (m; absent: a straight, conical tread).
    pub wheel_profile_radius: Option<Field>,
}

/// Flange contact as a stiff lateral spring beyond a clearance.
#[derive(Debug, Clone, PartialEq)]
pub struct RawFlange {
    /// Where.
    pub pos: Pos,
    /// Lateral clearance between the tread contact and flange contact (m, >= 0).
    pub clearance: Option<Field>,
    /// Lateral stiffness of the flange contact (N/m).
    pub stiffness: Option<Field>,
}

/// A wheelset on two rails (`kind: wheelset`): both wheels' contacts, compiled into one
/// element per wheel (`<name>_l`, `<name>_r`).
#[derive(Debug, Clone, PartialEq)]
pub struct RawWheelset {
    /// The rail points under the left and the right wheel.
    pub rails: Vec<Named>,
    /// The vertical profiles under the left and the right wheel (optional).
    pub profiles: Vec<Named>,
    /// The bodies that carry each rail laterally (a `y` DOF; optional: rigid).
    pub lateral_rails: Vec<Named>,
    /// Where `rails` was written.
    pub rails_pos: Pos,
    /// Half the lateral distance between the contact points `e0` (m).
    pub half_gauge: Option<Field>,
    /// Nominal rolling radius `r0` (m).
    pub radius: Option<Field>,
    /// Hertz constant `G` (m/N^(2/3)) of each wheel's normal contact.
    pub hertz: Option<Field>,
    /// Contact geometry.
    pub geometry: Option<RawGeometry>,
    /// Creep.
    pub creep: Option<RawCreep>,
    /// Flange contact.
    pub flange: Option<RawFlange>,
}

/// One entry of `elements`: a force element between two points acting along its `direction`,
/// its deflection positive when `from` moves along the direction relative to `to` (for the
/// default, vertical, direction: compression positive when `from` moves down).
#[derive(Debug, Clone, PartialEq)]
pub struct RawElement {
    /// Name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// Its law.
    pub law: RawLaw,
    /// The axis it acts along (default `z`) and where `direction:` was written.
    pub direction: (Axis, Option<Pos>),
    /// Upper end (a body point).
    pub from: Option<Named>,
    /// Lower end (a body point, a moving point or `ground`).
    pub to: Option<Named>,
    /// A profile under the lower end (a moving point).
    pub profile: Option<Named>,
}

/// One entry of `loads`: a constant force (N) at a point, along an axis (downward by default).
#[derive(Debug, Clone, PartialEq)]
pub struct RawLoad {
    /// Name.
    pub name: String,
    /// Where.
    pub pos: Pos,
    /// The point (a body point or a moving point).
    pub at: Option<Named>,
    /// Force (N, positive along `direction`: downward for the default `z`).
    pub force: Option<Field>,
    /// The axis it pushes along (default `z`) and where `direction:` was written.
    pub direction: (Axis, Option<Pos>),
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

/// Limits of the lateral indices (`lateral.limits`), each a literal and where it was written.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawLateralLimits {
    /// Upper limit of the derailment quotient's 2 m sliding mean.
    pub derailment_quotient: Option<(f64, Pos)>,
    /// Upper limit of the wheelset lateral force over the Prud'homme limit.
    pub lateral_force: Option<(f64, Pos)>,
    /// Upper limit of the lateral Sperling index.
    pub sperling: Option<(f64, Pos)>,
    /// Upper limit of the lateral oscillation's growth rate after the irregularity (1/s).
    pub stability: Option<(f64, Pos)>,
}

/// The `lateral` section: the lateral indices of a railway vehicle in space (`docs/indices.md`,
/// "Lateral indices") bound to its wheelsets and columns.
#[derive(Debug, Clone, PartialEq)]
pub struct RawLateral {
    /// Where.
    pub pos: Pos,
    /// The wheelsets (`kind: wheelset` elements), front to rear.
    pub wheelsets: Vec<Named>,
    /// The car body's lateral, yaw and roll accelerations (stored columns).
    pub car_body: Option<[Named; 3]>,
    /// Half the distance between the bogie centres (m).
    pub half_length: Option<Field>,
    /// Height of the measuring points: `z` below the car body's centre (m).
    pub floor: Option<Field>,
    /// The static axle load `P0` (N) of the Prud'homme limit.
    pub axle_load: Option<Field>,
    /// The factor `alpha` of the Prud'homme limit `alpha (10 + P0 / 3)` kN (1 for passenger
    /// vehicles), default 1.
    pub prudhomme: Option<Field>,
    /// The column whose oscillation after the irregularity gives the stability index.
    pub stability: Option<Named>,
    /// Limits.
    pub limits: RawLateralLimits,
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
    /// `lateral`.
    pub lateral: Option<RawLateral>,
    /// `indices_from` (s) and where it was written.
    pub indices_from: Option<(f64, Pos)>,
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
