//! The truncated DFT of the spectral layers as fixed matrices (`docs/export.md`), for
//! activations laid out time-major, `[T, columns]`: the analysis gives every kept mode's real
//! and imaginary parts, the synthesis the real series `sum_k c_k / T (Re Y_k cos - Im Y_k sin)`
//! (`c_0 = 1`, `c_k = 2` above, as `pino_learn::spectral::Dft`).
//!
//! Modes are held in *slots* `[K, 2]` (real, imaginary), the mode mixing reads them in that
//! order (an empty slot holds zeros). Two forms:
//! - direct: one product with `[2M, T]` (analysis) and `[T, 2M]` (synthesis), `4 M T`
//!   multiply-adds per column;
//! - two-stage, over `T = N1 N2` with `t = n1 + N1 n2`: the analysis first sums over `n2`
//!   with the short real DFT of length `N2` (`[R, N2]`, one cosine and one sine row per
//!   *class* `c = 0..N2/2`), which leaves every mode `k` with `k mod N2 = c` or `N2 - c`
//!   to a sum over `n1` of that class's rows (`[2J, 2 N1]` per class, `J` slots); the
//!   synthesis is its mirror. `R T` plus `4 J N1` per class multiply-adds per column and
//!   direction instead of `2 M T`: about a fifth of the work for the default model
//!   (`T = 2500 = 100 x 25`, 128 modes, 13 classes of 11 slots).
//!
//! [`Plan::for_layer`] picks the cheaper form; every matrix is computed in double precision
//! (angles reduced modulo the period first) and rounded once to single precision, the
//! products' ([`Analysis`], [`Synthesis`]).

use crate::graph::{Graph, Value};
use std::f64::consts::PI;

/// How one spectral layer's DFT is factored.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Padded length `T`.
    pub t: usize,
    /// Length of the short inner transform `N2` (1: the direct form).
    pub n2: usize,
    /// The classes `c` kept (those with a mode), in slot order.
    pub classes: Vec<usize>,
    /// Slots per class `J` (the direct form: `M` slots of one class).
    pub per_class: usize,
    /// The mode in each slot, class-major (`None`: an empty slot).
    pub slots: Vec<Option<usize>>,
}

impl Plan {
    /// The direct form of `m` modes over `t` points.
    pub fn direct(t: usize, m: usize) -> Self {
        Self {
            t,
            n2: 1,
            classes: vec![0],
            per_class: m,
            slots: (0..m).map(Some).collect(),
        }
    }

    /// The two-stage form with an inner length `n2` (a divisor of `t`).
    pub fn two_stage(t: usize, m: usize, n2: usize) -> Self {
        debug_assert!(n2 > 1 && t.is_multiple_of(n2));
        let mut classes = Vec::new();
        let mut members: Vec<Vec<usize>> = Vec::new();
        for c in 0..=n2 / 2 {
            let modes: Vec<usize> = (0..m)
                .filter(|&k| k % n2 == c || k % n2 == n2 - c)
                .collect();
            if !modes.is_empty() {
                classes.push(c);
                members.push(modes);
            }
        }
        let per_class = members.iter().map(Vec::len).max().unwrap_or(0);
        let slots = members
            .iter()
            .flat_map(|modes| (0..per_class).map(|j| modes.get(j).copied()))
            .collect();
        Self {
            t,
            n2,
            classes,
            per_class,
            slots,
        }
    }

    /// The cheapest form for `m` modes over `t` points between layers of `width` channels:
    /// the direct one, or the two-stage one over the divisor of `t` with the fewest
    /// multiply-adds per design (analysis, mixing and synthesis).
    pub fn for_layer(t: usize, m: usize, width: usize) -> Self {
        let mut best = Self::direct(t, m);
        for n2 in (2..t).filter(|n| t.is_multiple_of(*n)) {
            let p = Self::two_stage(t, m, n2);
            if p.cost(width) < best.cost(width) {
                best = p;
            }
        }
        best
    }

    /// Whether it is the direct form.
    pub fn is_direct(&self) -> bool {
        self.n2 == 1
    }

    /// The outer length `N1 = T / N2`.
    pub fn n1(&self) -> usize {
        self.t / self.n2
    }

    /// Slots `K`.
    pub fn n_slots(&self) -> usize {
        self.slots.len()
    }

    /// Rows of the inner transform `R` (a cosine and a sine row per class).
    pub fn rows(&self) -> usize {
        2 * self.classes.len()
    }

    /// Multiply-adds per design of one layer of `width` channels in and out.
    pub fn cost(&self, width: usize) -> usize {
        let per_column = if self.is_direct() {
            2 * self.t * 2 * self.n_slots()
        } else {
            2 * (self.rows() * self.t + self.classes.len() * 4 * self.per_class * self.n1())
        };
        width * per_column + self.n_slots() * 4 * width * width
    }

