//! The rail: a simply supported Euler-Bernoulli beam by modal superposition
//! (`docs/model.md`, Rail).
//!
//! Length `L = N_f s`, fasteners at `x_j = j s` (`j = 0..N_f-1`), modes `k = 1..N_M` with
//! mass-normalised shapes and circular frequencies
//! ```text
//! Y_k(x) = sqrt(2 / (m_r L)) sin(k pi x / L)           (1/sqrt(kg))
//! w_k^2  = (E I / m_r) (k pi / L)^4                     (rad^2/s^2)
//! q_k'' + w_k^2 q_k = - sum_j F_fj Y_k(x_j) + sum_i P_i Y_k(x_wi)
//! Z_r(x) = sum_k Y_k(x) q_k                              (m)
//! ```
//! On the fastener grid `Y_k(x_j) = sqrt(2/(m_r L)) sin(pi j k / N_f)`: both the modal-to-fastener
//! map and its transpose are the DST-I `S_jk = sin(pi j k / N_f)` (`j, k = 1..N_f-1`; `x_0 = 0`
//! is a node of every mode). [`SineTransform`] evaluates it in `O(N_f log N_f)`: for even `N_f`
//! through one complex FFT of length `N_f / 2` (a real FFT of a symmetrised sequence), for odd
//! `N_f` through one complex FFT of length `N_f` (the real FFT of the length-`2 N_f` odd
//! extension), instead of the `O(N_f N_M)` dense product ([`dense_sine_product`], kept as the
//! reference the tests compare against to round-off).

use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::f64::consts::PI;
use std::sync::Arc;

use crate::track::TrackParams;

/// Modal description of the rail.
#[derive(Debug, Clone)]
pub struct Rail {
    /// Rail length `L` (m).
    pub length: f64,
    /// Mode-shape amplitude `sqrt(2 / (m_r L))` (1/sqrt(kg)).
    pub shape_scale: f64,
    /// `w_k^2` for `k = 1..N_M` (index `k - 1`), rad^2/s^2.
    pub omega2: Vec<f64>,
    /// Fastener spacing `s` (m).
    pub spacing: f64,
    /// Number of fasteners `N_f`.
    pub n_f: usize,
}

impl Rail {
    /// The rail of `tp` (assumed validated).
    pub fn new(tp: &TrackParams) -> Self {
        let length = tp.length();
        let c = (tp.ei() / tp.m_r).sqrt();
        let omega2 = (1..=tp.n_m)
            .map(|k| {
                let w = (k as f64 * PI / length).powi(2) * c;
                w * w
            })
            .collect();
        Self {
            length,
            shape_scale: (2.0 / (tp.m_r * length)).sqrt(),
            omega2,
            spacing: tp.s,
            n_f: tp.n_f,
        }
    }

    /// Number of modes `N_M`.
    pub fn n_modes(&self) -> usize {
        self.omega2.len()
    }

