//! A wheelset on two rails: the tangential side of each wheel's contact (`kind: wheelset` of a
//! description; `docs/model.md`, "Wheelset on two rails", states the equations and their
//! validity).
//!
//! Frame and signs: `x` forward, `y` to the right, `z` down; the wheel of side `s` (`-1` left,
//! `+1` right) touches its rail at `(0, s e0, r0)` from the wheelset's centre. Its vertical
//! force `Q` is the element's Hertz law (crate `mbd-system`), on the compression
//! `d = z + s e0 phi + rho - w_rail - eta`; this module adds, in the track plane:
//!
//! ```text
//! u      = s (y - y_rail)                          shift toward the wheel's flange (m)
//! rho    = rho(u), delta = delta(u)                rolling-radius change, contact angle
//! xi_x   = -rho / r0 - s e0 psi' / V               longitudinal creepage
//! xi_y   = (y' - y_rail' - r0 phi') / V - psi      lateral creepage
//! spin   = psi' / V - s sin(delta) / r0            spin about z (1/m)
//! F_x    = -f11 xi_x                               Kalker's linear theory, forces on the wheel
//! F_y    = -f22 xi_y - f23 spin
//! M_z    =  f23 xi_y                               (f33 not tabulated: the spin moment's
//!                                                   own term is left out)
//! eps    = SHE(|(F_x, F_y)| / (mu Q))              Shen-Hedrick-Elkins saturation, scales
//!                                                   F_x, F_y, M_z
//! N_y    = -s Q tan(delta - s phi)                 lateral part of the normal force (with
//!                                                   tan phi = phi: small rotations)
//! F_fl   = k_fl max(u - c, 0)                      flange contact
//! F_Y    = eps F_y + N_y - s F_fl                  lateral force on the wheel (track frame)
//! ```
//!
//! Generalised forces on the wheelset: `F_Y` on `y`, `-r0 F_Y` on roll, `-s e0 eps F_x + eps
//! M_z` on yaw (`eps F_x` on `x` when the wheelset has it); `-F_Y` on the lateral rail body.
//! The derailment quotient's `Y` is `-s F_Y` (positive when the rail pushes the wheel toward
//! the track's centre: the flanging wheel).
//!
//! Creep coefficients (Kalker 1967, tabulated in Kalker, *Three-dimensional elastic bodies in
//! rolling contact*, Kluwer 1990, appendix E): `f11 = G a b C11`, `f22 = G a b C22`,
//! `f23 = G (a b)^(3/2) C23` with `G = E / (2 (1 + nu))` and the Hertz ellipse's semi-axes `a`
//! (rolling direction) and `b` ([`hertz_ellipse`]); `a, b` grow as `Q^(1/3)` at a fixed ratio,
//! so `f11, f22 ~ Q^(2/3)` and `f23 ~ Q`.

use crate::{Error, Result};
use mbd_system::model::{ModelGeometry, ModelWheel};
use std::f64::consts::PI;

/// Semi-axis ratios `a/b` of Kalker's table (`a` along the rolling direction).
const KALKER_RATIOS: [f64; 19] = [
    0.1,
    0.2,
    0.3,
    0.4,
    0.5,
    0.6,
    0.7,
    0.8,
    0.9,
    1.0,
    1.0 / 0.9,
    1.0 / 0.8,
    1.0 / 0.7,
    1.0 / 0.6,
    1.0 / 0.5,
    1.0 / 0.4,
    1.0 / 0.3,
    1.0 / 0.2,
    1.0 / 0.1,
];

/// Poisson's ratios of Kalker's table.
const KALKER_POISSON: [f64; 3] = [0.0, 0.25, 0.5];

