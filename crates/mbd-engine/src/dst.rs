//! The discrete sine transform that couples a modal beam to uniformly spaced supports.
//!
//! On a beam of length `L = N s` with supports at `x_j = j s` (`j = 0..N-1`), the mode shapes
//! `sin(k pi x_j / L) = sin(pi j k / N)` form the DST-I matrix `S_jk` (`j, k = 1..N-1`;
//! `x_0 = 0` is a node of every mode). Both the modal-to-support map and its transpose are
//! `S`, evaluated by [`SineTransform`] in `O(N log N)` instead of the `O(N N_M)` dense product
//! ([`dense_sine_product`], the reference the tests compare against to round-off). This is the
//! structure the engine's fast path for periodic supports rests on.

use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::f64::consts::PI;
use std::sync::Arc;

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
mod tests {
    use super::*;

    fn pseudo_random(len: usize, seed: u64) -> Vec<f64> {
        // A small LCG: deterministic inputs for a round-off comparison.
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..len)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    /// The FFT route equals the dense product to round-off, for the paper's N = 900 with 450
    /// inputs (modal -> supports), full-length inputs with truncated outputs (supports ->
    /// modes), and odd and prime sizes (the other FFT code paths).
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
            // Both round at ~eps (log2 N for the FFT, sqrt(N) for the sum) times the input norm;
            // 1e-13 of the output scale is ~500 eps.
            assert!(
                err <= 1e-13 * scale.max(1.0),
                "N={n}: error {err:e} vs scale {scale:e}"
            );
        }
    }
}