    /// Writes `Y_k(x)` for `k = 1..N_M` into `out` (1/sqrt(kg)). The sines come from one
    /// `sin_cos` and a complex rotation per mode, re-seeded exactly every 32 modes so the
    /// rounding error stays below ~1e-14 for any `N_M`.
    pub fn shapes_at(&self, x: f64, out: &mut [f64]) {
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

    /// Mode shapes at the four wheels, interleaved (`shapes[k - 1][i] = Y_k(x_i)`), and the rail
    /// displacement under each, `Z_r(x_i) = sum_k Y_k(x_i) q_k` (m), in one pass: the four
    /// independent rotation recurrences run side by side (SIMD lanes), re-seeded exactly every
    /// 128 modes (rounding error ~128 eps of the amplitude).
    pub fn wheel_shapes(&self, x: &[f64; 4], q: &[f64], shapes: &mut [[f64; 4]]) -> [f64; 4] {
        let theta = x.map(|x| PI * x / self.length);
        let step = theta.map(f64::sin_cos);
        let (s1, c1) = (step.map(|p| p.0), step.map(|p| p.1));
        let mut z = [0.0; 4];
        let n = shapes.len().min(q.len());
        let mut k = 0;
        while k < n {
            let seed = theta.map(|t| ((k + 1) as f64 * t).sin_cos());
            let (mut s, mut c) = (seed.map(|p| p.0), seed.map(|p| p.1));
            let end = (k + 128).min(n);
            for (y, &qk) in shapes[k..end].iter_mut().zip(&q[k..end]) {
                for i in 0..4 {
                    let yi = self.shape_scale * s[i];
                    y[i] = yi;
                    z[i] += yi * qk;
                    (s[i], c[i]) = (s[i] * c1[i] + c[i] * s1[i], c[i] * c1[i] - s[i] * s1[i]);
                }
            }
            k = end;
        }
        z
    }

    /// Rail displacement `Z_r(x) = sum_k Y_k(x) q_k` (m) from precomputed shapes at `x`.
    pub fn displacement(shapes: &[f64], q: &[f64]) -> f64 {
        shapes.iter().zip(q).map(|(y, q)| y * q).sum()
    }

    /// Adds the modal loads of point forces `sum_i P_i Y_k(x_i)` (downward force positive)
    /// to `modal` (N/sqrt(kg)); `shapes[i]` holds `Y_k(x_i)`.
    pub fn add_point_loads(shapes: &[&[f64]], loads: &[f64], modal: &mut [f64]) {
        for (y, &p) in shapes.iter().zip(loads) {
            for (m, y) in modal.iter_mut().zip(y.iter()) {
                *m += p * y;
            }
        }
    }
}

/// The DST-I `out_j = sum_{k=1}^{N-1} u_k sin(pi j k / N)` for `j = 1..N-1`. Even `N` goes
/// through `HalfSize` (complex FFT of length `N/2`); odd `N` as follows (length `N`).
///
/// With `y` the odd extension of `u` to length `2N` (`y_0 = y_N = 0`, `y_{2N-m} = -y_m`), its
/// DFT is `Y_j = -2i out_j`. Packing `z_n = y_{2n} + i y_{2n+1}` (length `N`) and
/// `Z = FFT_N(z)`, the even/odd-sample spectra are `E_j = (Z_j + conj Z_{N-j}) / 2`,
/// `O_j = (Z_j - conj Z_{N-j}) / (2i)`, and `Y_j = E_j + exp(-i pi j / N) O_j`, so
/// `out_j = -Im(Y_j) / 2`.
pub struct SineTransform {
    n: usize,
    fft: Arc<dyn Fft<f64>>,
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
    /// Zero-padded input `u_0..u_N` (`u_0 = u_N = 0`).
    pad: Vec<f64>,
    /// `cos(pi j / N) / 4` and `sin(pi j / N) / 4`, `j = 0..N-1`.
    cos4: Vec<f64>,
    sin4: Vec<f64>,
    /// The faster route for even `N` (see `HalfSize`).
    half: Option<HalfSize>,
}

/// DST-I of even `N` through a real FFT of length `N`, itself one complex FFT of length `N/2`
/// (half the work of the odd-extension route). With the symmetric/antisymmetric split
/// ```text
/// y_0 = 0,  y_j = sin(pi j / N) (u_j + u_{N-j}) + (u_j - u_{N-j}) / 2   (j = 1..N-1)
/// Y_k = sum_j y_j exp(-2 pi i j k / N) = R_k + i I_k
/// ```
/// the symmetric part gives `R_k = F_{2k+1} - F_{2k-1}` (product-to-sum of
/// `2 sin(pi j/N) cos(2 pi j k/N)`) and the antisymmetric part `I_k = -F_{2k}`, so
/// `F_{2k} = -I_k`, `F_1 = R_0 / 2`, `F_{2k+1} = F_{2k-1} + R_k` (a running sum: rounding grows
/// like sqrt(k) eps, tested against the dense product). The real FFT packs
/// `z_n = y_{2n} + i y_{2n+1}` and unpacks `Y_k = E_k + exp(-2 pi i k / N) O_k` as above.
struct HalfSize {
    fft: Arc<dyn Fft<f64>>,
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
    /// `sin(pi j / N)`, `j = 0..N-1`.
    sin_pre: Vec<f64>,
    /// `exp(-2 pi i k / N)`, `k = 0..N/2-1`.
    twiddle: Vec<Complex64>,
    /// Pre-processed sequence `y`, length `N`.
    y: Vec<f64>,
}

impl HalfSize {
    fn new(n: usize) -> Self {
        let h = n / 2;
        let fft = FftPlanner::new().plan_fft_forward(h);
        let scratch = vec![Complex64::new(0.0, 0.0); fft.get_inplace_scratch_len()];
        Self {
            fft,
            buf: vec![Complex64::new(0.0, 0.0); h],
            scratch,
            sin_pre: (0..n).map(|j| (PI * j as f64 / n as f64).sin()).collect(),
            twiddle: (0..h)
                .map(|k| {
                    let (s, c) = (2.0 * PI * k as f64 / n as f64).sin_cos();
                    Complex64::new(c, -s)
                })
                .collect(),
            y: vec![0.0; n],
        }
    }