    /// The slot of mode `k`.
    pub fn slot_of(&self, k: usize) -> Option<usize> {
        self.slots.iter().position(|&s| s == Some(k))
    }

    /// Direct analysis `[2K, T]`: row `2s` the real part of slot `s`'s mode, `2s + 1` its
    /// imaginary part.
    pub fn direct_analysis(&self) -> Vec<f64> {
        let t = self.t;
        let mut a = vec![0.0; 2 * self.n_slots() * t];
        for (s, k) in self.modes() {
            for n in 0..t {
                let (sin, cos) = angle(k * n, t).sin_cos();
                a[2 * s * t + n] = cos;
                a[(2 * s + 1) * t + n] = -sin;
            }
        }
        a
    }

    /// Direct synthesis `[T, 2K]`.
    pub fn direct_synthesis(&self) -> Vec<f64> {
        let (t, w) = (self.t, 2 * self.n_slots());
        let mut a = vec![0.0; t * w];
        for (s, k) in self.modes() {
            let c = weight(k, t);
            for n in 0..t {
                let (sin, cos) = angle(k * n, t).sin_cos();
                a[n * w + 2 * s] = c * cos;
                a[n * w + 2 * s + 1] = -c * sin;
            }
        }
        a
    }

    /// The inner transform `[R, N2]`: per class `c`, the rows `cos(2 pi c n2 / N2)` and
    /// `sin(..)`. Its transpose `[N2, R]` is the synthesis's last stage.
    pub fn inner(&self) -> Vec<f64> {
        let n2 = self.n2;
        let mut a = vec![0.0; self.rows() * n2];
        for (i, &c) in self.classes.iter().enumerate() {
            for n in 0..n2 {
                let (sin, cos) = angle(c * n, n2).sin_cos();
                a[2 * i * n2 + n] = cos;
                a[(2 * i + 1) * n2 + n] = sin;
            }
        }
        a
    }

    /// The inner transform's transpose `[N2, R]`.
    pub fn inner_transposed(&self) -> Vec<f64> {
        let (r, n2) = (self.rows(), self.n2);
        let a = self.inner();
        let mut t = vec![0.0; a.len()];
        for i in 0..r {
            for n in 0..n2 {
                t[n * r + i] = a[i * n2 + n];
            }
        }
        t
    }

    /// The outer analysis `[classes, 2J, 2 N1]`: for the slots of each class, their real and
    /// imaginary rows over the class's cosine and sine sums `[C(n1), S(n1)]`.
    pub fn outer_analysis(&self) -> Vec<f64> {
        let (j, n1) = (self.per_class, self.n1());
        let mut a = vec![0.0; self.classes.len() * 2 * j * 2 * n1];
        for (s, k) in self.modes() {
            let sigma = self.sigma(s, k);
            let row = |r: usize, col: usize| (2 * s + r) * 2 * n1 + col;
            for n in 0..n1 {
                let (sin, cos) = angle(k * n, self.t).sin_cos();
                a[row(0, n)] = cos;
                a[row(0, n1 + n)] = -sigma * sin;
                a[row(1, n)] = -sin;
                a[row(1, n1 + n)] = -sigma * cos;
            }
        }
        a
    }

    /// The outer synthesis `[classes, 2 N1, 2J]`: per class, the cosine and sine
    /// coefficients `[Q(n1), Q'(n1)]` of the inner synthesis from its slots' real and
    /// imaginary parts.
    pub fn outer_synthesis(&self) -> Vec<f64> {
        let (j, n1) = (self.per_class, self.n1());
        let mut a = vec![0.0; self.classes.len() * 2 * n1 * 2 * j];
        for (s, k) in self.modes() {
            let (class, slot) = (s / j, s % j);
            let sigma = self.sigma(s, k);
            let c = weight(k, self.t);
            let at = |row: usize, col: usize| (class * 2 * n1 + row) * 2 * j + 2 * slot + col;
            for n in 0..n1 {
                let (sin, cos) = angle(k * n, self.t).sin_cos();
                a[at(n, 0)] = c * cos;
                a[at(n, 1)] = -c * sin;
                a[at(n1 + n, 0)] = -sigma * c * sin;
                a[at(n1 + n, 1)] = -sigma * c * cos;
            }
        }
        a
    }

    /// `(slot, mode)` of every filled slot.
    fn modes(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.slots
            .iter()
            .enumerate()
            .filter_map(|(s, k)| k.map(|k| (s, k)))
    }

    /// `+1` when mode `k` (in slot `s`) is `c mod N2` of its class `c`, `-1` when `-c`.
    fn sigma(&self, s: usize, k: usize) -> f64 {
        let c = self.classes[s / self.per_class];
        if k % self.n2 == c {
            1.0
        } else {
            -1.0
        }
    }
}

