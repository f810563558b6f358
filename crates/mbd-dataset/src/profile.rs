//! Random-phase profiles from a displacement spectrum (the track irregularity of the
//! vehicle-track system, a road's roughness).
//!
//! **Spectrum.** A one-sided spectrum `S(f)` (mm^2/(1/m)) of the spatial frequency `f` (1/m)
//! ([`Psd`]): a piecewise power law, `S(f) = A_j / f^n_j` on segment `j` (TB/T 3352-2014 for
//! high-speed track, ISO 8608 classes for roads), or a two-pole form
//! `S(f) = c / ((f^2 + p^2)(f^2 + q^2))` (the FRA track classes,
//! [`mbd_system::schema::fra`]). The system description gives it and the wavelength band.
//!
//! **Profile.** `N = ceil(length / dx)` points `x_n = n dx` (m), rounded up to even, frequency
//! bins `f_k = k / (N dx)`, `df = 1 / (N dx)`. Each bin `0 < k < N/2` gets the power of the
//! spectrum over its cell, `P_k = integral of S over [f_k - df/2, f_k + df/2] ∩ band` (closed
//! form of either shape), and
//! ```text
//! eta(x_n) = sum_k sqrt(2 P_k) cos(2 pi f_k x_n + phi_k),   phi_k ~ U[0, 2 pi)
//! ```
//! computed as one inverse complex FFT of the Hermitian spectrum. Only the phases are random, so
//! every profile has mean exactly 0 and mean square exactly `sum_k P_k`, the band integral of
//! `S`. Integrating `S` over each cell (rather than sampling `S(f_k) df`) matters where `S`
//! falls steeply at the long wavelengths.
//!
//! The phases of sample `id` are the uniforms of its stream ([`crate::rng::SampleStream`] with
//! the profile's code) in increasing `k`, one per bin with nonzero power.
//!
//! **Units and sign.** Profiles are returned in metres, positive **downward** like every
//! displacement (a positive `eta` is a dip). They are periodic with period `N dx`.
//!
//! [`welch_psd`] is the one-sided Welch estimate (Hann window, 50% overlap) used to check
//! profiles against `S`.

use crate::rng::SampleStream;
use crate::{Error, Result};
use mbd_system::system::GENERATED_PROFILE_START;
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::sync::Arc;

/// Largest profile (points): 2^26, 0.5 GiB of complex FFT buffer; the default has 5400.
pub const MAX_POINTS: usize = 1 << 26;

/// One power-law segment `S(f) = a / f^n` (mm^2/(1/m)), valid from `f_start` (1/m) up to the
/// next segment's start.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PsdSegment {
    /// Lower frequency bound of the segment (1/m); 0 for the first.
    pub f_start: f64,
    /// Coefficient `A` (mm^2 (1/m)^(n-1)).
    pub a: f64,
    /// Exponent `n`.
    pub n: f64,
}

/// A checked spectrum: a piecewise power law or a two-pole form.
#[derive(Debug, Clone, PartialEq)]
pub struct Psd {
    shape: Shape,
}

#[derive(Debug, Clone, PartialEq)]
enum Shape {
    PowerLaw(Vec<PsdSegment>),
    /// `S(f) = c / ((f^2 + p^2)(f^2 + q^2))`, `0 <= p < q`.
    TwoPole {
        c: f64,
        p: f64,
        q: f64,
    },
}

/// `integral of df / (f^2 + a^2)` over `[f1, f2]` (`0 < f1 <= f2`, `a >= 0`):
/// `(atan(f2 / a) - atan(f1 / a)) / a`, written as one arctangent so that a narrow cell keeps
/// its digits; `(f2 - f1) / (f1 f2)` (its limit) at `a = 0`.
fn pole_integral(a: f64, f1: f64, f2: f64) -> f64 {
    if a == 0.0 {
        (f2 - f1) / (f1 * f2)
    } else {
        (a * (f2 - f1) / (a * a + f1 * f2)).atan() / a
    }
}

impl Psd {
    /// Smallest relative gap `(q - p) / q` of a two-pole spectrum: below it the partial
    /// fractions of [`Self::integral`] would lose more than about 3 of their digits.
    pub const MIN_POLE_GAP: f64 = 1e-3;

    /// The spectrum of a description's `psd` (in the generator's unit), checked.
    pub fn from_description(psd: &mbd_system::schema::RawPsd) -> Result<Self> {
        match psd {
            mbd_system::schema::RawPsd::PowerLaw(segments) => Self::new(
                segments
                    .iter()
                    .map(|s| PsdSegment {
                        f_start: s.f_start,
                        a: s.a,
                        n: s.n,
                    })
                    .collect(),
            ),
            &mbd_system::schema::RawPsd::TwoPole { c, p, q } => Self::two_pole(c, p, q),
        }
    }

