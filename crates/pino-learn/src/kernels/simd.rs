//! Inner loops of the fused kernels, written so the compiler vectorises them, and compiled
//! again for AVX2 + FMA and for AVX-512 with a run-time switch (the portable build targets
//! SSE2 only).
//!
//! GELU is the tanh form used throughout the project (candle's `gelu`):
//! `gelu(z) = z/2 (1 + tanh(u))`, `u = sqrt(2/pi) (z + 0.044715 z^3)`, with `tanh` from
//! `exp(-2|u|)` evaluated branch-free (Cody-Waite reduction by `ln 2`, degree-6 Taylor
//! polynomial on `|r| <= ln2/2`, exponent set in the bits): about 2e-7 absolute error, so
//! results match candle's `gelu` to f32 round-off.

/// Declares `pub fn $name(args)` that runs `$body` compiled for AVX2+FMA when the CPU has
/// them, and for the portable target otherwise.
macro_rules! dispatch {
    ($(#[$doc:meta])* fn $name:ident($($arg:ident : $ty:ty),*) $(-> $ret:ty)? $body:block) => {
        $(#[$doc])*
        pub fn $name($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn body($($arg: $ty),*) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
                unsafe fn widest($($arg: $ty),*) $(-> $ret)? { body($($arg),*) }
                #[target_feature(enable = "avx2,fma")]
                unsafe fn wide($($arg: $ty),*) $(-> $ret)? { body($($arg),*) }
                if std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                {
                    // SAFETY: the CPU supports the features `widest` was compiled for.
                    return unsafe { widest($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: the CPU supports the features `wide` was compiled for.
                    return unsafe { wide($($arg),*) };
                }
            }
            body($($arg),*)
        }
    };
}

const SQRT_2_OVER_PI: f32 = 0.797_884_6;
const GELU_CUBIC: f32 = 0.044_715;

/// `exp(x)` for `x <= 0` (clamped at -87, where it underflows f32's normal range).
#[inline(always)]
fn exp_nonpositive(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    const ROUND: f32 = 12_582_912.0; // 1.5 * 2^23: adding and subtracting rounds to integer
    let x = if x < -87.0 { -87.0 } else { x };
    let shifted = x * LOG2E + ROUND;
    let n = shifted - ROUND;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0))))));
    // `shifted + 127` holds the integer n + 127 (in 1..=127) in its low mantissa bits; moved
    // into the exponent field it is 2^n (no float-to-int conversion, so this vectorises).
    let scale = f32::from_bits((shifted + 127.0).to_bits() << 23);
    p * scale
}

/// `tanh(u)` from `exp(-2|u|)`.
#[inline(always)]
fn tanh(u: f32) -> f32 {
    let e = exp_nonpositive(-2.0 * u.abs());
    let magnitude = (1.0 - e) / (1.0 + e);
    f32::from_bits(magnitude.to_bits() | (u.to_bits() & 0x8000_0000))
}

/// GELU and its derivative at `z`.
#[inline(always)]
fn gelu_and_slope(z: f32) -> (f32, f32) {
    let z2 = z * z;
    let t = tanh(SQRT_2_OVER_PI * z * (1.0 + GELU_CUBIC * z2));
    let value = 0.5 * z * (1.0 + t);
    let slope =
        0.5 * (1.0 + t) + 0.5 * z * (1.0 - t * t) * SQRT_2_OVER_PI * (1.0 + 3.0 * GELU_CUBIC * z2);
    (value, slope)
}

dispatch! {
    /// `acc += (a_re + i a_im) (x_re + i x_im)` elementwise over complex vectors stored as
    /// separate real and imaginary parts.
    fn complex_axpy(a_re: f32, a_im: f32, x_re: &[f32], x_im: &[f32], acc_re: &mut [f32], acc_im: &mut [f32]) {
        let n = acc_re.len();
        let (x_re, x_im, acc_im) = (&x_re[..n], &x_im[..n], &mut acc_im[..n]);
        for i in 0..n {
            acc_re[i] += a_re * x_re[i] - a_im * x_im[i];
            acc_im[i] += a_re * x_im[i] + a_im * x_re[i];
        }
    }
}

dispatch! {
    /// `sum_i g_i conj(r_i)` of complex vectors stored as real and imaginary parts.
    fn complex_dot_conj(g_re: &[f32], g_im: &[f32], r_re: &[f32], r_im: &[f32]) -> (f32, f32) {
        const LANES: usize = 8;
        let n = g_re.len();
        let (g_im, r_re, r_im) = (&g_im[..n], &r_re[..n], &r_im[..n]);
        let mut re = [0.0f32; LANES];
        let mut im = [0.0f32; LANES];
        let full = n / LANES * LANES;
        for base in (0..full).step_by(LANES) {
            for l in 0..LANES {
                let i = base + l;
                re[l] += g_re[i] * r_re[i] + g_im[i] * r_im[i];
                im[l] += g_im[i] * r_re[i] - g_re[i] * r_im[i];
            }
        }
        for i in full..n {
            re[0] += g_re[i] * r_re[i] + g_im[i] * r_im[i];
            im[0] += g_im[i] * r_re[i] - g_re[i] * r_im[i];
        }
        (re.iter().sum(), im.iter().sum())
    }
}