/// Kalker's `C11`, a row per Poisson's ratio of [`KALKER_POISSON`], a column per ratio of
/// [`KALKER_RATIOS`] (Kalker 1990, table E3; at `nu = 0`, `C11 = C22`).
const C11: [[f64; 19]; 3] = [
    [
        2.51, 2.59, 2.68, 2.78, 2.88, 2.98, 3.09, 3.19, 3.29, 3.40, 3.51, 3.65, 3.82, 4.06, 4.37,
        4.84, 5.57, 6.96, 10.7,
    ],
    [
        3.31, 3.37, 3.44, 3.53, 3.62, 3.72, 3.81, 3.91, 4.01, 4.12, 4.22, 4.36, 4.54, 4.78, 5.10,
        5.57, 6.34, 7.78, 11.7,
    ],
    [
        4.85, 4.81, 4.80, 4.82, 4.83, 4.91, 4.97, 5.05, 5.12, 5.20, 5.30, 5.42, 5.58, 5.80, 6.11,
        6.57, 7.34, 8.82, 12.9,
    ],
];

/// Kalker's `C22` (as [`C11`]).
#[allow(clippy::approx_constant)] // 3.14 is Kalker's tabulated value, not pi.
const C22: [[f64; 19]; 3] = [
    [
        2.51, 2.59, 2.68, 2.78, 2.88, 2.98, 3.09, 3.19, 3.29, 3.40, 3.51, 3.65, 3.82, 4.06, 4.37,
        4.84, 5.57, 6.96, 10.7,
    ],
    [
        2.52, 2.63, 2.75, 2.88, 3.01, 3.14, 3.28, 3.41, 3.54, 3.67, 3.81, 3.99, 4.21, 4.50, 4.90,
        5.48, 6.40, 8.14, 12.8,
    ],
    [
        2.53, 2.66, 2.81, 2.98, 3.14, 3.31, 3.48, 3.65, 3.82, 3.98, 4.16, 4.39, 4.67, 5.04, 5.56,
        6.31, 7.51, 9.79, 16.0,
    ],
];

/// Kalker's `C23` (as [`C11`]).
const C23: [[f64; 19]; 3] = [
    [
        0.334, 0.483, 0.607, 0.720, 0.827, 0.930, 1.03, 1.13, 1.23, 1.33, 1.44, 1.58, 1.76, 2.01,
        2.35, 2.88, 3.79, 5.72, 12.2,
    ],
    [
        0.473, 0.603, 0.715, 0.823, 0.929, 1.03, 1.14, 1.25, 1.36, 1.47, 1.59, 1.75, 1.95, 2.23,
        2.62, 3.24, 4.32, 6.63, 14.6,
    ],
    [
        0.731, 0.809, 0.889, 0.977, 1.07, 1.18, 1.29, 1.40, 1.51, 1.63, 1.77, 1.94, 2.18, 2.50,
        2.96, 3.70, 5.01, 7.89, 18.0,
    ],
];

/// Kalker's coefficients `[C11, C22, C23]` at the semi-axis ratio `a/b` (`a` along the
/// rolling direction) and Poisson's ratio `nu`: linear in `a/b` between the table's columns,
/// quadratic through its three Poisson's ratios; `None` outside `a/b` in [0.1, 10] or `nu` in
/// [0, 0.5].
pub fn kalker(a_over_b: f64, nu: f64) -> Option<[f64; 3]> {
    let (lo, hi) = (KALKER_RATIOS[0], KALKER_RATIOS[18]);
    if !((lo..=hi).contains(&a_over_b) && (0.0..=0.5).contains(&nu)) {
        return None;
    }
    let j = KALKER_RATIOS
        .partition_point(|&r| r <= a_over_b)
        .clamp(1, 18)
        - 1;
    let t = (a_over_b - KALKER_RATIOS[j]) / (KALKER_RATIOS[j + 1] - KALKER_RATIOS[j]);
    // Lagrange weights of the three Poisson's ratios.
    let weight = |i: usize| -> f64 {
        (0..3)
            .filter(|&k| k != i)
            .map(|k| (nu - KALKER_POISSON[k]) / (KALKER_POISSON[i] - KALKER_POISSON[k]))
            .product()
    };
    let w = [weight(0), weight(1), weight(2)];
    let at = |table: &[[f64; 19]; 3]| -> f64 {
        (0..3)
            .map(|i| w[i] * (table[i][j] + t * (table[i][j + 1] - table[i][j])))
            .sum()
    };
    Some([at(&C11), at(&C22), at(&C23)])
}