    /// `pad` is `u_0..u_N` (zero ends); writes `F_1..F_m` into `out` (`m = out.len()`).
    fn apply(&mut self, pad: &[f64], out: &mut [f64]) {
        let n = self.y.len();
        let h = n / 2;
        self.y[0] = 0.0;
        let fwd = pad[1..n].iter();
        let bwd = pad[1..n].iter().rev();
        for ((y, s), (a, b)) in self.y[1..]
            .iter_mut()
            .zip(&self.sin_pre[1..])
            .zip(fwd.zip(bwd))
        {
            *y = s * (a + b) + 0.5 * (a - b);
        }
        for (z, y) in self.buf.iter_mut().zip(self.y.chunks_exact(2)) {
            *z = Complex64::new(y[0], y[1]);
        }
        self.fft
            .process_with_scratch(&mut self.buf, &mut self.scratch);
        let m = out.len();
        if m == 0 {
            return;
        }
        let z = &self.buf;
        // k = 0: E_0 = Re z_0, O_0 = Im z_0, so R_0 = Re z_0 + Im z_0 and F_1 = R_0 / 2.
        let mut odd = 0.5 * (z[0].re + z[0].im);
        out[0] = odd;
        // k >= 1 (k <= m/2 <= N/2 - 1): Y_k from Z_k and conj Z_{N/2-k}; F_{2k} = -I_k,
        // F_{2k+1} = F_{2k-1} + R_k.
        let kmax = m / 2;
        let half = Complex64::new(0.0, -0.5);
        for k in 1..=kmax {
            let (a, b) = (z[k], z[h - k].conj());
            let yk = (a + b) * 0.5 + self.twiddle[k] * ((a - b) * half);
            out[2 * k - 1] = -yk.im;
            odd += yk.re;
            if 2 * k < m {
                out[2 * k] = odd;
            }
        }
    }
}

impl std::fmt::Debug for SineTransform {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SineTransform").field("n", &self.n).finish()
    }
}

impl Clone for SineTransform {
    fn clone(&self) -> Self {
        Self::new(self.n)
    }
}

impl SineTransform {
    /// A transform for `N = n` (`n >= 2`; inputs and outputs have up to `n - 1` entries).
    pub fn new(n: usize) -> Self {
        assert!(n >= 2, "DST-I needs N >= 2");
        let fft = FftPlanner::new().plan_fft_forward(n);
        let scratch = vec![Complex64::new(0.0, 0.0); fft.get_inplace_scratch_len()];
        let angle = |j: usize| PI * j as f64 / n as f64;
        Self {
            n,
            fft,
            buf: vec![Complex64::new(0.0, 0.0); n],
            scratch,
            pad: vec![0.0; n + 1],
            cos4: (0..n).map(|j| 0.25 * angle(j).cos()).collect(),
            sin4: (0..n).map(|j| 0.25 * angle(j).sin()).collect(),
            half: (n & 1 == 0).then(|| HalfSize::new(n)),
        }
    }