dispatch! {
    /// In place `z = act(z + bias)` over one channel's block: the inference form of
    /// [`bias_act_forward`] with `b` absent (the same arithmetic, so the same values).
    fn bias_act_in_place(z: &mut [f32], bias: f32, gelu: bool) {
        if gelu {
            for v in z.iter_mut() {
                *v = gelu_and_slope(*v + bias).0;
            }
        } else {
            for v in z.iter_mut() {
                *v += bias;
            }
        }
    }
}

dispatch! {
    /// `out = act(a + b + bias)` over one channel's block, `b` optional (empty slice = absent),
    /// `act` GELU when `gelu`, identity otherwise.
    fn bias_act_forward(a: &[f32], b: &[f32], bias: f32, gelu: bool, out: &mut [f32]) {
        let n = out.len();
        let a = &a[..n];
        if b.is_empty() {
            if gelu {
                for i in 0..n {
                    out[i] = gelu_and_slope(a[i] + bias).0;
                }
            } else {
                for i in 0..n {
                    out[i] = a[i] + bias;
                }
            }
        } else {
            let b = &b[..n];
            if gelu {
                for i in 0..n {
                    out[i] = gelu_and_slope(a[i] + b[i] + bias).0;
                }
            } else {
                for i in 0..n {
                    out[i] = a[i] + b[i] + bias;
                }
            }
        }
    }
}

dispatch! {
    /// In place `grad *= gelu'(a + b + bias)` over one channel's block (`b` empty = absent);
    /// returns the block's sum of the result (the bias gradient).
    fn gelu_backward(a: &[f32], b: &[f32], bias: f32, grad: &mut [f32]) -> f32 {
        let n = grad.len();
        let a = &a[..n];
        if b.is_empty() {
            for i in 0..n {
                grad[i] *= gelu_and_slope(a[i] + bias).1;
            }
        } else {
            let b = &b[..n];
            for i in 0..n {
                grad[i] *= gelu_and_slope(a[i] + b[i] + bias).1;
            }
        }
        let mut lanes = [0.0f32; 16];
        let chunks = grad.chunks_exact(16);
        let tail: f32 = chunks.remainder().iter().sum();
        for c in chunks {
            for l in 0..16 {
                lanes[l] += c[l];
            }
        }
        lanes.iter().sum::<f32>() + tail
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gelu_matches_the_tanh_formula_and_its_derivative() {
        let reference = |z: f64| {
            let u = (2.0 / std::f64::consts::PI).sqrt() * (z + 0.044715 * z * z * z);
            0.5 * z * (1.0 + u.tanh())
        };
        for i in -4000..=4000 {
            let z = i as f64 * 0.005;
            let (v, s) = gelu_and_slope(z as f32);
            assert!((v as f64 - reference(z)).abs() < 1e-6, "z {z}");
            let h = 1e-5;
            let fd = (reference(z + h) - reference(z - h)) / (2.0 * h);
            assert!((s as f64 - fd).abs() < 2e-6, "z {z}: {s} vs {fd}");
        }
        // Far tails: identity and zero, no overflow.
        assert_eq!(gelu_and_slope(60.0), (60.0, 1.0));
        assert_eq!(gelu_and_slope(-60.0).0, 0.0);
    }

    #[test]
    fn exp_is_accurate_on_its_range() {
        for i in 0..=8700 {
            let x = -(i as f32) * 0.01;
            let got = exp_nonpositive(x) as f64;
            let want = (x as f64).exp();
            assert!((got - want).abs() <= 4e-7 * want, "x {x}: {got} vs {want}");
        }
    }

    #[test]
    fn complex_kernels_match_scalar_complex_arithmetic() {
        let n = 37;
        let v = |k: usize, s: f32| {
            (0..n)
                .map(|i| ((i * k) % 11) as f32 * s - 1.0)
                .collect::<Vec<_>>()
        };
        let (x_re, x_im, r_re, r_im) = (v(3, 0.2), v(5, 0.1), v(7, 0.3), v(2, 0.25));
        let mut acc_re = v(1, 0.5);
        let mut acc_im = v(4, 0.5);
        let (before_re, before_im) = (acc_re.clone(), acc_im.clone());
        complex_axpy(0.7, -1.3, &x_re, &x_im, &mut acc_re, &mut acc_im);
        for i in 0..n {
            let want_re = before_re[i] + 0.7 * x_re[i] + 1.3 * x_im[i];
            let want_im = before_im[i] + 0.7 * x_im[i] - 1.3 * x_re[i];
            assert!((acc_re[i] - want_re).abs() < 1e-5 && (acc_im[i] - want_im).abs() < 1e-5);
        }
        let (re, im) = complex_dot_conj(&x_re, &x_im, &r_re, &r_im);
        let (mut want_re, mut want_im) = (0.0f64, 0.0f64);
        for i in 0..n {
            // (x_re + i x_im)(r_re - i r_im)
            want_re += (x_re[i] * r_re[i] + x_im[i] * r_im[i]) as f64;
            want_im += (x_im[i] * r_re[i] - x_re[i] * r_im[i]) as f64;
        }
        assert!((re as f64 - want_re).abs() < 1e-4 && (im as f64 - want_im).abs() < 1e-4);
    }
}