/// The complete elliptic integrals `K(m)` and `E(m)` of parameter `m = e^2` in [0, 1), by the
/// arithmetic-geometric mean.
pub fn elliptic_ke(m: f64) -> (f64, f64) {
    let (mut a, mut b) = (1.0, (1.0 - m).sqrt());
    let mut c = m.sqrt();
    let mut sum = 0.5 * c * c;
    let mut power = 0.5;
    for _ in 0..40 {
        if c.abs() < 1e-17 {
            break;
        }
        let an = 0.5 * (a + b);
        let bn = (a * b).sqrt();
        c = 0.5 * (a - b);
        power *= 2.0;
        sum += power * c * c;
        a = an;
        b = bn;
    }
    let k = PI / (2.0 * a);
    (k, k * (1.0 - sum))
}

/// The semi-axes `(a, b)` (m) of the Hertz contact ellipse of two bodies of reduced modulus
/// `e_star` (Pa; `1 / E* = sum (1 - nu^2) / E`) pressed by `load` (N), with relative curvature
/// sums `curvature_x` (along the rolling direction) and `curvature_y` (1/m, both > 0):
/// `a` lies along `x`. With `A <= B` the curvatures, the ellipse's eccentricity `e` solves
/// `B / A = ((1 - e^2)^-1 E(e) - K(e)) / (K(e) - E(e))` and its major semi-axis is
/// `(3 P (K - E) / (2 pi e^2 A E*))^(1/3)` (Johnson, *Contact mechanics*, 1985, section 4.2);
/// equal curvatures give the circle `(3 P / (8 A E*))^(1/3)`.
pub fn hertz_ellipse(curvature_x: f64, curvature_y: f64, e_star: f64, load: f64) -> (f64, f64) {
    let (small, large) = if curvature_x <= curvature_y {
        (curvature_x, curvature_y)
    } else {
        (curvature_y, curvature_x)
    };
    let ratio = large / small;
    let (major, minor) = if ratio - 1.0 < 1e-9 {
        let r = (3.0 * load / (8.0 * small * e_star)).cbrt();
        (r, r)
    } else {
        let g = |m: f64| {
            let (k, e) = elliptic_ke(m);
            (e / (1.0 - m) - k) / (k - e)
        };
        // g increases from 1 at m = 0 to infinity at m = 1.
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if g(mid) < ratio {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let m = 0.5 * (lo + hi);
        let (k, e) = elliptic_ke(m);
        let major = (3.0 * load * (k - e) / (2.0 * PI * m * small * e_star)).cbrt();
        (major, major * (1.0 - m).sqrt())
    };
    // The major axis lies along the direction of the smaller curvature.
    if curvature_x <= curvature_y {
        (major, minor)
    } else {
        (minor, major)
    }
}

/// Shen, Hedrick and Elkins' saturation (1983): the factor by which the linear creep forces of
/// resultant `x mu Q` are scaled, `1 - x/3 + x^2/27` up to `x = 3`, `1/x` beyond (continuous
/// with its slope at `x = 3`, where the force reaches `mu Q`).
#[inline]
pub fn saturation(x: f64) -> f64 {
    if x <= 3.0 {
        1.0 - x / 3.0 + x * x / 27.0
    } else {
        1.0 / x
    }
}

/// Creep coefficients of a wheel per unit load: `f11 = k11 Q^(2/3)`, `f22 = k22 Q^(2/3)`,
/// `f23 = k23 Q` (N, N, N m at `Q` in N), and the friction coefficient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Creep {
    /// `f11 / Q^(2/3)`.
    pub k11: f64,
    /// `f22 / Q^(2/3)`.
    pub k22: f64,
    /// `f23 / Q` (m).
    pub k23: f64,
    /// `mu`.
    pub friction: f64,
    /// The ellipse's semi-axis ratio `a/b`.
    pub a_over_b: f64,
}