    /// `N` of this transform.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false (`N >= 2`).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// `out[j-1] = sum_k input[k-1] sin(pi j k / N)` for `j = 1..=out.len()`. `input` holds
    /// `u_1..u_m` (`m <= N-1`, the rest is zero); `out.len() <= N - 1`.
    pub fn apply(&mut self, input: &[f64], out: &mut [f64]) {
        let n = self.n;
        assert!(
            input.len() < n && out.len() < n,
            "DST-I of N = {n}: at most N - 1 values"
        );
        // u_pad[m] = u_m for 0 <= m <= N (u_0 = u_N = 0, zeros past the input); the odd
        // extension is y_m = u_pad[m] for m <= N and y_m = -u_pad[2N - m] for m > N.
        self.pad[1..=input.len()].copy_from_slice(input);
        self.pad[input.len() + 1..].fill(0.0);
        if let Some(half) = &mut self.half {
            half.apply(&self.pad, out);
            return;
        }
        // z_i = y_{2i} + i y_{2i+1}: for i < ceil(N/2) both indices are <= N (the head);
        // for the rest, with m = N - 1 - i, z_i = -(u_pad[2m+2] + i u_pad[2m+1]).
        let head = n.div_ceil(2);
        let (first, rest) = self.buf.split_at_mut(head);
        for (z, u) in first.iter_mut().zip(self.pad.chunks_exact(2)) {
            *z = Complex64::new(u[0], u[1]);
        }
        let mirrored = self.pad[1..].chunks_exact(2).take(n - head).rev();
        for (z, u) in rest.iter_mut().zip(mirrored) {
            *z = Complex64::new(-u[1], -u[0]);
        }
        self.fft
            .process_with_scratch(&mut self.buf, &mut self.scratch);
        // out_j = -Im(E_j + e^{-i pi j/N} O_j) / 2, written out in real arithmetic:
        // 4 out_j = cos_j (Z_j.re - Z_{N-j}.re) + sin_j (Z_j.im + Z_{N-j}.im)
        //           - (Z_j.im - Z_{N-j}.im).
        let m = out.len();
        let z = &self.buf;
        let up = z[1..=m].iter().zip(z[n - m..].iter().rev());
        let trig = self.cos4[1..=m].iter().zip(&self.sin4[1..=m]);
        for ((o, (a, b)), (c, s)) in out.iter_mut().zip(up).zip(trig) {
            *o = c * (a.re - b.re) + s * (a.im + b.im) - 0.25 * (a.im - b.im);
        }
    }
}