/// A plan's analysis in a graph: its fixed matrices.
pub enum Analysis {
    /// `[2K, T]`.
    Direct(Value),
    /// Inner `[R, N2]` and outer `[classes, 2J, 2 N1]`.
    TwoStage(Value, Value),
}

impl Analysis {
    /// The matrices of `plan`.
    pub fn new(g: &mut Graph, plan: &Plan) -> Self {
        if plan.is_direct() {
            let a = g.f32s(
                &[2 * plan.n_slots(), plan.t],
                &single(plan.direct_analysis()),
            );
            return Self::Direct(a);
        }
        let (r, n1, j, c) = (plan.rows(), plan.n1(), plan.per_class, plan.classes.len());
        Self::TwoStage(
            g.f32s(&[r, plan.n2], &single(plan.inner())),
            g.f32s(&[c, 2 * j, 2 * n1], &single(plan.outer_analysis())),
        )
    }

    /// The slots `[K, 2, C]` (real, imaginary) of the columns of `x [T, C]`.
    pub fn apply(&self, g: &mut Graph, plan: &Plan, x: &str) -> Value {
        let spec = match self {
            Self::Direct(a) => g.matmul(a, x), // [2K, C]
            Self::TwoStage(inner, outer) => {
                let cols = g.reshape(x, &[plan.n2 as i64, -1]); // [N2, N1 C]
                let sums = g.matmul(inner, &cols); // [R, N1 C]
                let classes = plan.classes.len() as i64;
                let per_class = g.reshape(&sums, &[classes, 2 * plan.n1() as i64, -1]);
                g.matmul(outer, &per_class) // [classes, 2J, C]
            }
        };
        g.reshape(&spec, &[plan.n_slots() as i64, 2, -1])
    }
}

/// A plan's synthesis in a graph: its fixed matrices.
pub enum Synthesis {
    /// `[T, 2K]`.
    Direct(Value),
    /// Outer `[classes, 2 N1, 2J]` and inner `[N2, R]`.
    TwoStage(Value, Value),
}

impl Synthesis {
    /// The matrices of `plan`.
    pub fn new(g: &mut Graph, plan: &Plan) -> Self {
        if plan.is_direct() {
            let s = g.f32s(
                &[plan.t, 2 * plan.n_slots()],
                &single(plan.direct_synthesis()),
            );
            return Self::Direct(s);
        }
        let (r, n1, j, c) = (plan.rows(), plan.n1(), plan.per_class, plan.classes.len());
        Self::TwoStage(
            g.f32s(&[c, 2 * n1, 2 * j], &single(plan.outer_synthesis())),
            g.f32s(&[plan.n2, r], &single(plan.inner_transposed())),
        )
    }

    /// The real series `[T, C]` of the slots `y [K, 2, C]`.
    pub fn apply(&self, g: &mut Graph, plan: &Plan, y: &str) -> Value {
        match self {
            Self::Direct(s) => {
                let y = g.reshape(y, &[2 * plan.n_slots() as i64, -1]);
                g.matmul(s, &y)
            }
            Self::TwoStage(outer, inner) => {
                let classes = plan.classes.len() as i64;
                let y = g.reshape(y, &[classes, 2 * plan.per_class as i64, -1]);
                let coeffs = g.matmul(outer, &y); // [classes, 2 N1, C]
                let coeffs = g.reshape(&coeffs, &[plan.rows() as i64, -1]);
                let out = g.matmul(inner, &coeffs); // [N2, N1 C]
                g.reshape(&out, &[plan.t as i64, -1])
            }
        }
    }
}

/// Rounded to single precision.
fn single(v: Vec<f64>) -> Vec<f32> {
    v.into_iter().map(|x| x as f32).collect()
}

/// `2 pi (p mod n) / n`.
fn angle(p: usize, n: usize) -> f64 {
    2.0 * PI * (p % n) as f64 / n as f64
}

