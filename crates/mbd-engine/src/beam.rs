//! A simply supported Euler-Bernoulli beam by modal superposition.
//!
//! Length `L`, mass per length `mu`, bending stiffness `EI`, modes `k = 1..N_M` with
//! mass-normalised shapes and circular frequencies
//! ```text
//! Y_k(x) = sqrt(2 / (mu L)) sin(k pi x / L)        (1/sqrt(kg))
//! w_k^2  = (EI / mu) (k pi / L)^4                  (rad^2/s^2)
//! q_k'' + 2 zeta w_k q_k' + w_k^2 q_k = sum_i F_i Y_k(x_i)      (F_i downward point forces)
//! w(x, t) = sum_k Y_k(x) q_k(t)                    (m, positive downward)
//! ```
//! `zeta` the modal damping ratio (0 unless given). A point off the beam (`x < 0` or `x > L`)
//! has zero shapes: it neither moves the beam nor is moved by it.

use std::f64::consts::PI;

/// A beam's modal data.
#[derive(Debug, Clone)]
pub struct ModalBeam {
    /// Length `L` (m).
    pub length: f64,
    /// Shape amplitude `sqrt(2 / (mu L))` (1/sqrt(kg)).
    pub shape_scale: f64,
    /// `w_k^2`, index `k - 1` (rad^2/s^2).
    pub omega2: Vec<f64>,
    /// `2 zeta w_k` (1/s); empty without modal damping.
    pub damping: Vec<f64>,
}

/// Points evaluated side by side (SIMD lanes).
pub const LANES: usize = 4;

impl ModalBeam {
    /// The beam of length `length`, mass per length `mu`, bending stiffness `ei`, `modes`
    /// modes and damping ratio `zeta`.
    pub fn new(length: f64, mu: f64, ei: f64, modes: usize, zeta: f64) -> Self {
        let c = (ei / mu).sqrt();
        let omega2: Vec<f64> = (1..=modes)
            .map(|k| {
                let w = (k as f64 * PI / length).powi(2) * c;
                w * w
            })
            .collect();
        let damping = if zeta > 0.0 {
            omega2.iter().map(|w2| 2.0 * zeta * w2.sqrt()).collect()
        } else {
            Vec::new()
        };
        Self {
            length,
            shape_scale: (2.0 / (mu * length)).sqrt(),
            omega2,
            damping,
        }
    }

    /// Number of modes.
    pub fn modes(&self) -> usize {
        self.omega2.len()
    }

    /// Whether `x` lies on the beam.
    #[inline]
    pub fn contains(&self, x: f64) -> bool {
        (0.0..=self.length).contains(&x)
    }

