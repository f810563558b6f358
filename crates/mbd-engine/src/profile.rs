//! Profiles under the moving points: the vertical level of the track or road (m, positive
//! downward: a dip), read by an element at its lower end's position `x`.
//!
//! A generated profile comes per sample as points `(x_n, eta_n)`, read between them as its
//! description says (`interpolation:`):
//!
//! - **linear** (the default): straight segments. The level is continuous but the slope, which a
//!   damper on the profile reads as `v d eta / dx`, jumps at every point, so the fixed-step
//!   solver loses its second order wherever a damper reads the profile.
//! - **cubic**: the not-a-knot cubic spline through the points (C2: level, slope and curvature
//!   continuous). Not-a-knot rather than natural: a natural spline forces zero curvature at the
//!   ends, which a random profile does not have, while not-a-knot (one cubic across the first
//!   two and across the last two cells) invents no end condition and reproduces any cubic
//!   polynomial exactly. A monotone Hermite (PCHIP, Akima) would be C1 only and flattens
//!   extrema. The slopes `s_n` at the points solve one tridiagonal system at construction
//!   (O(N), no pivoting needed: every pivot is positive for N >= 4); each cell then keeps the
//!   coefficients of `eta_n + s_n t + c2_n t^2 + c3_n t^3`, `t = x - x_n`.
//!
//! Both read a point in O(log N) (a binary search for the cell) and are clamped outside the
//! points: `eta` keeps its end value and the slope is 0 beyond the ends (coverage is checked
//! before a run, so a run never reads there). A harmonic profile is analytic,
//! `eta(x) = a sin(2 pi x / lambda + phi)`, so a test can compare against a closed form without
//! the interpolation's loss of amplitude.

use crate::{Error, Result};
use mbd_system::schema::Interpolation;

/// Sampled profile points and how they are read between them.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    x: Vec<f64>,
    eta: Vec<f64>,
    /// Per cell `n` (from `x_n` to `x_{n+1}`) of a cubic profile: `[s_n, c2_n, c3_n]` of
    /// `eta_n + s_n t + c2_n t^2 + c3_n t^3` (m/m, m/m^2, m/m^3); empty for a linear one.
    cubic: Vec<[f64; 3]>,
    /// `1 / dx` when the points are evenly spaced (to 1e-9 of the spacing), as a generated
    /// profile's are: [`Profile::cell`] then guesses the cell from `x` and only checks it.
    inverse_spacing: Option<f64>,
}

impl Profile {
    /// Linearly interpolated points. Checks lengths (equal, >= 2), strictly increasing finite
    /// `x` and finite `eta`.
    pub fn new(x: Vec<f64>, eta: Vec<f64>) -> Result<Self> {
        if x.len() != eta.len() || x.len() < 2 {
            return Err(Error::Shape {
                name: "eta".to_owned(),
                found: eta.len(),
                expected: x.len().max(2),
            });
        }
        if let Some(w) = x
            .windows(2)
            .find(|w| !(w[0].is_finite() && w[1].is_finite() && w[1] > w[0]))
        {
            return Err(Error::OutOfRange {
                name: "x".to_owned(),
                value: w[1],
                allowed: format!("finite and strictly increasing (after {})", w[0]),
            });
        }
        if let Some(e) = eta.iter().find(|e| !e.is_finite()) {
            return Err(Error::OutOfRange {
                name: "eta".to_owned(),
                value: *e,
                allowed: "finite".to_owned(),
            });
        }
        let n = x.len();
        let dx = (x[n - 1] - x[0]) / (n - 1) as f64;
        let even = x
            .iter()
            .enumerate()
            .all(|(i, &xi)| (xi - (x[0] + i as f64 * dx)).abs() <= 1e-9 * dx);
        Ok(Self {
            x,
            eta,
            cubic: Vec::new(),
            inverse_spacing: even.then_some(1.0 / dx),
        })
    }

    /// The same points read by `interpolation`; a cubic needs at least
    /// [`Interpolation::min_points`] points.
    pub fn interpolated(mut self, interpolation: Interpolation) -> Result<Self> {
        match interpolation {
            Interpolation::Linear => self.cubic = Vec::new(),
            Interpolation::Cubic => {
                if self.x.len() < interpolation.min_points() {
                    return Err(Error::Shape {
                        name: "eta (a cubic profile)".to_owned(),
                        found: self.x.len(),
                        expected: interpolation.min_points(),
                    });
                }
                self.cubic = spline_cells(&self.x, &self.eta);
            }
        }
        Ok(self)
    }

