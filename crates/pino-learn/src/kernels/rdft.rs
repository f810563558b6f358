//! The truncated real DFT of the spectral convolution, two real rows per complex FFT.
//!
//! For a real row `x` of length `T` and `M < T/2` kept modes (`theta_mt = 2 pi m t / T`):
//! ```text
//! analysis   X_m = sum_t x_t e^{-i theta_mt}                    m = 0..M-1
//! synthesis  y_t = sum_m w_m Re( Y_m e^{+i theta_mt} )          (per-mode weights w_m)
//! ```
//! The spectral convolution synthesises with `w_0 = 1/T, w_m = 2/T` (the inverse of the
//! analysis on band-limited signals); its adjoint with `w_m = 1`.
//!
//! Two real rows `a, b` share one complex FFT of `z = a + i b`: with `Z = FFT(z)`,
//! `A_k = (Z_k + conj Z_{T-k}) / 2` and `B_k = (Z_k - conj Z_{T-k}) / 2i`. Synthesis builds the
//! Hermitian spectra of both rows (`A'_k = w_k A_k / 2`, `A'_{T-k} = conj A'_k`, `A'_0 =
//! w_0 Re A_0`) into `Z = A' + i B'` and one unnormalised inverse FFT returns `a + i b`.
//! Work per row is `O(T log T)` whatever `M` is (the dense-basis product costs `4 M T`).

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// Planned forward and inverse complex FFTs of one length, with the analysis/synthesis of
/// real row pairs on the lowest `modes` modes.
#[derive(Clone)]
pub struct RealDft {
    t: usize,
    modes: usize,
    forward: Arc<dyn Fft<f32>>,
    inverse: Arc<dyn Fft<f32>>,
    scratch_len: usize,
}

impl std::fmt::Debug for RealDft {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RealDft {{ t: {}, modes: {} }}", self.t, self.modes)
    }
}

/// Per-thread work space of a [`RealDft`].
pub struct Workspace {
    buf: Vec<Complex<f32>>,
    scratch: Vec<Complex<f32>>,
}

impl RealDft {
    /// Plans length `t` with `modes` kept modes (`1 <= modes`, `2 modes <= t`).
    pub fn new(t: usize, modes: usize) -> Self {
        assert!(
            modes >= 1 && 2 * modes <= t,
            "RealDft: modes {modes}, t {t}"
        );
        let mut planner = FftPlanner::new();
        let forward = planner.plan_fft_forward(t);
        let inverse = planner.plan_fft_inverse(t);
        let scratch_len = forward
            .get_inplace_scratch_len()
            .max(inverse.get_inplace_scratch_len());
        Self {
            t,
            modes,
            forward,
            inverse,
            scratch_len,
        }
    }

    /// Row length `T`.
    pub fn len(&self) -> usize {
        self.t
    }

    /// Always false (a plan has at least two points).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Kept modes `M`.
    pub fn modes(&self) -> usize {
        self.modes
    }

    /// A work space for one thread.
    pub fn workspace(&self) -> Workspace {
        Workspace {
            buf: vec![Complex::default(); self.t],
            scratch: vec![Complex::default(); self.scratch_len],
        }
    }

    /// Analysis of rows `a` and `b` (`b` may be absent = zeros) into `out_a`, `out_b`
    /// (`M` modes each).
    pub fn analyse_pair(
        &self,
        a: &[f32],
        b: Option<&[f32]>,
        out_a: &mut [Complex<f32>],
        out_b: &mut [Complex<f32>],
        ws: &mut Workspace,
    ) {
        let t = self.t;
        match b {
            Some(b) => {
                for ((z, &re), &im) in ws.buf.iter_mut().zip(a).zip(b) {
                    *z = Complex::new(re, im);
                }
            }
            None => {
                for (z, &re) in ws.buf.iter_mut().zip(a) {
                    *z = Complex::new(re, 0.0);
                }
            }
        }
        self.forward
            .process_with_scratch(&mut ws.buf, &mut ws.scratch);
        let z = &ws.buf;
        for k in 0..self.modes {
            let zk = z[k];
            let zc = z[(t - k) % t].conj();
            out_a[k] = (zk + zc) * 0.5;
            // (zk - zc) / (2i) = (zk - zc) * (-i / 2)
            let d = zk - zc;
            out_b[k] = Complex::new(d.im * 0.5, -d.re * 0.5);
        }
    }