    /// `S(f) = c / ((f^2 + p^2)(f^2 + q^2))` (mm^2/(1/m)), `c > 0` (mm^2 (1/m)^3) and the poles
    /// `p, q >= 0` (1/m, either order) finite, at most one of them 0, at least
    /// [`Self::MIN_POLE_GAP`] apart relative to the larger.
    pub fn two_pole(c: f64, p: f64, q: f64) -> Result<Self> {
        let bad = |value: f64, allowed: &str| Error::OutOfRange {
            name: "psd".to_owned(),
            value,
            allowed: allowed.to_owned(),
        };
        if !(c.is_finite() && c > 0.0) {
            return Err(bad(c, "c must be finite and > 0"));
        }
        let (p, q) = (p.min(q), p.max(q));
        if !(p >= 0.0 && q.is_finite()) {
            return Err(bad(p, "the poles must be finite and >= 0"));
        }
        if !(q > 0.0 && q - p >= Self::MIN_POLE_GAP * q) {
            return Err(bad(
                q,
                &format!(
                    "the poles {p} and {q} must differ by at least {} of the larger",
                    Self::MIN_POLE_GAP
                ),
            ));
        }
        Ok(Self {
            shape: Shape::TwoPole { c, p, q },
        })
    }

    /// Checks a segment table: first `f_start` is 0, starts strictly increasing, every `a > 0`
    /// and `n` finite.
    pub fn new(segments: Vec<PsdSegment>) -> Result<Self> {
        let bad = |value: f64, allowed: &str| Error::OutOfRange {
            name: "psd".to_owned(),
            value,
            allowed: allowed.to_owned(),
        };
        match segments.first() {
            None => return Err(bad(0.0, "at least one segment {f_start, a, n}")),
            Some(s) if s.f_start != 0.0 => {
                return Err(bad(s.f_start, "the first segment's f_start must be 0"))
            }
            _ => {}
        }
        for (j, s) in segments.iter().enumerate() {
            if !(s.a.is_finite() && s.a > 0.0) {
                return Err(bad(s.a, &format!("segment {j}: a must be finite and > 0")));
            }
            if !s.n.is_finite() {
                return Err(bad(s.n, &format!("segment {j}: n must be finite")));
            }
            if j > 0 && !(s.f_start.is_finite() && s.f_start > segments[j - 1].f_start) {
                return Err(bad(
                    s.f_start,
                    &format!("segment {j}: f_start must be finite and above the previous one"),
                ));
            }
        }
        Ok(Self {
            shape: Shape::PowerLaw(segments),
        })
    }

    /// The segments of a power law; empty for a two-pole spectrum.
    pub fn segments(&self) -> &[PsdSegment] {
        match &self.shape {
            Shape::PowerLaw(segments) => segments,
            Shape::TwoPole { .. } => &[],
        }
    }

    /// `S(f)` in mm^2/(1/m) for `f > 0` (1/m).
    pub fn value(&self, f: f64) -> f64 {
        match &self.shape {
            Shape::PowerLaw(segments) => {
                let j = segments.iter().rposition(|s| f >= s.f_start).unwrap_or(0);
                let s = segments[j];
                s.a * f.powf(-s.n)
            }
            &Shape::TwoPole { c, p, q } => c / ((f * f + p * p) * (f * f + q * q)),
        }
    }

    /// `integral of S(f) df` over `[f1, f2]` (mm^2), `0 < f1 <= f2`, in closed form: per
    /// segment of a power law `A (f^(1-n)) / (1-n)`, or `A ln f` when `n = 1`; for two poles
    /// the partial fractions `c / (q^2 - p^2) (1 / (f^2 + p^2) - 1 / (f^2 + q^2))`.
    pub fn integral(&self, f1: f64, f2: f64) -> f64 {
        match &self.shape {
            Shape::PowerLaw(segments) => power_law_integral(segments, f1, f2),
            &Shape::TwoPole { c, p, q } => {
                c / (q * q - p * p) * (pole_integral(p, f1, f2) - pole_integral(q, f1, f2))
            }
        }
    }
}

/// [`Psd::integral`] of a power law.
fn power_law_integral(segments: &[PsdSegment], f1: f64, f2: f64) -> f64 {
    let mut total = 0.0;
    for (j, s) in segments.iter().enumerate() {
        let end = segments.get(j + 1).map_or(f64::INFINITY, |s| s.f_start);
        let lo = f1.max(s.f_start);
        let hi = f2.min(end);
        if hi > lo {
            total += if (s.n - 1.0).abs() < 1e-12 {
                s.a * (hi / lo).ln()
            } else {
                s.a * (hi.powf(1.0 - s.n) - lo.powf(1.0 - s.n)) / (1.0 - s.n)
            };
        }
    }
    total
}

/// The run controls of profile generation (the `irregularity` stage's parameters): seed, point
/// spacing and profile length. The spectrum and the wavelength band come from the system
/// description.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileParams {
    /// Seed of the random phases.
    pub seed: u64,
    /// Profile spacing `dx` (m).
    pub dx: f64,
    /// Profile length (m), from `x = 0`.
    pub length: f64,
}