impl Creep {
    /// `(f11, f22, f23)` at the normal load `q` (N).
    #[inline]
    pub fn at(&self, q: f64) -> (f64, f64, f64) {
        let q13 = q.cbrt();
        let q23 = q13 * q13;
        (self.k11 * q23, self.k22 * q23, self.k23 * q)
    }

    /// The creep coefficients of a wheel (its ellipse from the wheel's rolling radius and
    /// tread radius against the rail head's transverse radius); an error names the wheelset
    /// when the ellipse falls outside Kalker's table.
    pub fn of(w: &ModelWheel, name: &str) -> Result<Self> {
        let e_star = w.young / (2.0 * (1.0 - w.poisson * w.poisson));
        let shear = w.young / (2.0 * (1.0 + w.poisson));
        let curvature_x = 0.5 / w.radius;
        let curvature_y = 0.5 / w.rail_radius + w.wheel_profile_radius.map_or(0.0, |r| 0.5 / r);
        if curvature_y.is_nan() || curvature_y <= 0.0 {
            return Err(Error::OutOfRange {
                name: format!("elements.{name}.creep.wheel_profile_radius"),
                value: w.wheel_profile_radius.unwrap_or(f64::NAN),
                allowed: format!(
                    "a tread no more hollow than the rail head is round (radius beyond -{} m)",
                    w.rail_radius
                ),
            });
        }
        let (a, b) = hertz_ellipse(curvature_x, curvature_y, e_star, 1.0);
        let a_over_b = a / b;
        let [c11, c22, c23] = kalker(a_over_b, w.poisson).ok_or_else(|| Error::OutOfRange {
            name: format!("elements.{name}.creep"),
            value: a_over_b,
            allowed: "a contact ellipse of semi-axis ratio a/b in [0.1, 10] (Kalker's table)"
                .into(),
        })?;
        Ok(Creep {
            k11: shear * a * b * c11,
            k22: shear * a * b * c22,
            k23: shear * (a * b).powf(1.5) * c23,
            friction: w.friction,
            a_over_b,
        })
    }
}

/// A wheel's contact geometry at run time (the right wheel's; the left mirrors it).
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// Conical treads: `rho = gamma u`, `tan delta = gamma`, `sin delta` precomputed.
    Cone {
        /// `gamma`.
        gamma: f64,
        /// `sin(atan gamma)`.
        sin: f64,
    },
    /// Tabulated, linear between points, held beyond them.
    Table {
        /// Shifts (m).
        shift: Vec<f64>,
        /// Rolling-radius changes (m).
        radius: Vec<f64>,
        /// Contact angles (rad).
        angle: Vec<f64>,
    },
}

impl Geometry {
    fn of(g: &ModelGeometry) -> Self {
        match g {
            ModelGeometry::Conicity(gamma) => Geometry::Cone {
                gamma: *gamma,
                sin: gamma.atan().sin(),
            },
            ModelGeometry::Table {
                shift,
                radius,
                angle,
            } => Geometry::Table {
                shift: shift.clone(),
                radius: radius.clone(),
                angle: angle.clone(),
            },
        }
    }