    /// Writes `Y_k(x)`, `k = 1..N_M`, into `out` (zero off the beam). The sines come from one
    /// `sin_cos` and a rotation per mode, re-seeded exactly every 32 modes (rounding below
    /// ~1e-14 for any `N_M`).
    pub fn shapes_at(&self, x: f64, out: &mut [f64]) {
        if !self.contains(x) {
            out.fill(0.0);
            return;
        }
        let theta = PI * x / self.length;
        let (s1, c1) = theta.sin_cos();
        let mut k = 0;
        while k < out.len() {
            let (mut s, mut c) = ((k + 1) as f64 * theta).sin_cos();
            let end = (k + 32).min(out.len());
            for o in &mut out[k..end] {
                *o = self.shape_scale * s;
                (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
            }
            k = end;
        }
    }

    /// Shapes at up to [`LANES`] points side by side (`shapes[k - 1][i] = Y_k(x_i)`) and the
    /// deflection under each, `w(x_i) = sum_k Y_k(x_i) q_k`, in one pass: independent rotation
    /// recurrences in the lanes, re-seeded exactly every 128 modes (~128 eps of the amplitude).
    /// Lanes at or beyond `n` (and points off the beam) get zero shapes.
    pub fn lane_shapes(
        &self,
        x: &[f64; LANES],
        n: usize,
        q: &[f64],
        shapes: &mut [[f64; LANES]],
    ) -> [f64; LANES] {
        let on: [bool; LANES] = std::array::from_fn(|i| i < n && self.contains(x[i]));
        let theta = x.map(|x| PI * x / self.length);
        let step = theta.map(f64::sin_cos);
        let (s1, c1) = (step.map(|p| p.0), step.map(|p| p.1));
        let scale: [f64; LANES] =
            std::array::from_fn(|i| if on[i] { self.shape_scale } else { 0.0 });
        let mut z = [0.0; LANES];
        let m = shapes.len().min(q.len());
        let mut k = 0;
        while k < m {
            let seed = theta.map(|t| ((k + 1) as f64 * t).sin_cos());
            let (mut s, mut c) = (seed.map(|p| p.0), seed.map(|p| p.1));
            let end = (k + 128).min(m);
            for (y, &qk) in shapes[k..end].iter_mut().zip(&q[k..end]) {
                for i in 0..LANES {
                    let yi = scale[i] * s[i];
                    y[i] = yi;
                    z[i] += yi * qk;
                    (s[i], c[i]) = (s[i] * c1[i] + c[i] * s1[i], c[i] * c1[i] - s[i] * s1[i]);
                }
            }
            k = end;
        }
        z
    }

    /// The deflection under each of [`LANES`] points from their shapes already computed
    /// (`shapes[k - 1][i] = Y_k(x_i)`, by [`ModalBeam::lane_shapes`] for another beam with the
    /// same modes and points), summed in mode order as `lane_shapes` sums it.
    /// The lanes are one AVX register where the CPU has it (a run-time switch; the portable
    /// build targets SSE2): the same products and sums, so the same values to the bit.
    pub fn lane_deflection(shapes: &[[f64; LANES]], q: &[f64]) -> [f64; LANES] {
        #[inline(always)]
        fn body(shapes: &[[f64; LANES]], q: &[f64]) -> [f64; LANES] {
            let mut z = [0.0; LANES];
            for (y, &qk) in shapes.iter().zip(q) {
                for i in 0..LANES {
                    z[i] += y[i] * qk;
                }
            }
            z
        }
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx")]
            unsafe fn wide(shapes: &[[f64; LANES]], q: &[f64]) -> [f64; LANES] {
                body(shapes, q)
            }
            if std::arch::is_x86_feature_detected!("avx") {
                // SAFETY: the CPU supports the feature `wide` was compiled for.
                return unsafe { wide(shapes, q) };
            }
        }
        body(shapes, q)
    }