    /// How the points are read between them.
    pub fn interpolation(&self) -> Interpolation {
        if self.cubic.is_empty() {
            Interpolation::Linear
        } else {
            Interpolation::Cubic
        }
    }

    /// Covered positions `[x_first, x_last]` (m).
    pub fn range(&self) -> [f64; 2] {
        [self.x[0], self.x[self.x.len() - 1]]
    }

    /// The cell `i` (from `x_(i-1)` to `x_i`, `1 <= i < len`) holding `x`: the first point
    /// above `x`, clamped to the ends. On evenly spaced points the cell guessed from `x` and
    /// its neighbours are checked first (the result is the binary search's either way).
    #[inline]
    fn cell(&self, x: f64) -> usize {
        let n = self.x.len();
        if let Some(inverse) = self.inverse_spacing {
            let guess = (x - self.x[0]) * inverse;
            if guess >= 0.0 && guess < n as f64 {
                // Truncation is the floor of a non-negative number.
                let g = guess as usize + 1;
                for i in [g, g - 1, g + 1] {
                    // `i` is the first point above `x`, or the end cell that holds it.
                    if (1..n).contains(&i)
                        && (i == 1 || self.x[i - 1] <= x)
                        && (i == n - 1 || self.x[i] > x)
                    {
                        return i;
                    }
                }
            }
        }
        self.x.partition_point(|&p| p <= x).clamp(1, n - 1)
    }

    /// `eta` at `x` (m) by the profile's interpolation (clamped to the ends).
    #[inline]
    pub fn at(&self, x: f64) -> f64 {
        let i = self.cell(x);
        if let Some(&[s, c2, c3]) = self.cubic.get(i - 1) {
            let t = x.clamp(self.x[i - 1], self.x[i]) - self.x[i - 1];
            return self.eta[i - 1] + t * (s + t * (c2 + t * c3));
        }
        let (x0, x1) = (self.x[i - 1], self.x[i]);
        let w = ((x - x0) / (x1 - x0)).clamp(0.0, 1.0);
        self.eta[i - 1] + w * (self.eta[i] - self.eta[i - 1])
    }

    /// `d eta / dx` at `x` (1): the slope of the interpolant (of the segment for a linear
    /// profile, continuous for a cubic one); 0 beyond the ends.
    #[inline]
    pub fn slope(&self, x: f64) -> f64 {
        let [lo, hi] = self.range();
        if x < lo || x > hi {
            return 0.0;
        }
        let i = self.cell(x);
        if let Some(&[s, c2, c3]) = self.cubic.get(i - 1) {
            let t = x - self.x[i - 1];
            return s + t * (2.0 * c2 + t * 3.0 * c3);
        }
        (self.eta[i] - self.eta[i - 1]) / (self.x[i] - self.x[i - 1])
    }

    /// `(eta(x), d eta / dx)`: [`Profile::at`] and [`Profile::slope`] from one cell search,
    /// each by its own arithmetic (the same values to the bit).
    #[inline]
    pub fn at_and_slope(&self, x: f64) -> (f64, f64) {
        let i = self.cell(x);
        let [lo, hi] = self.range();
        let inside = !(x < lo || x > hi);
        if let Some(&[s, c2, c3]) = self.cubic.get(i - 1) {
            let t = x.clamp(self.x[i - 1], self.x[i]) - self.x[i - 1];
            let at = self.eta[i - 1] + t * (s + t * (c2 + t * c3));
            if !inside {
                return (at, 0.0);
            }
            let t = x - self.x[i - 1];
            return (at, s + t * (2.0 * c2 + t * 3.0 * c3));
        }
        let (x0, x1) = (self.x[i - 1], self.x[i]);
        let w = ((x - x0) / (x1 - x0)).clamp(0.0, 1.0);
        let at = self.eta[i - 1] + w * (self.eta[i] - self.eta[i - 1]);
        let slope = if inside {
            (self.eta[i] - self.eta[i - 1]) / (x1 - x0)
        } else {
            0.0
        };
        (at, slope)
    }
}