impl ProfileParams {
    /// The number of points `N = ceil(length / dx)` rounded up to even, or `None` when `dx` or
    /// `length` is not a finite positive number or `N` exceeds [`MAX_POINTS`].
    pub fn points(&self) -> Option<usize> {
        let points = (self.length / self.dx).ceil();
        if !(self.dx > 0.0 && points.is_finite() && points >= 0.0 && points <= MAX_POINTS as f64) {
            return None;
        }
        let n = points as usize;
        Some(if n % 2 == 1 { n + 1 } else { n })
    }

    /// Checks the values against the band `[wavelength_min, wavelength_max]` (m) of `psd`
    /// and precomputes the bin amplitudes and the FFT plan. `code` keys the random phases
    /// ([`crate::rng::profile_code`]).
    pub fn generator(
        &self,
        psd: Psd,
        wavelengths: [f64; 2],
        code: u64,
    ) -> Result<ProfileGenerator> {
        let out = |name: &str, value: f64, allowed: String| Error::OutOfRange {
            name: name.to_owned(),
            value,
            allowed,
        };
        if !(self.dx.is_finite() && self.dx > 0.0) {
            return Err(out("dx", self.dx, "finite and > 0 (m)".into()));
        }
        if !(self.length.is_finite() && self.length >= 4.0 * self.dx) {
            return Err(out(
                "length",
                self.length,
                format!("finite and >= 4 dx = {} (m)", 4.0 * self.dx),
            ));
        }
        let [lmin, lmax] = wavelengths;
        // The band must lie strictly below Nyquist (wavelength 2 dx) and fit in the profile.
        if !(lmin.is_finite()
            && lmax.is_finite()
            && lmin > 2.0 * self.dx
            && lmin < lmax
            && lmax <= self.length)
        {
            return Err(Error::InvalidRange {
                name: "wavelengths".to_owned(),
                lo: lmin,
                hi: lmax,
                allowed: format!(
                    "need 2 dx = {} < min < max <= length = {} (m)",
                    2.0 * self.dx,
                    self.length
                ),
            });
        }
        let Some(n) = self.points() else {
            return Err(out(
                "length",
                self.length,
                format!("at most {MAX_POINTS} points of dx = {} m", self.dx),
            ));
        };
        let df = 1.0 / (n as f64 * self.dx);
        let (f_lo, f_hi) = (1.0 / lmax, 1.0 / lmin);
        let mut bins = Vec::new();
        for k in 1..n / 2 {
            let fk = k as f64 * df;
            let lo = (fk - 0.5 * df).max(f_lo);
            let hi = (fk + 0.5 * df).min(f_hi);
            if hi > lo {
                bins.push((k, psd.integral(lo, hi)));
            }
        }
        let fft = FftPlanner::new().plan_fft_inverse(n);
        Ok(ProfileGenerator {
            seed: self.seed,
            code,
            dx: self.dx,
            n,
            band: [f_lo, f_hi],
            bins,
            psd,
            fft,
        })
    }
}

/// Generates the profile of any sample; cheap to share across threads.
#[derive(Clone)]
pub struct ProfileGenerator {
    seed: u64,
    code: u64,
    dx: f64,
    n: usize,
    band: [f64; 2],
    /// `(k, P_k)`: bin index and bin power (mm^2), increasing `k`.
    bins: Vec<(usize, f64)>,
    psd: Psd,
    fft: Arc<dyn Fft<f64>>,
}

impl std::fmt::Debug for ProfileGenerator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProfileGenerator")
            .field("seed", &self.seed)
            .field("dx", &self.dx)
            .field("n", &self.n)
            .field("band", &self.band)
            .field("bins", &self.bins.len())
            .finish()
    }
}

impl ProfileGenerator {
    /// Number of profile points `N` (even).
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false: a profile has at least 4 points.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Spacing (m).
    pub fn dx(&self) -> f64 {
        self.dx
    }

    /// Positions `x_n = x_s + n dx` (m), from the start `x_s` every generated profile has
    /// ([`GENERATED_PROFILE_START`], 0).
    pub fn positions(&self) -> Vec<f64> {
        (0..self.n)
            .map(|i| GENERATED_PROFILE_START + i as f64 * self.dx)
            .collect()
    }

    /// The band `[f_lo, f_hi]` (1/m).
    pub fn band(&self) -> [f64; 2] {
        self.band
    }

    /// The spectrum.
    pub fn psd(&self) -> &Psd {
        &self.psd
    }

    /// Bins with power: `(k, P_k)`, `f_k = k / (N dx)`, `P_k` in mm^2.
    pub fn bins(&self) -> &[(usize, f64)] {
        &self.bins
    }