/// The synthesis weight `c_k / T`.
fn weight(k: usize, t: usize) -> f64 {
    if k == 0 {
        1.0 / t as f64
    } else {
        2.0 / t as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `a [r, c] x b [c, n]`.
    fn product(a: &[f64], b: &[f64], (r, c, n): (usize, usize, usize)) -> Vec<f64> {
        let mut out = vec![0.0; r * n];
        for i in 0..r {
            for k in 0..c {
                for j in 0..n {
                    out[i * n + j] += a[i * c + k] * b[k * n + j];
                }
            }
        }
        out
    }

    /// The plan's analysis of `x [T]` into `[K, 2]`.
    fn analyse(p: &Plan, x: &[f64]) -> Vec<f64> {
        let k = p.n_slots();
        if p.is_direct() {
            return product(&p.direct_analysis(), x, (2 * k, p.t, 1));
        }
        let (r, n1, n2, j) = (p.rows(), p.n1(), p.n2, p.per_class);
        let sums = product(&p.inner(), x, (r, n2, n1)); // [R, N1] = [classes, 2 N1]
        let outer = p.outer_analysis();
        let mut out = Vec::new();
        for c in 0..p.classes.len() {
            let a = &outer[c * 2 * j * 2 * n1..(c + 1) * 2 * j * 2 * n1];
            out.extend(product(
                a,
                &sums[c * 2 * n1..(c + 1) * 2 * n1],
                (2 * j, 2 * n1, 1),
            ));
        }
        out
    }

    /// The plan's synthesis of `y [K, 2]` into `[T]`.
    fn synthesise(p: &Plan, y: &[f64]) -> Vec<f64> {
        let k = p.n_slots();
        if p.is_direct() {
            return product(&p.direct_synthesis(), y, (p.t, 2 * k, 1));
        }
        let (r, n1, n2, j) = (p.rows(), p.n1(), p.n2, p.per_class);
        let outer = p.outer_synthesis();
        let mut coeffs = Vec::new();
        for c in 0..p.classes.len() {
            let a = &outer[c * 2 * n1 * 2 * j..(c + 1) * 2 * n1 * 2 * j];
            coeffs.extend(product(
                a,
                &y[c * 2 * j..(c + 1) * 2 * j],
                (2 * n1, 2 * j, 1),
            ));
        }
        product(&p.inner_transposed(), &coeffs, (n2, r, n1))
    }

    fn series(t: usize, seed: u64) -> Vec<f64> {
        (0..t)
            .map(|n| {
                let x = (n as u64 * 2654435761 + seed * 97) % 1000;
                x as f64 / 500.0 - 1.0
            })
            .collect()
    }

    #[test]
    fn both_forms_are_the_truncated_dft_and_its_synthesis() {
        for (t, m) in [(2500, 128), (60, 7), (48, 24), (35, 12), (31, 5)] {
            let x = series(t, t as u64);
            let y = series(2 * m, 3);
            // The definitions, term by term.
            let spectrum: Vec<f64> = (0..m)
                .flat_map(|k| {
                    let re: f64 = (0..t).map(|n| x[n] * angle(k * n, t).cos()).sum();
                    let im: f64 = (0..t).map(|n| -x[n] * angle(k * n, t).sin()).sum();
                    [re, im]
                })
                .collect();
            let series_of = |n: usize| -> f64 {
                (0..m)
                    .map(|k| {
                        let a = angle(k * n, t);
                        weight(k, t) * (y[2 * k] * a.cos() - y[2 * k + 1] * a.sin())
                    })
                    .sum()
            };
            let scale = x.iter().fold(0.0f64, |a, v| a.max(v.abs())) * t as f64;
            let mut plans = vec![Plan::direct(t, m), Plan::for_layer(t, m, 32)];
            plans.extend(
                (2..t)
                    .filter(|n| t.is_multiple_of(*n))
                    .map(|n2| Plan::two_stage(t, m, n2)),
            );
            for p in plans {
                let got = analyse(&p, &x);
                let mut packed = vec![0.0; 2 * p.n_slots()];
                for k in 0..m {
                    let s = p.slot_of(k).expect("every mode has a slot");
                    for part in 0..2 {
                        let d = (got[2 * s + part] - spectrum[2 * k + part]).abs();
                        assert!(d < 1e-9 * scale, "T {t}, N2 {}, mode {k}: {d}", p.n2);
                        packed[2 * s + part] = y[2 * k + part];
                    }
                }
                let empty = p.slots.iter().enumerate().filter(|(_, k)| k.is_none());
                for (s, _) in empty {
                    assert_eq!((got[2 * s], got[2 * s + 1]), (0.0, 0.0));
                }
                let back = synthesise(&p, &packed);
                for (n, v) in back.iter().enumerate() {
                    assert!((v - series_of(n)).abs() < 1e-12, "T {t}, N2 {}: {n}", p.n2);
                }
            }
        }
    }

    #[test]
    fn the_default_model_gets_the_two_stage_form_at_a_quarter_of_the_work() {
        let p = Plan::for_layer(2500, 128, 32);
        assert!(!p.is_direct());
        assert_eq!((p.n2, p.classes.len(), p.per_class), (25, 13, 11));
        let direct = Plan::direct(2500, 128).cost(32);
        assert!(4 * p.cost(32) < direct, "{} against {direct}", p.cost(32));
        // A prime length has no factorisation; few modes need none.
        assert!(Plan::for_layer(31, 5, 8).is_direct());
        assert!(Plan::for_layer(60, 2, 8).is_direct());
    }
}
