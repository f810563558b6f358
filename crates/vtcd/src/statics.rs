//! Static deflection of the track under point loads (`docs/model.md`, start protocols).
//!
//! With every velocity and acceleration zero, the substructure equations of
//! [`crate::track`] become linear algebra. The sleeper carries the fastener force on to the
//! ballast, so fastener and ballast act in series, `F_fj = k_fb (Z_r(x_j) - Z_bj)` with
//! `k_fb = k_f k_b / (k_f + k_b)`, and the sleeper sits at `Z_sj = (k_f Z_r(x_j) + k_b Z_bj) /
//! (k_f + k_b)`. The ballast blocks then solve one tridiagonal system,
//! ```text
//! (k_fb + k_g + 2 k_w) Z_bj - k_w (Z_b,j-1 + Z_b,j+1) = k_fb Z_r(x_j)     (ends fixed)
//! ```
//! and the rail modes the symmetric positive definite system
//! ```text
//! w_k^2 q_k + sum_j F_fj Y_k(x_j) = sum_i P_i Y_k(x_i)
//! ```
//! whose operator costs two sine transforms and one tridiagonal solve. It is solved by
//! preconditioned conjugate gradients. The preconditioner is exact for the same track with
//! block 0 (under the rail's end node) removed: there the ballast grid shares the rail's
//! discrete sine basis, the tridiagonal matrix has eigenvalues `k_fb + k_g + k_w (2 - 2 cos(pi k
//! / N_f))`, and by discrete sine orthogonality the modal operator is diagonal,
//! `w_k^2 + (N_f / 2) scale^2 s_k` with `s_k = k_fb - k_fb^2 / (k_fb + k_g + k_w (2 - 2
//! cos(pi k / N_f)))`. The real track differs from it by one block, a low-rank change, so the
//! iteration reaches round-off in a few steps.

use std::f64::consts::PI;

use crate::rail::{Rail, SineTransform};
use crate::track::TrackParams;
use crate::{Error, Result};

/// Relative residual `|b - K q| / |b|` the iteration stops at (round-off of the operator).
const TOLERANCE: f64 = 1e-14;
/// Relative residual below which a stalled iteration still counts as converged.
const ACCEPT: f64 = 1e-11;
/// Iterations without a new smallest residual after which the iteration has stalled at
/// round-off.
const STALL: usize = 10;
/// Iteration cap; the preconditioned system converges in tens of steps.
const MAX_ITERATIONS: usize = 500;

/// The static track state under the loads.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackStatics {
    /// Rail modal coordinates `q_1..q_N_M` (sqrt(kg) m).
    pub q: Vec<f64>,
    /// Sleeper displacements `Z_s0..` (m).
    pub sleepers: Vec<f64>,
    /// Ballast block displacements `Z_b0..` (m).
    pub ballast: Vec<f64>,
    /// Conjugate-gradient iterations taken.
    pub iterations: usize,
    /// Final relative residual of the modal system.
    pub residual: f64,
}

/// The modal stiffness operator of the statically condensed track.
struct Operator<'a> {
    rail: &'a Rail,
    dst: SineTransform,
    k_fb: f64,
    k_w: f64,
    /// Thomas-algorithm factors of the ballast matrix: modified super-diagonal and the
    /// reciprocal pivots.
    upper: Vec<f64>,
    inv_pivot: Vec<f64>,
    scaled: Vec<f64>,
    grid: Vec<f64>,
    ballast: Vec<f64>,
    force: Vec<f64>,
    modal: Vec<f64>,
}

impl<'a> Operator<'a> {
    fn new(rail: &'a Rail, tp: &TrackParams, k_f: f64) -> Self {
        let n = tp.n_f;
        let k_fb = k_f * tp.k_b / (k_f + tp.k_b);
        let diag = k_fb + tp.k_g + 2.0 * tp.k_w;
        let (mut upper, mut inv_pivot) = (vec![0.0; n], vec![0.0; n]);
        // Forward elimination of the constant tridiagonal [-k_w, diag, -k_w]: strictly
        // diagonally dominant (k_fb + k_g > 0), so every pivot is positive.
        let mut prev_upper = 0.0;
        for j in 0..n {
            let pivot = diag + tp.k_w * prev_upper;
            inv_pivot[j] = 1.0 / pivot;
            upper[j] = -tp.k_w * inv_pivot[j];
            prev_upper = upper[j];
        }
        Self {
            rail,
            dst: SineTransform::new(n),
            k_fb,
            k_w: tp.k_w,
            upper,
            inv_pivot,
            scaled: vec![0.0; tp.n_m],
            grid: vec![0.0; n],
            ballast: vec![0.0; n],
            force: vec![0.0; n],
            modal: vec![0.0; tp.n_m],
        }
    }