    /// As [`ModalBeam::lane_shapes`], with the velocity of each point along its path: the
    /// beam's `w_t = sum_k Y_k q_k'` plus `speed w_x`, `w_x = sum_k Y_k' q_k` (the total
    /// derivative of the deflection under a point moving at `speed`).
    pub fn lane_shapes_moving(
        &self,
        x: &[f64; LANES],
        n: usize,
        speed: f64,
        q: &[f64],
        qd: &[f64],
        shapes: &mut [[f64; LANES]],
    ) -> ([f64; LANES], [f64; LANES]) {
        let w = self.lane_shapes(x, n, q, shapes);
        let mut rate = [0.0; LANES];
        for (y, &qdk) in shapes.iter().zip(qd) {
            for i in 0..LANES {
                rate[i] += y[i] * qdk;
            }
        }
        if speed != 0.0 {
            // w_x = sum_k scale (k pi / L) cos(k pi x / L) q_k, by the same rotation.
            for i in 0..n.min(LANES) {
                if !self.contains(x[i]) {
                    continue;
                }
                let theta = PI * x[i] / self.length;
                let (s1, c1) = theta.sin_cos();
                let mut slope = 0.0;
                let mut k = 0;
                while k < q.len() {
                    let (mut s, mut c) = ((k + 1) as f64 * theta).sin_cos();
                    let end = (k + 32).min(q.len());
                    for (j, &qk) in q[k..end].iter().enumerate() {
                        slope +=
                            self.shape_scale * ((k + j + 1) as f64 * PI / self.length) * c * qk;
                        (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
                    }
                    k = end;
                }
                rate[i] += speed * slope;
            }
        }
        (w, rate)
    }

    /// `sum_k Y_k q_k` from shapes at one point.
    pub fn deflection(shapes: &[f64], q: &[f64]) -> f64 {
        shapes.iter().zip(q).map(|(y, q)| y * q).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A second beam's deflections from the first one's shapes (the run-time switch's wide
    /// path on a CPU with AVX) equal `lane_shapes`' own sums to the bit, for full and partial
    /// lanes of points.
    #[test]
    fn shared_shapes_give_lane_shapes_deflections_to_the_bit() {
        let beam = ModalBeam::new(540.0, 60.64, 2.059e11 * 3.217e-5, 450, 0.0);
        let q: Vec<f64> = (0..450)
            .map(|k| 1e-4 * ((k * 7 % 13) as f64 - 6.0) / (1.0 + k as f64))
            .collect();
        for n in [4, 3] {
            let x = [20.0, 37.5, 197.3, 214.8];
            let mut shapes = vec![[0.0; LANES]; 450];
            let w = beam.lane_shapes(&x, n, &q, &mut shapes);
            let shared = ModalBeam::lane_deflection(&shapes, &q);
            assert_eq!(w.map(f64::to_bits), shared.map(f64::to_bits), "{n} points");
            assert!(w[0] != 0.0 && (n == 4 || w[3] == 0.0));
        }
    }

    #[test]
    fn shapes_match_direct_sines_and_frequencies_the_beam_formula() {
        let beam = ModalBeam::new(540.0, 60.64, 2.059e11 * 3.217e-5, 450, 0.0);
        let mut y = vec![0.0; 450];
        for x in [0.3, 20.0, 271.7, 539.9] {
            beam.shapes_at(x, &mut y);
            for (k, yk) in y.iter().enumerate() {
                let exact = beam.shape_scale * ((k + 1) as f64 * PI * x / beam.length).sin();
                // The angle reaches ~800 rad (last bit 1.1e-13); the rotation adds ~32 eps.
                assert!(
                    (yk - exact).abs() < 1e-12 * beam.shape_scale,
                    "x={x} k={}",
                    k + 1
                );
            }
        }
        let xs = [30.3, 100.0, 255.5, 539.0];
        let q: Vec<f64> = (0..450).map(|k| 1.0 / (1.0 + k as f64)).collect();
        let mut lanes = vec![[0.0; LANES]; 450];
        let z = beam.lane_shapes(&xs, 4, &q, &mut lanes);
        for (i, &x) in xs.iter().enumerate() {
            beam.shapes_at(x, &mut y);
            for k in 0..450 {
                assert!((lanes[k][i] - y[k]).abs() < 1e-12 * beam.shape_scale);
            }
            let direct = ModalBeam::deflection(&y, &q);
            assert!(
                (z[i] - direct).abs() < 1e-11 * beam.shape_scale,
                "{} vs {direct}",
                z[i]
            );
        }
        // Off the beam: nothing.
        beam.shapes_at(-1.0, &mut y);
        assert!(y.iter().all(|v| *v == 0.0));
        let w1 = beam.omega2[0].sqrt();
        let expect = (PI / 540.0f64).powi(2) * (2.059e11 * 3.217e-5 / 60.64f64).sqrt();
        assert!((w1 - expect).abs() < 1e-12 * expect);
    }

    /// The slope term of a moving point equals the difference quotient of the deflection.
    #[test]
    fn moving_point_rate_is_the_total_derivative() {
        let beam = ModalBeam::new(25.0, 2303.0, 2.87e9 * 2.9, 20, 0.02);
        let q: Vec<f64> = (0..20).map(|k| 1e-3 / (1.0 + k as f64).powi(2)).collect();
        let qd = vec![0.0; 20];
        let (x, v) = (7.3, 27.0);
        let mut lanes = vec![[0.0; LANES]; 20];
        let (_, rate) = beam.lane_shapes_moving(&[x, 0.0, 0.0, 0.0], 1, v, &q, &qd, &mut lanes);
        let h = 1e-6;
        let w = |x: f64| {
            let mut y = vec![0.0; 20];
            beam.shapes_at(x, &mut y);
            ModalBeam::deflection(&y, &q)
        };
        let fd = v * (w(x + h) - w(x - h)) / (2.0 * h);
        assert!(
            (rate[0] - fd).abs() < 1e-6 * fd.abs(),
            "{} vs {fd}",
            rate[0]
        );
    }
}