    /// `(rho, tan delta, sin delta)` at the shift `u` (m) toward the wheel's flange.
    #[inline]
    pub fn at(&self, u: f64) -> (f64, f64, f64) {
        match self {
            Geometry::Cone { gamma, sin } => (gamma * u, *gamma, *sin),
            Geometry::Table {
                shift,
                radius,
                angle,
            } => {
                let n = shift.len();
                let (rho, delta) = if u <= shift[0] {
                    (radius[0], angle[0])
                } else if u >= shift[n - 1] {
                    (radius[n - 1], angle[n - 1])
                } else {
                    let j = shift.partition_point(|&s| s <= u).clamp(1, n - 1) - 1;
                    let t = (u - shift[j]) / (shift[j + 1] - shift[j]);
                    (
                        radius[j] + t * (radius[j + 1] - radius[j]),
                        angle[j] + t * (angle[j + 1] - angle[j]),
                    )
                };
                (rho, delta.tan(), delta.sin())
            }
        }
    }
}

/// The tangential forces of one wheel at one instant (see the module doc).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WheelForces {
    /// `F_Y`: the lateral force on the wheel in the track frame (N, positive to the right).
    pub lateral: f64,
    /// `eps F_x`: the longitudinal creep force on the wheel (N, positive forward).
    pub longitudinal: f64,
    /// `eps M_z`: the spin moment on the wheel (N m, about `z`).
    pub moment: f64,
    /// The flange contact force (N, >= 0).
    pub flange: f64,
    /// The shift `u` toward the wheel's flange (m).
    pub shift: f64,
    /// `Y = -s F_Y` (N, toward the track's centre).
    pub y: f64,
}

/// The motion a wheel's tangential forces read: the wheelset's lateral shift relative to the
/// rail and its rate, its roll rate, yaw and yaw rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelMotion {
    /// `y - y_rail` (m).
    pub shift: f64,
    /// `y' - y_rail'` (m/s).
    pub shift_rate: f64,
    /// Wheelset roll `phi` (rad).
    pub roll: f64,
    /// `phi'` (rad/s).
    pub roll_rate: f64,
    /// Wheelset yaw `psi` (rad).
    pub yaw: f64,
    /// `psi'` (rad/s).
    pub yaw_rate: f64,
}

/// One wheel at run time: its wheelset's DOFs, dimensions, geometry, creep coefficients and
/// flange.
#[derive(Debug, Clone, PartialEq)]
pub struct Wheel {
    /// `s`: -1 left, +1 right.
    pub side: f64,
    /// The wheelset's `y`, roll, yaw and (if any) `x` DOFs.
    pub y: usize,
    /// See `y`.
    pub roll: usize,
    /// See `y`.
    pub yaw: usize,
    /// See `y`.
    pub x: Option<usize>,
    /// The lateral rail's DOF.
    pub rail: Option<usize>,
    /// `e0` (m).
    pub half_gauge: f64,
    /// `r0` (m).
    pub radius: f64,
    /// Hertz constant `G` (m/N^(2/3)).
    pub hertz: f64,
    /// Geometry.
    pub geometry: Geometry,
    /// Creep coefficients.
    pub creep: Creep,
    /// Flange clearance (m) and stiffness (N/m).
    pub flange: Option<(f64, f64)>,
}

impl Wheel {
    /// The run-time wheel of a model wheel (`name`: the wheelset, for messages).
    pub fn of(w: &ModelWheel, name: &str) -> Result<Self> {
        Ok(Self {
            side: w.side,
            y: w.y,
            roll: w.roll,
            yaw: w.yaw,
            x: w.x,
            rail: w.rail,
            half_gauge: w.half_gauge,
            radius: w.radius,
            hertz: w.hertz,
            geometry: Geometry::of(&w.geometry),
            creep: Creep::of(w, name)?,
            flange: w.flange,
        })
    }

    /// The wheel's motion from the rigid state `(x, v)`.
    #[inline]
    pub fn motion(&self, x: &[f64], v: &[f64]) -> WheelMotion {
        let (mut shift, mut shift_rate) = (x[self.y], v[self.y]);
        if let Some(r) = self.rail {
            shift -= x[r];
            shift_rate -= v[r];
        }
        WheelMotion {
            shift,
            shift_rate,
            roll: x[self.roll],
            roll_rate: v[self.roll],
            yaw: x[self.yaw],
            yaw_rate: v[self.yaw],
        }
    }