    /// Rail displacement on the fastener grid (`grid[0] = 0`, the end node) and the ballast
    /// displacements under it, for modal coordinates `q`.
    fn deflect(&mut self, q: &[f64]) {
        let scale = self.rail.shape_scale;
        for (s, q) in self.scaled.iter_mut().zip(q) {
            *s = scale * q;
        }
        self.grid[0] = 0.0;
        self.dst.apply(&self.scaled, &mut self.grid[1..]);
        // Thomas: forward sweep on k_fb Z_r, then back substitution.
        let mut prev = 0.0;
        for j in 0..self.grid.len() {
            let rhs = self.k_fb * self.grid[j] + self.k_w * prev;
            self.ballast[j] = rhs * self.inv_pivot[j];
            prev = self.ballast[j];
        }
        for j in (0..self.grid.len() - 1).rev() {
            self.ballast[j] -= self.upper[j] * self.ballast[j + 1];
        }
    }

    /// `out = K q`: modal stiffness plus the fastener reactions.
    fn apply(&mut self, q: &[f64], out: &mut [f64]) {
        self.deflect(q);
        for ((f, z), b) in self.force.iter_mut().zip(&self.grid).zip(&self.ballast) {
            *f = self.k_fb * (z - b);
        }
        self.dst.apply(&self.force[1..], &mut self.modal);
        let scale = self.rail.shape_scale;
        for (((o, q), w2), m) in out
            .iter_mut()
            .zip(q)
            .zip(&self.rail.omega2)
            .zip(&self.modal)
        {
            *o = w2 * q + scale * m;
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The static state of the track (rail, sleepers, ballast) under downward point loads
/// `loads[i]` (N) at positions `positions[i]` (m), with fastener stiffness `k_f` (N/m).
/// `tp` is assumed validated (as [`crate::simulation::Simulation::new`] does).
pub fn track_deflection(
    rail: &Rail,
    tp: &TrackParams,
    k_f: f64,
    positions: &[f64],
    loads: &[f64],
) -> Result<TrackStatics> {
    let nm = tp.n_m;
    let mut op = Operator::new(rail, tp, k_f);
    // Right-hand side: modal loads sum_i P_i Y_k(x_i).
    let mut b = vec![0.0; nm];
    let mut shapes = vec![0.0; nm];
    for (&x, &p) in positions.iter().zip(loads) {
        rail.shapes_at(x, &mut shapes);
        for (b, y) in b.iter_mut().zip(&shapes) {
            *b += p * y;
        }
    }
    let n_f = tp.n_f as f64;
    let scale2 = rail.shape_scale * rail.shape_scale;
    let inv_precond: Vec<f64> = (1..=nm)
        .zip(&rail.omega2)
        .map(|(k, w2)| {
            let lambda = 2.0 - 2.0 * (PI * k as f64 / n_f).cos();
            let s = op.k_fb - op.k_fb * op.k_fb / (op.k_fb + tp.k_g + tp.k_w * lambda);
            1.0 / (w2 + 0.5 * n_f * scale2 * s)
        })
        .collect();
    let b_norm = dot(&b, &b).sqrt();
    let mut q = vec![0.0; nm];
    let (mut iterations, mut residual) = (0, 0.0);
    if b_norm > 0.0 {
        let mut r = b.clone();
        let mut z: Vec<f64> = r.iter().zip(&inv_precond).map(|(r, m)| r * m).collect();
        let mut p = z.clone();
        let mut kp = vec![0.0; nm];
        let mut rz = dot(&r, &z);
        residual = 1.0;
        let (mut best, mut best_at) = (f64::INFINITY, 0);
        while residual > TOLERANCE && iterations < MAX_ITERATIONS && iterations - best_at < STALL {
            op.apply(&p, &mut kp);
            let alpha = rz / dot(&p, &kp);
            for ((q, r), (p, kp)) in q.iter_mut().zip(r.iter_mut()).zip(p.iter().zip(&kp)) {
                *q += alpha * p;
                *r -= alpha * kp;
            }
            iterations += 1;
            // The true residual, not the recurrence's (which drifts below round-off).
            op.apply(&q, &mut kp);
            let true_r: f64 = b
                .iter()
                .zip(&kp)
                .map(|(b, k)| (b - k) * (b - k))
                .sum::<f64>()
                .sqrt();
            residual = true_r / b_norm;
            if residual < best {
                (best, best_at) = (residual, iterations);
            }
            for ((z, r), m) in z.iter_mut().zip(&r).zip(&inv_precond) {
                *z = r * m;
            }
            let rz_next = dot(&r, &z);
            let beta = rz_next / rz;
            rz = rz_next;
            for (p, z) in p.iter_mut().zip(&z) {
                *p = z + beta * *p;
            }
        }
        if residual.is_nan() || residual > ACCEPT {
            return Err(Error::NoConvergence {
                what: "static track deflection (conjugate gradients)".to_owned(),
                iterations,
                residual,
            });
        }
    }
    op.deflect(&q);
    let (k_b, sum) = (tp.k_b, k_f + tp.k_b);
    let sleepers = op
        .grid
        .iter()
        .zip(&op.ballast)
        .map(|(z, b)| (k_f * z + k_b * b) / sum)
        .collect();
    Ok(TrackStatics {
        q,
        sleepers,
        ballast: op.ballast,
        iterations,
        residual,
    })
}