    /// The exact mean square of every profile, `sum_k P_k`, in m^2.
    pub fn variance(&self) -> f64 {
        self.bins.iter().map(|(_, p)| p).sum::<f64>() * 1e-6
    }

    /// The profile of sample `id`: `eta(x_n)` in metres, positive downward.
    pub fn profile(&self, id: u64) -> Vec<f64> {
        let mut out = vec![0.0; self.n];
        self.profile_into(id, &mut out);
        out
    }

    /// The profiles of samples `ids` (non-negative), one after the other ([`Self::len`] points
    /// each), generated in parallel; `tick` is called after each. Each is [`Self::profile`] of
    /// its id, whatever the thread count.
    pub fn profiles_of(&self, ids: &[i64], tick: &(dyn Fn() + Sync)) -> Vec<f64> {
        let mut eta = vec![0.0; self.n * ids.len()];
        eta.par_chunks_mut(self.n)
            .zip(ids)
            .for_each(|(chunk, &id)| {
                self.profile_into(id as u64, chunk);
                tick();
            });
        eta
    }

    /// One line on `count` profiles `name` of this generator: points, length and spacing, RMS
    /// and wavelength band.
    pub fn describe(&self, name: &str, count: usize) -> String {
        format!(
            "{count} profiles `{name}` x {} points ({:.1} m at dx {} m), RMS {:.3} mm over {}-{} m wavelengths",
            self.n,
            self.n as f64 * self.dx,
            self.dx,
            self.variance().sqrt() * 1e3,
            1.0 / self.band[1],
            1.0 / self.band[0],
        )
    }

    /// Writes the profile of sample `id` into `out` (length [`Self::len`]).
    ///
    /// # Panics
    /// If `out.len() != self.len()`.
    pub fn profile_into(&self, id: u64, out: &mut [f64]) {
        assert_eq!(out.len(), self.n, "profile buffer length");
        let mut stream = SampleStream::with_code(self.seed, self.code, id);
        let mut spectrum = vec![Complex::new(0.0, 0.0); self.n];
        for &(k, power) in &self.bins {
            // Half the cosine amplitude sqrt(2 P_k) on k and on N-k (mm -> m).
            let half = 0.5 * (2.0 * power).sqrt() * 1e-3;
            let phase = 2.0 * PI * stream.uniform();
            let c = Complex::from_polar(half, phase);
            spectrum[k] = c;
            spectrum[self.n - k] = c.conj();
        }
        self.fft.process(&mut spectrum);
        for (o, c) in out.iter_mut().zip(&spectrum) {
            *o = c.re;
        }
    }
}

/// One-sided Welch PSD of `z` sampled every `dx`: Hann windows of `segment_len` points,
/// 50% overlap, each segment's mean removed,
/// `P(f_k) = 2 |FFT(w z)_k|^2 / (fs sum w^2)`, `fs = 1/dx`, `f_k = k fs / segment_len`,
/// `k = 0..=segment_len/2` (no doubling at 0 and at Nyquist). Returns `(f, P)`; `P` in units of
/// `z^2 / (1/m)`.
pub fn welch_psd(z: &[f64], dx: f64, segment_len: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    if segment_len < 4 || segment_len % 2 == 1 {
        return Err(Error::Shape {
            name: "welch segment".to_owned(),
            found: segment_len,
            expected: 4,
        });
    }
    if z.len() < segment_len {
        return Err(Error::Shape {
            name: "welch signal".to_owned(),
            found: z.len(),
            expected: segment_len,
        });
    }
    let m = segment_len;
    // Periodic Hann window: constant sum at 50% overlap.
    let w: Vec<f64> = (0..m)
        .map(|i| 0.5 * (1.0 - (2.0 * PI * i as f64 / m as f64).cos()))
        .collect();
    let w2: f64 = w.iter().map(|x| x * x).sum();
    let fft = FftPlanner::new().plan_fft_forward(m);
    let mut acc = vec![0.0; m / 2 + 1];
    let mut buf = vec![Complex::new(0.0, 0.0); m];
    let step = m / 2;
    let mut count = 0usize;
    let mut start = 0;
    while start + m <= z.len() {
        let seg = &z[start..start + m];
        let mean = seg.iter().sum::<f64>() / m as f64;
        for ((b, x), wi) in buf.iter_mut().zip(seg).zip(&w) {
            *b = Complex::new((x - mean) * wi, 0.0);
        }
        fft.process(&mut buf);
        for (a, b) in acc.iter_mut().zip(&buf) {
            *a += b.norm_sqr();
        }
        count += 1;
        start += step;
    }
    let fs = 1.0 / dx;
    let scale = 1.0 / (fs * w2 * count as f64);
    let p: Vec<f64> = acc
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let one_sided = if k == 0 || k == m / 2 { 1.0 } else { 2.0 };
            one_sided * a * scale
        })
        .collect();
    let f = (0..=m / 2).map(|k| k as f64 * fs / m as f64).collect();
    Ok((f, p))
}