/// Reference dense product `out_j = sum_k input_k sin(pi j k / N)` (1-based `j`, `k`), with the
/// angle reduced exactly modulo `2N` before the sine. `O(N M)`; used by tests.
pub fn dense_sine_product(n: usize, input: &[f64], out: &mut [f64]) {
    for (j, o) in out.iter_mut().enumerate() {
        let j = j + 1;
        *o = input
            .iter()
            .enumerate()
            .map(|(k, u)| {
                let m = (j * (k + 1)) % (2 * n);
                u * (PI * m as f64 / n as f64).sin()
            })
            .sum();
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // matrix loops read best with indices
mod tests {
    use super::*;

    fn pseudo_random(len: usize, seed: u64) -> Vec<f64> {
        let mut s = crate::rng::SampleStream::new(seed, crate::rng::Purpose::Training, 99);
        (0..len).map(|_| s.uniform_in(-1.0, 1.0)).collect()
    }

    /// The FFT route equals the dense product to round-off, for the paper's N_f = 900 with
    /// N_M = 450 inputs (modal -> fasteners), full-length inputs with truncated outputs
    /// (fasteners -> modes), and odd and prime sizes (other FFT code paths).
    #[test]
    fn sine_transform_equals_dense_product() {
        for (n, m_in, m_out) in [
            (900, 450, 899),
            (900, 899, 450),
            (2, 1, 1),
            (7, 6, 3),
            (97, 40, 96),
            (64, 63, 63),
        ] {
            let input = pseudo_random(m_in, n as u64);
            let (mut fast, mut dense) = (vec![0.0; m_out], vec![0.0; m_out]);
            SineTransform::new(n).apply(&input, &mut fast);
            dense_sine_product(n, &input, &mut dense);
            let scale = dense.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            let err = fast
                .iter()
                .zip(&dense)
                .fold(0.0f64, |a, (f, d)| a.max((f - d).abs()));
            // Both sides round at ~eps * (log2 N for the FFT, sqrt(N) for the sum) times the
            // input norm; 1e-13 of the output scale is ~500 eps: round-off, not an error.
            assert!(
                err <= 1e-13 * scale.max(1.0),
                "N={n}: error {err:e} vs scale {scale:e}"
            );
        }
    }

    /// Discrete sine orthogonality: sum_j Y_k(x_j) Y_h(x_j) = delta_kh / (m_r s), i.e. the
    /// transform applied twice is (N/2) times the identity.
    #[test]
    fn discrete_orthogonality() {
        let tp = TrackParams {
            n_f: 60,
            n_m: 30,
            ..Default::default()
        };
        let rail = Rail::new(&tp);
        let mut shapes = vec![0.0; tp.n_m];
        let mut gram = vec![vec![0.0; tp.n_m]; tp.n_m];
        for j in 0..tp.n_f {
            rail.shapes_at(j as f64 * tp.s, &mut shapes);
            for k in 0..tp.n_m {
                for h in 0..tp.n_m {
                    gram[k][h] += shapes[k] * shapes[h];
                }
            }
        }
        let expect = 1.0 / (tp.m_r * tp.s);
        for k in 0..tp.n_m {
            for h in 0..tp.n_m {
                let want = if k == h { expect } else { 0.0 };
                assert!((gram[k][h] - want).abs() < 1e-12 * expect, "({k},{h})");
            }
        }
    }

    #[test]
    fn shapes_match_direct_sines_and_frequencies_the_beam_formula() {
        let tp = TrackParams::default();
        let rail = Rail::new(&tp);
        let mut y = vec![0.0; tp.n_m];
        for x in [0.3, 20.0, 271.7, 539.9] {
            rail.shapes_at(x, &mut y);
            for (k, yk) in y.iter().enumerate() {
                let exact = rail.shape_scale * ((k + 1) as f64 * PI * x / rail.length).sin();
                // The angle k pi x / L reaches ~800 rad, whose last bit is 1.1e-13: both sides
                // carry that much; the 32-mode rotation adds ~32 eps. 1e-12 is 10x above both.
                assert!(
                    (yk - exact).abs() < 1e-12 * rail.shape_scale,
                    "x={x} k={}",
                    k + 1
                );
            }
        }
        // The fused four-wheel evaluation gives the same shapes and Z_r = sum_k Y_k q_k.
        let xs = [30.3, 100.0, 255.5, 539.0];
        let q: Vec<f64> = (0..tp.n_m).map(|k| 1.0 / (1.0 + k as f64)).collect();
        let mut fused = vec![[0.0; 4]; tp.n_m];
        let z = rail.wheel_shapes(&xs, &q, &mut fused);
        for (i, &x) in xs.iter().enumerate() {
            rail.shapes_at(x, &mut y);
            for k in 0..tp.n_m {
                // 128-mode rotation runs: ~128 eps plus the angle's last bit (see above).
                assert!((fused[k][i] - y[k]).abs() < 1e-12 * rail.shape_scale);
            }
            let direct = Rail::displacement(&y, &q);
            assert!(
                (z[i] - direct).abs() < 1e-12 * rail.shape_scale * 10.0,
                "{} vs {direct}",
                z[i]
            );
        }
        // w_1 = (pi/L)^2 sqrt(EI/m_r) for L = 540 m: 3.3846e-5 * 330.5 = 0.011187 rad/s.
        let w1 = rail.omega2[0].sqrt();
        let expect = (PI / 540.0f64).powi(2) * (2.059e11 * 3.217e-5 / 60.64f64).sqrt();
        assert!((w1 - expect).abs() < 1e-12 * expect);
        assert!((rail.omega2[449] / rail.omega2[0] - 450f64.powi(4)).abs() < 1e-6 * 450f64.powi(4));
    }
}