    /// Synthesis of two rows from their modes with per-mode weights `w` into `out_a`, `out_b`
    /// (`out_b` absent: `ya`'s row only, `yb` ignored).
    pub fn synthesise_pair(
        &self,
        ya: &[Complex<f32>],
        yb: &[Complex<f32>],
        w: &[f32],
        out_a: &mut [f32],
        out_b: Option<&mut [f32]>,
        ws: &mut Workspace,
    ) {
        let t = self.t;
        let pair = out_b.is_some();
        ws.buf.fill(Complex::default());
        for k in 0..self.modes {
            let (ha, hb) = if k == 0 {
                (
                    Complex::new(w[0] * ya[0].re, 0.0),
                    if pair {
                        Complex::new(w[0] * yb[0].re, 0.0)
                    } else {
                        Complex::default()
                    },
                )
            } else {
                (
                    ya[k] * (0.5 * w[k]),
                    if pair {
                        yb[k] * (0.5 * w[k])
                    } else {
                        Complex::default()
                    },
                )
            };
            // Z_k += A'_k + i B'_k
            ws.buf[k] += Complex::new(ha.re - hb.im, ha.im + hb.re);
            if k > 0 {
                // Z_{T-k} += conj A'_k + i conj B'_k
                ws.buf[t - k] += Complex::new(ha.re + hb.im, -ha.im + hb.re);
            }
        }
        self.inverse
            .process_with_scratch(&mut ws.buf, &mut ws.scratch);
        for (o, z) in out_a.iter_mut().zip(&ws.buf) {
            *o = z.re;
        }
        if let Some(out_b) = out_b {
            for (o, z) in out_b.iter_mut().zip(&ws.buf) {
                *o = z.im;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn row(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 40) as f64 / (1u64 << 24) as f64 * 2.0 - 1.0) as f32
            })
            .collect()
    }

    /// Direct sums in f64 against the paired FFT, for analysis and weighted synthesis,
    /// including the `2M = T` edge where mode `T/2` is its own mirror.
    #[test]
    fn paired_transforms_match_direct_sums() {
        for (t, m) in [(30usize, 7usize), (45, 11), (16, 8)] {
            let dft = RealDft::new(t, m);
            let mut ws = dft.workspace();
            let (a, b) = (row(t, 1), row(t, 2));
            let mut xa = vec![Complex::default(); m];
            let mut xb = vec![Complex::default(); m];
            dft.analyse_pair(&a, Some(&b), &mut xa, &mut xb, &mut ws);
            for k in 0..m {
                for (x, got) in [(&a, xa[k]), (&b, xb[k])] {
                    let (mut re, mut im) = (0.0f64, 0.0f64);
                    for (n, &v) in x.iter().enumerate() {
                        let th = 2.0 * PI * (k * n) as f64 / t as f64;
                        re += v as f64 * th.cos();
                        im -= v as f64 * th.sin();
                    }
                    assert!((got.re as f64 - re).abs() < 1e-4, "t {t} k {k}");
                    assert!((got.im as f64 - im).abs() < 1e-4, "t {t} k {k}");
                }
            }
            let w: Vec<f32> = (0..m).map(|k| 0.3 + k as f32).collect();
            let mut ya = vec![0.0f32; t];
            let mut yb = vec![0.0f32; t];
            dft.synthesise_pair(&xa, &xb, &w, &mut ya, Some(&mut yb), &mut ws);
            let mut ya_alone = vec![0.0f32; t];
            dft.synthesise_pair(&xa, &[], &w, &mut ya_alone, None, &mut ws);
            for n in 0..t {
                for (spec, got) in [(&xa, ya[n]), (&xb, yb[n]), (&xa, ya_alone[n])] {
                    let mut y = 0.0f64;
                    for k in 0..m {
                        let th = 2.0 * PI * (k * n) as f64 / t as f64;
                        let s = spec[k];
                        y += w[k] as f64 * (s.re as f64 * th.cos() - s.im as f64 * th.sin());
                    }
                    assert!(
                        (got as f64 - y).abs() < 1e-3 * (1.0 + y.abs()),
                        "t {t} n {n}"
                    );
                }
            }
        }
    }
}
