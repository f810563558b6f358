//! The Sperling ride index, vertical `W_z` and lateral `W_y`, spectral form.
//!
//! Of an acceleration `a(t)` (m/s^2) sampled at `dt` over `N` points: the one-sided amplitude
//! spectrum `a_k` (cm/s^2) at `f_k = k / (N dt)` (Hz), `k = 1..N/2`,
//!
//! ```text
//! X_k = sum_n w_n a_n e^{-2 pi i k n / N}       a_k = c_k |X_k| / sum_n w_n
//!                                              (c_k = 2, 1 at the Nyquist line)
//! W_k = 0.896 (a_k^3 F(f_k) / f_k)^(1/10)
//! F(f) = 0.325 f^2 (0.5 <= f < 5.9),  400 / f^2 (5.9 <= f < 20),  1 (f >= 20)
//! W_z = (sum_{f_k >= f_min} W_k^10)^(1/10) = 0.896 (sum a_k^3 F(f_k) / f_k)^(1/10)
//! ```
//!
//! The lateral index `W_y` takes the lateral weighting ([`weighting_lateral`]):
//! `F(f) = 0.8 f^2 (0.5 <= f < 5.4), 650 / f^2 (5.4 <= f < 26), 1 (f >= 26)` (Sperling's
//! lateral curve, as tabulated for GB/T 5599 and in Garg and Dukkipati, *Dynamics of railway
//! vehicle systems*, 1984).
//!
//! with `w_n` the taper (1 for [`Taper::None`]). A sinusoid of amplitude `A` on a spectral
//! line therefore gives `0.896 (A^3 F(f) / f)^0.1` exactly (the closed form in the tests).
//! With a segment length `L` the window is cut into `floor(N dt / L)` consecutive segments and
//! `W_z` is the largest of theirs.

use crate::config::{SperlingParams, Taper};
use crate::{Error, Result};
use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use std::cell::RefCell;

/// The frequency weighting `F(f)` of the vertical Sperling index (f in Hz).
pub fn weighting(f: f64) -> f64 {
    if f < 5.9 {
        0.325 * f * f
    } else if f < 20.0 {
        400.0 / (f * f)
    } else {
        1.0
    }
}

/// The frequency weighting `F(f)` of the lateral Sperling index (f in Hz).
pub fn weighting_lateral(f: f64) -> f64 {
    if f < 5.4 {
        0.8 * f * f
    } else if f < 26.0 {
        650.0 / (f * f)
    } else {
        1.0
    }
}

thread_local! {
    static PLANNER: RefCell<FftPlanner<f64>> = RefCell::new(FftPlanner::new());
}

/// `sum_k a_k^3 F(f_k) / f_k` of one segment (a_k in cm/s^2).
fn weighted_sum(a: &[f64], dt: f64, taper: Taper, f_min: f64, weight: fn(f64) -> f64) -> f64 {
    let n = a.len();
    let w: Vec<f64> = match taper {
        Taper::None => vec![1.0; n],
        // Periodic Hann: w_n = sin^2(pi n / N).
        Taper::Hann => (0..n)
            .map(|k| (std::f64::consts::PI * k as f64 / n as f64).sin().powi(2))
            .collect(),
    };
    let gain: f64 = w.iter().sum();
    // m/s^2 -> cm/s^2.
    let mut buf: Vec<Complex<f64>> = a
        .iter()
        .zip(&w)
        .map(|(x, w)| Complex::new(100.0 * x * w, 0.0))
        .collect();
    let fft = PLANNER.with(|p| p.borrow_mut().plan_fft_forward(n));
    fft.process(&mut buf);
    let span = n as f64 * dt;
    let mut sum = 0.0;
    for (k, x) in buf.iter().enumerate().take(n / 2 + 1).skip(1) {
        let f = k as f64 / span;
        if f < f_min {
            continue;
        }
        let c = if 2 * k == n { 1.0 } else { 2.0 };
        let amp = c * x.norm() / gain;
        sum += amp * amp * amp * weight(f) / f;
    }
    sum
}

/// `W_z` of acceleration `a` (m/s^2) sampled every `dt` seconds.
pub fn sperling_wz(a: &[f64], dt: f64, p: &SperlingParams) -> Result<f64> {
    sperling_with(a, dt, p, weighting)
}

/// `W_y` (lateral) of acceleration `a` (m/s^2) sampled every `dt` seconds.
pub fn sperling_wy(a: &[f64], dt: f64, p: &SperlingParams) -> Result<f64> {
    sperling_with(a, dt, p, weighting_lateral)
}

/// The Sperling index of `a` with the frequency weighting `weight`.
fn sperling_with(a: &[f64], dt: f64, p: &SperlingParams, weight: fn(f64) -> f64) -> Result<f64> {
    let n = a.len();
    let seg = match p.segment_s {
        None => n,
        Some(len) => (len / dt).round() as usize,
    };
    // At least two points per segment (the spectrum's resolution is 1 / (seg dt): a window
    // shorter than 1 / f_min simply has no line between f_min and its first one).
    let needed = 2;
    if seg < needed || n < seg {
        return Err(Error::TooShort {
            what: format!(
                "Sperling segment ({} at dt {dt} s)",
                p.segment_s
                    .map_or("the whole window".to_owned(), |s| format!("{s} s")),
            ),
            found: n.min(seg),
            needed,
        });
    }
    let worst = a
        .chunks_exact(seg)
        .map(|s| weighted_sum(s, dt, p.taper, p.f_min_hz, weight))
        .fold(0.0f64, f64::max);
    Ok(0.896 * worst.powf(0.1))
}