/// Number of Welch segments [`welch_psd`] averages for `len` points.
pub fn welch_segments(len: usize, segment_len: usize) -> usize {
    if len < segment_len {
        0
    } else {
        (len - segment_len) / (segment_len / 2) + 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbd_system::schema::fra::{fra_psd, FraIrregularity};

    /// TB/T 3352-2014, ballastless track, vertical (as in `systems/vtcd.yaml`).
    fn tbt3352() -> Psd {
        Psd::new(vec![
            PsdSegment {
                f_start: 0.0,
                a: 1.0544e-5,
                n: 3.3891,
            },
            PsdSegment {
                f_start: 0.0187,
                a: 3.5588e-3,
                n: 1.9271,
            },
            PsdSegment {
                f_start: 0.0474,
                a: 1.9784e-2,
                n: 1.3643,
            },
            PsdSegment {
                f_start: 0.1533,
                a: 3.9488e-4,
                n: 3.4516,
            },
        ])
        .unwrap()
    }

    /// The profiles of a group of samples are each sample's own profile, in order.
    #[test]
    fn profiles_of_a_group_are_each_samples_profile() {
        let g = generator(7);
        let ids = [0i64, 5, 3];
        let ticks = std::sync::atomic::AtomicUsize::new(0);
        let tick = || {
            ticks.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        };
        let eta = g.profiles_of(&ids, &tick);
        assert_eq!(eta.len(), ids.len() * g.len());
        for (chunk, &id) in eta.chunks(g.len()).zip(&ids) {
            assert_eq!(chunk, g.profile(id as u64).as_slice());
        }
        assert_ne!(&eta[..g.len()], &eta[g.len()..2 * g.len()]);
        assert_eq!(ticks.into_inner(), ids.len());
    }

    /// The description names the count, the points, the length, the spacing and the band.
    #[test]
    fn describe_names_count_points_length_and_band() {
        let g = generator(7);
        let line = g.describe("eta", 12);
        assert!(
            line.starts_with("12 profiles `eta` x 5400 points (540.0 m at dx 0.1 m), RMS "),
            "{line}"
        );
        assert!(line.ends_with(" mm over 2-100 m wavelengths"), "{line}");
    }

    fn generator(seed: u64) -> ProfileGenerator {
        generator_of(tbt3352(), seed)
    }

    /// Profiles of `psd` over 2-100 m wavelengths, 540 m at dx = 0.1 m.
    fn generator_of(psd: Psd, seed: u64) -> ProfileGenerator {
        ProfileParams {
            seed,
            dx: 0.1,
            length: 540.0,
        }
        .generator(psd, [2.0, 100.0], crate::rng::profile_code(0))
        .unwrap()
    }

    #[test]
    fn spectrum_is_continuous_at_the_breaks() {
        // TB/T 3352: continuous to 0.4% at each break (largest jump 0.398% at 0.0187 1/m).
        let psd = tbt3352();
        for j in 1..psd.segments().len() {
            let (l, r) = (psd.segments()[j - 1], psd.segments()[j]);
            let fb = r.f_start;
            let left = l.a * fb.powf(-l.n);
            let right = r.a * fb.powf(-r.n);
            assert!(
                (left / right - 1.0).abs() < 0.004,
                "break {fb}: {left} vs {right}"
            );
            assert_eq!(psd.value(fb), right);
        }
    }

    #[test]
    fn band_integral_is_the_published_value() {
        // 2-100 m wavelengths: 0.3667 mm^2 (4 digits).
        let psd = tbt3352();
        let v = psd.integral(0.01, 0.5);
        assert!((v - 0.3667).abs() < 5e-5, "{v}");
        // Closed form against a fine midpoint rule (relative error ~ (h/f)^2 n^2 / 24 < 1e-7).
        let m = 200_000;
        let h = (0.5 - 0.01) / m as f64;
        let mid: f64 = (0..m)
            .map(|i| psd.value(0.01 + (i as f64 + 0.5) * h) * h)
            .sum();
        assert!((mid / v - 1.0).abs() < 1e-6, "{mid} vs {v}");
    }

    #[test]
    fn every_profile_has_the_exact_variance() {
        let g = generator(3);
        assert_eq!(g.len(), 5400);
        assert!(
            (g.variance() * 1e6 - 0.3667).abs() < 5e-5,
            "{}",
            g.variance() * 1e6
        );
        for id in 0..20 {
            let z = g.profile(id);
            let n = z.len() as f64;
            let mean = z.iter().sum::<f64>() / n;
            let ms = z.iter().map(|x| x * x).sum::<f64>() / n;
            // Round-off of a 5400-point FFT and sum: ~1e-13 relative; 1e-10 is generous.
            assert!(mean.abs() < 1e-10 * g.variance().sqrt(), "mean {mean}");
            assert!((ms / g.variance() - 1.0).abs() < 1e-10, "{ms}");
        }
    }

    #[test]
    fn fft_equals_the_cosine_sum() {
        // The FFT path against the definition eta = sum sqrt(2 P_k) cos(2 pi f_k x + phi_k).
        let g = ProfileParams {
            seed: 9,
            dx: 0.1,
            length: 60.0,
        }
        .generator(tbt3352(), [2.0, 50.0], crate::rng::profile_code(0))
        .unwrap();
        let z = g.profile(1);
        let mut s = SampleStream::with_code(9, crate::rng::profile_code(0), 1);
        let phases: Vec<f64> = g.bins().iter().map(|_| 2.0 * PI * s.uniform()).collect();
        let l = g.len() as f64 * g.dx();
        for (i, zi) in z.iter().enumerate() {
            let x = i as f64 * g.dx();
            let direct: f64 = g
                .bins()
                .iter()
                .zip(&phases)
                .map(|(&(k, pk), ph)| {
                    (2.0 * pk).sqrt() * 1e-3 * (2.0 * PI * k as f64 * x / l + ph).cos()
                })
                .sum();
            assert!(
                (zi - direct).abs() < 1e-12 * g.variance().sqrt() * 100.0,
                "{i}: {zi} {direct}"
            );
        }
    }

    #[test]
    fn welch_of_white_noise_is_flat_and_keeps_the_variance() {
        // White noise of variance s2 sampled every dx has one-sided PSD 2 s2 dx.
        let dx = 0.25;
        let mut s = SampleStream::new(1, crate::rng::Purpose::Irregularity, 1000);
        let z: Vec<f64> = (0..65_536).map(|_| 0.3 * s.normal()).collect();
        let (f, p) = welch_psd(&z, dx, 256).unwrap();
        let k = welch_segments(z.len(), 256) as f64; // 511 averages
        let expect = 2.0 * 0.09 * dx;
        // Each interior bin averages k Hann periodograms: relative std ~ 1.06/sqrt(k) = 4.7%;
        // 5 standard deviations over 127 bins.
        for (fi, pi) in f.iter().zip(&p).skip(1).take(f.len() - 2) {
            assert!(
                (pi / expect - 1.0).abs() < 5.0 * 1.06 / k.sqrt(),
                "f {fi}: {pi} vs {expect}"
            );
        }
        // Parseval: sum P df equals the variance to the same few percent.
        let var: f64 = p.iter().sum::<f64>() * f[1];
        assert!((var / 0.09 - 1.0).abs() < 0.02, "{var}");
        assert!(welch_psd(&z[..100], dx, 256).is_err());
        assert!(welch_psd(&z, dx, 255).is_err());
    }

    #[test]
    fn ensemble_welch_follows_the_spectrum() {
        assert_ensemble_welch_follows_the_spectrum(tbt3352());
    }

    /// The mean Welch estimate of 32 profiles of `psd` over 2-100 m wavelengths follows `psd`
    /// bin by bin.
    fn assert_ensemble_welch_follows_the_spectrum(psd: Psd) {
        // Long profiles (6553.6 m at dx = 0.2 m) so that 819-m Welch windows (resolution
        // 0.0012 1/m) resolve the steep low-frequency end of the band.
        let g = ProfileParams {
            seed: 21,
            dx: 0.2,
            length: 6553.6,
        }
        .generator(psd, [2.0, 100.0], crate::rng::profile_code(0))
        .unwrap();
        let (seg, samples) = (4096, 32);
        let mut mean = vec![0.0; seg / 2 + 1];
        let mut f = Vec::new();
        for id in 0..samples {
            let (fi, p) = welch_psd(&g.profile(id), g.dx(), seg).unwrap();
            for (m, x) in mean.iter_mut().zip(&p) {
                *m += x / samples as f64;
            }
            f = fi;
        }
        // The average of K Hann periodograms of a Gaussian process has relative std about
        // 1/sqrt(K) = 4.6% (K = 32 x 15 = 480); each bin may deviate by 4 of those. Checked
        // from 1.25 f_lo to 0.96 f_hi: closer to the band edges the window's main lobe
        // straddles the edge where S drops to zero.
        let averages = samples as f64 * welch_segments(g.len(), seg) as f64;
        let tol = 4.0 / averages.sqrt();
        let [f_lo, f_hi] = g.band();
        let mut ratios = Vec::new();
        for (fi, p) in f.iter().zip(&mean) {
            if *fi >= 1.25 * f_lo && *fi <= 0.96 * f_hi {
                let r = p / (g.psd().value(*fi) * 1e-6);
                assert!((r - 1.0).abs() < tol, "f {fi}: ratio {r}");
                ratios.push(r);
            }
        }
        assert!(ratios.len() > 350, "{}", ratios.len());
        // The band average has std ~ 1/sqrt(K bins) = 0.2%; 1% covers the window's bias.
        let avg = ratios.iter().sum::<f64>() / ratios.len() as f64;
        assert!((avg - 1.0).abs() < 0.01, "{avg}");
    }

    #[test]
    fn pointwise_ensemble_variance_is_the_band_integral() {
        assert_pointwise_ensemble_variance_is_the_band_integral(&generator(5));
    }

    /// Over 8000 samples of `g`, the mean of `z^2` at three points is the band integral
    /// within 4 standard errors.
    fn assert_pointwise_ensemble_variance_is_the_band_integral(g: &ProfileGenerator) {
        // At a fixed x the value sum_k a_k cos(theta_k) over random phases has variance
        // sigma^2 = sum a_k^2 / 2 and E z^4 = 3 sigma^4 - (3/8) sum a_k^4, which gives the
        // standard error of the ensemble mean of z^2 exactly.
        let m = 8000;
        let points = [0usize, 1234, 4000];
        let mut sums = [0.0; 3];
        for id in 0..m {
            let z = g.profile(id);
            for (s, &i) in sums.iter_mut().zip(&points) {
                *s += z[i] * z[i] / m as f64;
            }
        }
        let sigma2 = g.variance();
        let a4: f64 = g.bins().iter().map(|(_, p)| (2.0 * p * 1e-6).powi(2)).sum();
        let var_z2 = 3.0 * sigma2 * sigma2 - 0.375 * a4 - sigma2 * sigma2;
        let se = (var_z2 / m as f64).sqrt() / sigma2; // 1.5% relative: bound 4 se = 6%
        for (s, i) in sums.iter().zip(points) {
            assert!(
                (s / sigma2 - 1.0).abs() < 4.0 * se,
                "x_{i}: {s} vs {sigma2} (se {se})"
            );
        }
        assert!(se < 0.016, "{se}");
    }

    #[test]
    fn profiles_are_reproducible_and_distinct_per_sample_and_profile() {
        let g = generator(7);
        assert_eq!(g.profile(4), g.profile(4));
        assert_ne!(g.profile(4), g.profile(5));
        let other = ProfileParams {
            seed: 7,
            dx: 0.1,
            length: 540.0,
        }
        .generator(tbt3352(), [2.0, 100.0], crate::rng::profile_code(1))
        .unwrap();
        assert_ne!(g.profile(4), other.profile(4));
    }

    /// An FRA class spectrum as the description gives it.
    fn fra(class: usize, irregularity: FraIrregularity) -> Psd {
        Psd::from_description(&fra_psd(class, irregularity).unwrap()).unwrap()
    }

    #[test]
    fn fra_spectra_in_the_generators_unit_are_the_hand_computed_values() {
        // Class 5 vertical at f = 0.1 cycles/m: Omega = 2 pi 0.1 rad/m, Omega^2 = 0.39478418,
        // Omega_c^2 = 0.8245^2 = 0.67980025; S_v = 0.25 * 0.2095 * 0.67980025 /
        // (0.39478418 * (0.39478418 + 0.67980025)) = 0.035604538 / 0.42422893
        // = 0.083927653 cm^2/(rad/m); S(f) = 2 pi S_v (per cycle/m) * 100 (cm^2 -> mm^2)
        // = 52.733299 mm^2/(1/m).
        let v = fra(5, FraIrregularity::Vertical).value(0.1);
        assert!((v / 52.733299 - 1.0).abs() < 1e-7, "{v}");
        // Class 1 cross-level (Omega_s = 0.6046 below Omega_c): 4 * 0.25 * 1.2107 * 0.67980025
        // / ((0.39478418 + 0.67980025)(0.39478418 + 0.6046^2)) = 1.0073441 cm^2/(rad/m),
        // 632.93298 mm^2/(1/m).
        let c = fra(1, FraIrregularity::CrossLevel).value(0.1);
        assert!((c / 632.93298 - 1.0).abs() < 1e-7, "{c}");
        // Alignment: the vertical form with A_a (class 5: 0.0762 against A_v = 0.2095).
        let a = fra(5, FraIrregularity::Alignment).value(0.1);
        assert!((a / v - 0.0762 / 0.2095).abs() < 1e-12, "{a}");
        assert!(fra_psd(0, FraIrregularity::Vertical).is_none());
        assert!(fra_psd(7, FraIrregularity::Vertical).is_none());
    }

    #[test]
    fn fra_band_integrals_are_the_midpoint_rule_of_the_omega_form() {
        // The closed form (f, mm^2) against a fine midpoint rule of the published form in
        // Omega (cm^2/(rad/m)) over the same band, 2-100 m: the powers are equal,
        // integral S(f) df = 100 integral S(Omega) dOmega. Cross-level class 5 has its two
        // poles 0.4% apart (the partial fractions' hardest case).
        const K: f64 = 0.25;
        const C2: f64 = 0.8245 * 0.8245;
        // (class, irregularity, S(Omega) in cm^2/(rad/m))
        type Form = (usize, FraIrregularity, fn(f64) -> f64);
        let forms: [Form; 3] = [
            (5, FraIrregularity::Vertical, |w| {
                K * 0.2095 * C2 / (w * w * (w * w + C2))
            }),
            (2, FraIrregularity::Alignment, |w| {
                K * 1.2107 * C2 / (w * w * (w * w + C2))
            }),
            (5, FraIrregularity::CrossLevel, |w| {
                4.0 * K * 0.2095 * C2 / ((w * w + C2) * (w * w + 0.8209 * 0.8209))
            }),
        ];
        let (w1, w2) = (2.0 * PI * 0.01, 2.0 * PI * 0.5);
        let m = 400_000;
        let h = (w2 - w1) / m as f64;
        for (class, irregularity, s) in forms {
            let closed = fra(class, irregularity).integral(0.01, 0.5);
            let mid: f64 = (0..m)
                .map(|i| s(w1 + (i as f64 + 0.5) * h) * h)
                .sum::<f64>()
                * 100.0;
            assert!(
                (closed / mid - 1.0).abs() < 1e-6,
                "class {class} {irregularity:?}: {closed} vs {mid}"
            );
        }
    }

    #[test]
    fn fra_profiles_have_the_band_integral_as_mean_square() {
        // Class 5 vertical over 2-100 m: every profile's mean square is the PSD's band
        // integral, exactly (random phases only), and the ensemble at fixed points agrees
        // within the statistical tolerance of the TB/T test.
        let psd = fra(5, FraIrregularity::Vertical);
        let band = psd.integral(0.01, 0.5) * 1e-6;
        let g = generator_of(psd, 5);
        assert!(
            (g.variance() / band - 1.0).abs() < 1e-12,
            "{}",
            g.variance()
        );
        for id in 0..20 {
            let z = g.profile(id);
            let ms = z.iter().map(|x| x * x).sum::<f64>() / z.len() as f64;
            assert!((ms / band - 1.0).abs() < 1e-10, "{ms} vs {band}");
        }
        assert_pointwise_ensemble_variance_is_the_band_integral(&g);
    }

    #[test]
    fn ensemble_welch_follows_the_fra_cross_level_spectrum() {
        assert_ensemble_welch_follows_the_spectrum(fra(5, FraIrregularity::CrossLevel));
    }

    #[test]
    fn two_pole_spectra_are_checked() {
        let msg = |c: f64, p: f64, q: f64| Psd::two_pole(c, p, q).unwrap_err().to_string();
        assert!(msg(-1.0, 0.0, 0.1).contains("c must be finite and > 0"));
        assert!(msg(1.0, -0.1, 0.1).contains("the poles must be finite and >= 0"));
        assert!(msg(1.0, 0.1, f64::INFINITY).contains("the poles must be finite"));
        assert!(msg(1.0, 0.1, 0.10001).contains("must differ by at least"));
        assert!(msg(1.0, 0.0, 0.0).contains("must differ by at least"));
        // Either order of the poles is the same spectrum.
        assert_eq!(
            Psd::two_pole(1.0, 0.2, 0.1).unwrap(),
            Psd::two_pole(1.0, 0.1, 0.2).unwrap()
        );
        assert!(Psd::two_pole(1.0, 0.1, 0.2).unwrap().segments().is_empty());
    }

    #[test]
    fn bad_settings_are_named() {
        let p = ProfileParams {
            seed: 1,
            dx: 0.1,
            length: 540.0,
        };
        let msg = |p: ProfileParams, band: [f64; 2]| {
            p.generator(tbt3352(), band, 2).unwrap_err().to_string()
        };
        assert!(msg(ProfileParams { dx: 0.0, ..p }, [2.0, 100.0]).contains("`dx`"));
        let e = msg(p, [120.0, 100.0]);
        assert!(
            e.contains("wavelengths") && e.contains("< min < max"),
            "{e}"
        );
        // Nyquist wavelength 3 m > 2 m.
        assert!(msg(ProfileParams { dx: 1.5, ..p }, [2.0, 100.0]).contains("2 dx = 3"));
        // Shorter than the 100 m wavelength.
        assert!(msg(ProfileParams { length: 50.0, ..p }, [2.0, 100.0]).contains("<= length = 50"));
        assert!(msg(ProfileParams { length: 1e12, ..p }, [2.0, 100.0])
            .contains("at most 67108864 points"));
        let mut segments = tbt3352().segments().to_vec();
        segments[2].f_start = 0.01;
        assert!(Psd::new(segments.clone())
            .unwrap_err()
            .to_string()
            .contains("segment 2"));
        segments[2].f_start = 0.0474;
        segments[0].a = -1.0;
        assert!(Psd::new(segments)
            .unwrap_err()
            .to_string()
            .contains("a must be finite and > 0"));
    }
}