    /// The wheel's contact from the vertical compression `d0` (m) before the rolling-radius
    /// change and its motion: the compression `d = d0 + rho`, the vertical load
    /// `Q = (d / G)^(3/2)` (computed as `x sqrt(x)`, `x = d / G`, as the Hertz law of the
    /// element; 0 when `d <= 0`) and the tangential forces, the creep coefficients at
    /// `Q^(2/3) = x`.
    #[inline]
    pub fn contact(&self, d0: f64, m: &WheelMotion, speed: f64) -> (f64, f64, WheelForces) {
        let u = self.side * m.shift;
        let geometry = self.geometry.at(u);
        let d = d0 + geometry.0;
        let (load, load_23) = if d > 0.0 {
            let x = d / self.hertz;
            (x * x.sqrt(), x)
        } else {
            (0.0, 0.0)
        };
        (d, load, self.tangential(load, load_23, geometry, m, speed))
    }

    /// The tangential forces at the normal load `q` (N) and speed `speed` (m/s, > 0).
    pub fn forces(&self, q: f64, m: &WheelMotion, speed: f64) -> WheelForces {
        let geometry = self.geometry.at(self.side * m.shift);
        let q13 = q.cbrt();
        self.tangential(q, q13 * q13, geometry, m, speed)
    }

    /// The tangential forces at the normal load `q` (N), `q23 = q^(2/3)`, with the geometry
    /// `(rho, tan delta, sin delta)` at the wheel's shift.
    #[inline]
    fn tangential(
        &self,
        q: f64,
        q23: f64,
        (rho, tan_delta, sin_delta): (f64, f64, f64),
        m: &WheelMotion,
        speed: f64,
    ) -> WheelForces {
        let s = self.side;
        let u = s * m.shift;
        let (mut fx, mut fy, mut mz) = (0.0, 0.0, 0.0);
        let mut normal = 0.0;
        if q > 0.0 {
            let (f11, f22, f23) = (
                self.creep.k11 * q23,
                self.creep.k22 * q23,
                self.creep.k23 * q,
            );
            let r0 = self.radius;
            let xi_x = -rho / r0 - s * self.half_gauge * m.yaw_rate / speed;
            let xi_y = (m.shift_rate - r0 * m.roll_rate) / speed - m.yaw;
            let spin = m.yaw_rate / speed - s * sin_delta / r0;
            fx = -f11 * xi_x;
            fy = -f22 * xi_y - f23 * spin;
            mz = f23 * xi_y;
            let resultant = (fx * fx + fy * fy).sqrt();
            let limit = self.creep.friction * q;
            if resultant > 0.0 {
                let eps = saturation(resultant / limit);
                fx *= eps;
                fy *= eps;
                mz *= eps;
            }
            // tan(delta - s phi) = (tan delta - tan s phi) / (1 + tan delta tan s phi), the
            // roll's tangent its angle (small rotations).
            let t_phi = s * m.roll;
            normal = -s * q * (tan_delta - t_phi) / (1.0 + tan_delta * t_phi);
        }
        let flange = match self.flange {
            Some((clearance, k)) if u > clearance => k * (u - clearance),
            _ => 0.0,
        };
        let lateral = fy + normal - s * flange;
        WheelForces {
            lateral,
            longitudinal: fx,
            moment: mz,
            flange,
            shift: u,
            y: -s * lateral,
        }
    }