/// The cells of the not-a-knot cubic spline through `(x, eta)` (`x` strictly increasing, at
/// least 4 points). The slopes `s` at the points solve, with `h_n = x_{n+1} - x_n` and the
/// secants `d_n = (eta_{n+1} - eta_n) / h_n`,
/// ```text
/// h_n s_{n-1} + 2 (h_{n-1} + h_n) s_n + h_{n-1} s_{n+1} = 3 (h_n d_{n-1} + h_{n-1} d_n)
/// ```
/// at the interior points (continuous curvature) and, at the ends, continuity of the third
/// derivative across the second and the second-to-last point (not-a-knot):
/// ```text
/// h_1 s_0 + (h_0 + h_1) s_1 = ((h_0 + 2 (h_0 + h_1)) h_1 d_0 + h_0^2 d_1) / (h_0 + h_1)
/// (h_m + h_{m-1}) s_{m} + h_{m-1} s_{m+1} = (h_m^2 d_{m-1} + (2 (h_{m-1} + h_m) + h_m) h_{m-1} d_m)
///                                          / (h_{m-1} + h_m),   m = N - 2
/// ```
/// solved by forward elimination and back substitution without pivoting: the pivots are
/// `h_1`, `h_0 + h_1`, then above `2 h_{n-1} + h_n` on the interior rows and above
/// `h_{m-1}^2 / (2 h_{m-1} + h_m)` on the last, all positive.
fn spline_cells(x: &[f64], eta: &[f64]) -> Vec<[f64; 3]> {
    let n = x.len();
    let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let d: Vec<f64> = (0..n - 1).map(|i| (eta[i + 1] - eta[i]) / h[i]).collect();
    // Row i: lower[i] s_{i-1} + diag[i] s_i + upper[i] s_{i+1} = rhs[i].
    let (mut lower, mut diag, mut upper, mut rhs) =
        (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    diag[0] = h[1];
    upper[0] = h[0] + h[1];
    rhs[0] = ((h[0] + 2.0 * (h[0] + h[1])) * h[1] * d[0] + h[0] * h[0] * d[1]) / (h[0] + h[1]);
    for i in 1..n - 1 {
        lower[i] = h[i];
        diag[i] = 2.0 * (h[i - 1] + h[i]);
        upper[i] = h[i - 1];
        rhs[i] = 3.0 * (h[i] * d[i - 1] + h[i - 1] * d[i]);
    }
    let m = n - 2;
    lower[n - 1] = h[m] + h[m - 1];
    diag[n - 1] = h[m - 1];
    rhs[n - 1] = (h[m] * h[m] * d[m - 1] + (2.0 * (h[m - 1] + h[m]) + h[m]) * h[m - 1] * d[m])
        / (h[m - 1] + h[m]);
    for i in 1..n {
        let f = lower[i] / diag[i - 1];
        diag[i] -= f * upper[i - 1];
        rhs[i] -= f * rhs[i - 1];
    }
    let mut s = vec![0.0; n];
    s[n - 1] = rhs[n - 1] / diag[n - 1];
    for i in (0..n - 1).rev() {
        s[i] = (rhs[i] - upper[i] * s[i + 1]) / diag[i];
    }
    (0..n - 1)
        .map(|i| {
            let c2 = (3.0 * d[i] - 2.0 * s[i] - s[i + 1]) / h[i];
            let c3 = (s[i] + s[i + 1] - 2.0 * d[i]) / (h[i] * h[i]);
            [s[i], c2, c3]
        })
        .collect()
}

/// A profile as the engine reads it.
#[derive(Debug, Clone, PartialEq)]
pub enum ProfileSource {
    /// Sampled points.
    Points(Profile),
    /// `amplitude sin(2 pi x / wavelength + phase)`.
    Harmonic {
        /// m.
        amplitude: f64,
        /// m.
        wavelength: f64,
        /// rad.
        phase: f64,
    },
    /// A perfectly level track or road.
    Level,
    /// A weighted sum of profiles, `sum_k w_k eta_k(x)` (a description's `combination`).
    Sum(Vec<(f64, ProfileSource)>),
    /// A profile that ends at `end` (m): `w(x) eta(x)`, `w` 1 up to `end - taper`, then
    /// `(1 + cos(pi (x - end + taper) / taper)) / 2` down to 0 at `end` (level and slope
    /// continuous), 0 beyond (a description's `until`).
    Until {
        /// The profile.
        inner: Box<ProfileSource>,
        /// Where it ends (m).
        end: f64,
        /// Length of the fade (m).
        taper: f64,
    },
}

impl ProfileSource {
    /// `eta(x)` (m).
    #[inline]
    pub fn at(&self, x: f64) -> f64 {
        match self {
            ProfileSource::Points(p) => p.at(x),
            ProfileSource::Harmonic {
                amplitude,
                wavelength,
                phase,
            } => amplitude * (std::f64::consts::TAU * x / wavelength + phase).sin(),
            ProfileSource::Level => 0.0,
            ProfileSource::Sum(terms) => terms.iter().map(|(w, p)| w * p.at(x)).sum(),
            ProfileSource::Until { inner, end, taper } => {
                let (w, _) = fade(x, *end, *taper);
                if w == 0.0 {
                    0.0
                } else {
                    w * inner.at(x)
                }
            }
        }
    }

    /// The excitation `r eta(x)` (m) with the start-up factor `r` of the run controls
    /// ([`crate::RunConfig::ramp`]): exactly 0 while the profile is off.
    #[inline]
    pub fn ramped(&self, ramp: f64, x: f64) -> f64 {
        if ramp > 0.0 {
            ramp * self.at(x)
        } else {
            0.0
        }
    }

    /// The rate `d/dt (r eta(x))` (m/s) of [`ProfileSource::ramped`] read at `x = x0 + speed t`
    /// under the start-up factor `r` and its rate `ramp_rate` (1/s): `r speed eta'(x) +
    /// r' eta(x)`.
    #[inline]
    pub fn ramped_rate(&self, ramp: f64, ramp_rate: f64, speed: f64, x: f64) -> f64 {
        ramp * speed * self.slope(x) + ramp_rate * self.at(x)
    }

    /// `(eta(x), d eta / dx)`, the values of [`ProfileSource::at`] and
    /// [`ProfileSource::slope`] to the bit, a sampled profile's cell searched once.
    #[inline]
    pub fn at_and_slope(&self, x: f64) -> (f64, f64) {
        match self {
            ProfileSource::Points(p) => p.at_and_slope(x),
            ProfileSource::Until { inner, end, taper } => {
                let (w, dw) = fade(x, *end, *taper);
                if w == 0.0 {
                    (0.0, 0.0)
                } else {
                    let (at, slope) = inner.at_and_slope(x);
                    (w * at, w * slope + dw * at)
                }
            }
            _ => (self.at(x), self.slope(x)),
        }
    }

    /// The positions (m) the profile covers, `None` for every `x` (an analytic or level
    /// profile); a sum covers where all its sampled parts do.
    pub fn covered(&self) -> Option<[f64; 2]> {
        match self {
            ProfileSource::Points(p) => Some(p.range()),
            ProfileSource::Sum(terms) => terms
                .iter()
                .filter_map(|(_, p)| p.covered())
                .reduce(|a, b| [a[0].max(b[0]), a[1].min(b[1])]),
            // Beyond its end it is level everywhere.
            ProfileSource::Until { inner, end, .. } => inner.covered().map(|[lo, hi]| {
                if *end <= hi {
                    [lo, f64::INFINITY]
                } else {
                    [lo, hi]
                }
            }),
            _ => None,
        }
    }

    /// `d eta / dx` (1).
    #[inline]
    pub fn slope(&self, x: f64) -> f64 {
        match self {
            ProfileSource::Points(p) => p.slope(x),
            ProfileSource::Harmonic {
                amplitude,
                wavelength,
                phase,
            } => {
                let k = std::f64::consts::TAU / wavelength;
                amplitude * k * (k * x + phase).cos()
            }
            ProfileSource::Level => 0.0,
            ProfileSource::Sum(terms) => terms.iter().map(|(w, p)| w * p.slope(x)).sum(),
            ProfileSource::Until { inner, end, taper } => {
                let (w, dw) = fade(x, *end, *taper);
                if w == 0.0 {
                    0.0
                } else {
                    w * inner.slope(x) + dw * inner.at(x)
                }
            }
        }
    }
}

/// The fade of an ending profile at `x` and its slope: 1 up to `end - taper`, a half cosine
/// to 0 at `end`, 0 beyond.
#[inline]
fn fade(x: f64, end: f64, taper: f64) -> (f64, f64) {
    if x >= end {
        (0.0, 0.0)
    } else if x <= end - taper {
        (1.0, 0.0)
    } else {
        let phase = std::f64::consts::PI * (x - end + taper) / taper;
        (
            0.5 * (1.0 + phase.cos()),
            -0.5 * std::f64::consts::PI / taper * phase.sin(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cell found from an evenly spaced grid's guess is the binary search's, at points,
    /// between them, beyond both ends, on grids that are even and on one that is not.
    #[test]
    fn cell_guess_equals_the_search() {
        let even: Vec<f64> = (0..200).map(|i| i as f64 * 0.1 - 3.0).collect();
        for x in [even.clone(), uneven()] {
            let p = Profile::new(x.clone(), vec![0.0; x.len()]).unwrap();
            let n = x.len();
            let search = |v: f64| x.partition_point(|&q| q <= v).clamp(1, n - 1);
            let mut probes: Vec<f64> = x.clone();
            probes.extend(x.windows(2).map(|w| 0.5 * (w[0] + w[1])));
            probes.extend(x.iter().map(|v| v - 1e-12));
            probes.extend([x[0] - 5.0, x[n - 1] + 5.0, x[n - 1], x[0]]);
            for v in probes {
                assert_eq!(p.cell(v), search(v), "x = {v}");
            }
        }
        assert!(Profile::new(even, vec![0.0; 200])
            .unwrap()
            .inverse_spacing
            .is_some());
    }

    /// Unevenly spaced points (the spline's system is not the uniform one).
    fn uneven() -> Vec<f64> {
        (0..12)
            .map(|i| {
                let i = i as f64;
                0.5 * i + 0.07 * (1.3 * i).sin()
            })
            .collect()
    }

    fn cubic_of(x: &[f64], f: impl Fn(f64) -> f64) -> Profile {
        let eta = x.iter().map(|&x| f(x)).collect();
        Profile::new(x.to_vec(), eta)
            .unwrap()
            .interpolated(Interpolation::Cubic)
            .unwrap()
    }

    /// Not-a-knot reproduces a cubic polynomial exactly (its end conditions hold for it), level
    /// and slope, between and at the points; so does it a line.
    #[test]
    fn cubic_is_exact_for_a_cubic_polynomial() {
        let x = uneven();
        let f = |x: f64| 1e-3 * (0.3 - 0.8 * x + 0.45 * x * x - 0.09 * x * x * x);
        let df = |x: f64| 1e-3 * (-0.8 + 0.9 * x - 0.27 * x * x);
        let p = cubic_of(&x, f);
        assert_eq!(p.interpolation(), Interpolation::Cubic);
        let [lo, hi] = p.range();
        for k in 0..=500 {
            let s = lo + (hi - lo) * k as f64 / 500.0;
            assert!(
                (p.at(s) - f(s)).abs() < 1e-15,
                "at {s}: {} vs {}",
                p.at(s),
                f(s)
            );
            assert!((p.slope(s) - df(s)).abs() < 1e-14, "slope at {s}");
        }
    }

    /// The points are reproduced (exactly where a cell starts, to round-off at the last point,
    /// the end of the last cell), and the slope's left and right limits agree at every
    /// interior point (continuous; the linear profile's jump there is far larger).
    #[test]
    fn cubic_reproduces_its_points_with_a_continuous_slope() {
        let x = uneven();
        let f = |x: f64| 2e-3 * (1.7 * x).sin() + 1e-3 * (0.4 * x).cos();
        let cubic = cubic_of(&x, f);
        let linear = Profile::new(x.clone(), x.iter().map(|&x| f(x)).collect()).unwrap();
        let eps = 1e-9;
        let mut jump_linear = 0.0f64;
        for (i, &xi) in x.iter().enumerate() {
            if i + 1 < x.len() {
                assert_eq!(cubic.at(xi), f(xi), "point {i}");
            } else {
                assert!((cubic.at(xi) - f(xi)).abs() < 1e-18, "last point");
            }
            if i > 0 && i + 1 < x.len() {
                let jump = (cubic.slope(xi + eps) - cubic.slope(xi - eps)).abs();
                assert!(jump < 1e-10, "slope jumps by {jump:e} at point {i}");
                jump_linear =
                    jump_linear.max((linear.slope(xi + eps) - linear.slope(xi - eps)).abs());
            }
        }
        assert!(jump_linear > 1e-4, "{jump_linear:e}");
    }

    /// Clamped outside the points like the linear profile: the end values, slope 0.
    #[test]
    fn cubic_is_clamped_beyond_its_ends() {
        let x = uneven();
        let p = cubic_of(&x, |x| 1e-3 * x.sin());
        let [lo, hi] = p.range();
        assert_eq!(p.at(lo - 1.0), p.at(lo));
        assert_eq!(p.at(hi + 1.0), p.at(hi));
        assert_eq!(p.slope(lo - 1e-6), 0.0);
        assert_eq!(p.slope(hi + 1e-6), 0.0);
        assert!(p.slope(lo).abs() > 1e-5);
    }

    /// A cubic needs 4 points; a linear profile keeps its segments (and its values) whatever
    /// it was before.
    #[test]
    fn cubic_refuses_fewer_than_four_points_and_linear_is_unchanged() {
        let three = Profile::new(vec![0.0, 1.0, 2.0], vec![0.0, 1e-3, 0.0]).unwrap();
        let e = three
            .clone()
            .interpolated(Interpolation::Cubic)
            .unwrap_err();
        assert!(e.to_string().contains("cubic"), "{e}");
        let x = uneven();
        let linear = Profile::new(x.clone(), x.iter().map(|x| 1e-3 * x.sin()).collect()).unwrap();
        let back = cubic_of(&x, |x| 1e-3 * x.sin())
            .interpolated(Interpolation::Linear)
            .unwrap();
        assert_eq!(back, linear);
        assert_eq!(
            linear.at(0.75),
            1e-3 * (x[1].sin() + (0.75 - x[1]) / (x[2] - x[1]) * (x[2].sin() - x[1].sin()))
        );
    }

    /// An ending profile: the profile itself before the taper, 0 from its end on, level and
    /// slope continuous across the taper (its slope the derivative of its level), and covered
    /// everywhere beyond its end.
    #[test]
    fn until_fades_out_continuously() {
        let inner = ProfileSource::Harmonic {
            amplitude: 2e-3,
            wavelength: 7.0,
            phase: 0.3,
        };
        let (end, taper) = (30.0, 4.0);
        let p = ProfileSource::Until {
            inner: Box::new(inner.clone()),
            end,
            taper,
        };
        for x in [0.0, 12.5, end - taper] {
            assert_eq!(p.at(x), inner.at(x));
            assert_eq!(p.slope(x), inner.slope(x));
        }
        for x in [end, end + 0.1, 1e3] {
            assert_eq!((p.at(x), p.slope(x)), (0.0, 0.0));
        }
        // Half-way the fade is 1/2, its slope -pi / (2 taper).
        let mid = end - taper / 2.0;
        assert!((p.at(mid) - 0.5 * inner.at(mid)).abs() < 1e-18);
        let want = 0.5 * inner.slope(mid) - std::f64::consts::PI / (2.0 * taper) * inner.at(mid);
        assert!((p.slope(mid) - want).abs() < 1e-15);
        // The slope is the level's derivative (central differences) over the whole taper and
        // at both of its ends.
        let h = 1e-5;
        let mut x = end - taper - 0.5;
        while x <= end + 0.5 {
            let fd = (p.at(x + h) - p.at(x - h)) / (2.0 * h);
            assert!(
                (fd - p.slope(x)).abs() < 1e-8,
                "x {x}: {fd} vs {}",
                p.slope(x)
            );
            x += 0.0625;
        }
        let points = Profile::new(vec![0.0, 10.0, 20.0, 40.0], vec![0.0; 4]).unwrap();
        let ending = |end: f64| ProfileSource::Until {
            inner: Box::new(ProfileSource::Points(points.clone())),
            end,
            taper: 1.0,
        };
        assert_eq!(ending(35.0).covered(), Some([0.0, f64::INFINITY]));
        assert_eq!(ending(50.0).covered(), Some([0.0, 40.0]));
    }
}