    /// Adds the wheel's tangential generalised forces to the rigid DOFs' `out`.
    #[inline]
    pub fn apply(&self, f: &WheelForces, out: &mut [f64]) {
        out[self.y] += f.lateral;
        out[self.roll] -= self.radius * f.lateral;
        out[self.yaw] += f.moment - self.side * self.half_gauge * f.longitudinal;
        if let Some(x) = self.x {
            out[x] += f.longitudinal;
        }
        if let Some(r) = self.rail {
            out[r] -= f.lateral;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `K` and `E` against their series `pi/2 (1 + m/4 + 9 m^2/64)`, `pi/2 (1 - m/4 - 3 m^2/64)`
    /// at small `m`, and the closed values at `m = 1/2` (Abramowitz and Stegun, table 17.1).
    #[test]
    fn elliptic_integrals_match_series_and_table() {
        let m = 1e-3;
        let (k, e) = elliptic_ke(m);
        assert!((k - PI / 2.0 * (1.0 + m / 4.0 + 9.0 * m * m / 64.0)).abs() < 1e-9);
        assert!((e - PI / 2.0 * (1.0 - m / 4.0 - 3.0 * m * m / 64.0)).abs() < 1e-9);
        let (k, e) = elliptic_ke(0.5);
        assert!((k - 1.854_074_677_301_372).abs() < 1e-13, "{k}");
        assert!((e - 1.350_643_881_047_675).abs() < 1e-13, "{e}");
    }

    /// Equal curvatures give Hertz's circle `a^3 = 3 P R / (4 E*)` for a sphere of radius `R`
    /// on a plane (curvature sums `1 / (2R)`); nearly equal ones approach it continuously;
    /// swapping the curvatures swaps the axes; the ellipse's approach `3 P K / (2 pi a E*)`
    /// is the same whichever way round.
    #[test]
    fn hertz_ellipse_matches_the_circle_and_is_symmetric() {
        let (r, p, e_star): (f64, f64, f64) = (0.3, 7e4, 1.13e11);
        let want = (3.0 * p * r / (4.0 * e_star)).cbrt();
        let (a, b) = hertz_ellipse(0.5 / r, 0.5 / r, e_star, p);
        assert!((a - want).abs() < 1e-15 && (b - want).abs() < 1e-15);
        let (a, b) = hertz_ellipse(0.5 / r, 0.5 / r * (1.0 + 1e-6), e_star, p);
        assert!((a - want).abs() < 1e-6 * want && (b - want).abs() < 1e-6 * want);
        let (a1, b1) = hertz_ellipse(1.163, 1.667, e_star, p);
        let (a2, b2) = hertz_ellipse(1.667, 1.163, e_star, p);
        assert!(a1 > b1 && (a1 - b2).abs() < 1e-15 && (b1 - a2).abs() < 1e-15);
    }

    /// The table's nodes are returned as tabulated, `C11 = C22` at `nu = 0`, and the Poisson
    /// interpolation reproduces the middle row.
    #[test]
    fn kalker_table_nodes() {
        assert_eq!(kalker(1.0, 0.25), Some([4.12, 3.67, 1.47]));
        let [c11, c22, _] = kalker(0.37, 0.0).unwrap();
        assert!((c11 - c22).abs() < 1e-12);
        assert!(kalker(0.05, 0.25).is_none() && kalker(1.0, 0.6).is_none());
        let [c11, ..] = kalker(1.0 / 0.5, 0.25).unwrap();
        assert!((c11 - 5.10).abs() < 1e-12);
    }

    /// The saturation law is 1 at no creep, continuous with its slope at `x = 3`, and the
    /// saturated force `x eps(x)` rises monotonically to 1 (`mu Q`) and stays there.
    #[test]
    fn saturation_is_smooth_and_bounded() {
        assert_eq!(saturation(0.0), 1.0);
        let h = 1e-7;
        assert!((saturation(3.0 - h) - saturation(3.0 + h)).abs() < 1e-6);
        let slope = |x: f64| (saturation(x + h) - saturation(x - h)) / (2.0 * h);
        assert!((slope(3.0 - 1e-3) - slope(3.0 + 1e-3)).abs() < 1e-3);
        let mut last = 0.0;
        for i in 1..100 {
            let x = i as f64 * 0.05;
            let f = x * saturation(x);
            assert!(f >= last - 1e-15 && f <= 1.0 + 1e-15);
            last = f;
        }
    }
}
