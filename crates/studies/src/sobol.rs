//! Variance-based sensitivity: Sobol indices by Saltelli's scheme.
//!
//! Two independent `N x d` matrices `A`, `B` of unit-cube points come from one Owen-scrambled
//! Sobol' sequence of `2d` dimensions ([`SaltelliDesign`]: `A` the first `d` coordinates, `B`
//! the last `d`). A factor is a group of columns (one parameter, or every random phase of a
//! profile as one "excitation" factor); `A_B^(i)` is `A` with factor `i`'s columns taken from
//! `B`. With `g` factors the model runs `N (g + 2)` times, stored in SALib's order: for each
//! row `j`, `f(A_j)`, `f(A_B^(1)_j)`, ..., `f(A_B^(g)_j)`, `f(B_j)` ([`Block`]).
//!
//! The outputs are standardised (`(y - mean) / std` over all `N (g + 2)` values, population
//! std), as SALib does before estimating, then with `V` the population variance of the `2N`
//! values of `f(A)` and `f(B)`:
//! - first order (Saltelli et al. 2010): `S_i = mean(f(B) (f(A_B^(i)) - f(A))) / V`;
//! - total (Jansen 1999): `ST_i = mean((f(A) - f(A_B^(i)))^2) / (2 V)`.
//!
//! Intervals are percentile bootstraps over the rows (a row's `A`, `B` and every `A_B^(i)`
//! resampled together); the convergence record repeats the estimate on the first `2^m` rows
//! (balanced prefixes of the Sobol' sequence).

use crate::stats::{bootstrap, Interval};
use crate::{out_of_range, Result};

/// The largest `N` of a design (the scrambled sequence's length).
pub const MAX_ROWS: usize = 1 << 16;

/// The largest number of unit-cube dimensions of `A` (half the sequence's 256).
pub const MAX_DIMS: usize = 128;

/// The smallest prefix of the convergence record.
pub const CONVERGENCE_FROM: usize = 16;

/// The first-order and total index of each factor, in factor order.
pub type Indices = Vec<(f64, f64)>;

/// Which matrix an evaluation belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Block {
    /// `A`.
    A,
    /// `A` with factor `i`'s columns from `B`.
    AB(usize),
    /// `B`.
    B,
}

impl Block {
    /// The block's position within a row of `g + 2` evaluations (SALib's order).
    pub fn position(self, factors: usize) -> usize {
        match self {
            Self::A => 0,
            Self::AB(i) => i + 1,
            Self::B => factors + 1,
        }
    }

    /// The block at `position` of a row.
    pub fn at(position: usize, factors: usize) -> Self {
        match position {
            0 => Self::A,
            p if p == factors + 1 => Self::B,
            p => Self::AB(p - 1),
        }
    }

    /// Its name in the stored matrices: `A`, `AB`, `B`.
    pub fn label(self) -> &'static str {
        match self {
            Self::A => "A",
            Self::AB(_) => "AB",
            Self::B => "B",
        }
    }
}

/// The unit-cube points of Saltelli's design: `n` rows of `dims` coordinates in `A` and `B`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SaltelliDesign {
    /// Rows `N` (a power of two).
    pub n: usize,
    /// Coordinates per point.
    pub dims: usize,
    /// Scrambling seed.
    pub seed: u32,
}

impl SaltelliDesign {
    /// A design of `n` rows (a power of two from 2 to [`MAX_ROWS`]) and `dims` coordinates
    /// (1 to [`MAX_DIMS`]).
    pub fn new(n: usize, dims: usize, seed: u32) -> Result<Self> {
        if !(2..=MAX_ROWS).contains(&n) || !n.is_power_of_two() {
            return Err(out_of_range(
                "n",
                n,
                format!("a power of two from 2 to {MAX_ROWS}"),
            ));
        }
        if !(1..=MAX_DIMS).contains(&dims) {
            return Err(out_of_range(
                "factors",
                dims,
                format!("1 to {MAX_DIMS} varying parameters"),
            ));
        }
        Ok(Self { n, dims, seed })
    }

    fn point(&self, row: usize, offset: usize) -> Vec<f64> {
        (0..self.dims)
            .map(|d| {
                f64::from(sobol_burley::sample(
                    row as u32,
                    (offset + d) as u32,
                    self.seed,
                ))
            })
            .collect()
    }

    /// Row `row` of `A`.
    pub fn a(&self, row: usize) -> Vec<f64> {
        self.point(row, 0)
    }

    /// Row `row` of `B`.
    pub fn b(&self, row: usize) -> Vec<f64> {
        self.point(row, self.dims)
    }
}

/// Row `a` with the columns of `group` taken from row `b` (`A_B^(i)`).
pub fn swap(a: &[f64], b: &[f64], group: &[usize]) -> Vec<f64> {
    let mut out = a.to_vec();
    for &c in group {
        out[c] = b[c];
    }
    out
}

/// One factor's indices with their bootstrap intervals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FactorIndices {
    /// First-order index.
    pub first: f64,
    /// Its interval.
    pub first_ci: Interval,
    /// Total index.
    pub total: f64,
    /// Its interval.
    pub total_ci: Interval,
}

/// `(y - mean) / std` over all values (population std; unchanged when constant).
fn standardised(y: &[f64]) -> Vec<f64> {
    let n = y.len() as f64;
    let m = y.iter().sum::<f64>() / n;
    let s = (y.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n).sqrt();
    if s > 0.0 {
        y.iter().map(|v| (v - m) / s).collect()
    } else {
        y.to_vec()
    }
}

/// First-order and total indices of every factor from standardised outputs `y` (SALib order,
/// `g + 2` per row) over rows `rows`.
fn estimate_rows(y: &[f64], g: usize, rows: &[usize]) -> Indices {
    let step = g + 2;
    let a = |r: usize| y[r * step];
    let b = |r: usize| y[r * step + g + 1];
    let n = rows.len() as f64;
    let mean_ab = rows.iter().map(|&r| a(r) + b(r)).sum::<f64>() / (2.0 * n);
    let var = rows
        .iter()
        .map(|&r| (a(r) - mean_ab).powi(2) + (b(r) - mean_ab).powi(2))
        .sum::<f64>()
        / (2.0 * n);
    (0..g)
        .map(|i| {
            if var == 0.0 {
                return (0.0, 0.0);
            }
            let ab = |r: usize| y[r * step + i + 1];
            let first = rows.iter().map(|&r| b(r) * (ab(r) - a(r))).sum::<f64>() / n / var;
            let total = rows.iter().map(|&r| (a(r) - ab(r)).powi(2)).sum::<f64>() / n / (2.0 * var);
            (first, total)
        })
        .collect()
}

fn check_outputs(y: &[f64], n: usize, g: usize) -> Result<()> {
    if y.len() != n * (g + 2) || n < 2 {
        return Err(out_of_range(
            "outputs",
            y.len(),
            format!("N (g + 2) = {} values (N = {n}, g = {g})", n * (g + 2)),
        ));
    }
    Ok(())
}

/// The indices of `g` factors from the outputs `y` of an `n`-row design (SALib order).
pub fn estimate(y: &[f64], n: usize, g: usize) -> Result<Indices> {
    check_outputs(y, n, g)?;
    let rows: Vec<usize> = (0..n).collect();
    Ok(estimate_rows(&standardised(y), g, &rows))
}

/// [`estimate`] with percentile-bootstrap intervals at `level` (`reps` replicates from
/// `seed`).
pub fn estimate_with_intervals(
    y: &[f64],
    n: usize,
    g: usize,
    reps: usize,
    seed: u64,
    level: f64,
) -> Result<Vec<FactorIndices>> {
    check_outputs(y, n, g)?;
    let ys = standardised(y);
    let rows: Vec<usize> = (0..n).collect();
    let point = estimate_rows(&ys, g, &rows);
    let ci = bootstrap(n, reps, seed, level, |rows| {
        estimate_rows(&ys, g, rows)
            .into_iter()
            .flat_map(|(f, t)| [f, t])
            .collect()
    });
    let nan = Interval {
        lo: f64::NAN,
        hi: f64::NAN,
    };
    Ok(point
        .iter()
        .enumerate()
        .map(|(i, &(first, total))| FactorIndices {
            first,
            first_ci: ci.get(2 * i).copied().unwrap_or(nan),
            total,
            total_ci: ci.get(2 * i + 1).copied().unwrap_or(nan),
        })
        .collect())
}

/// The estimates on the first `2^m` rows, `m` from [`CONVERGENCE_FROM`] up to `n`: `(rows,
/// indices)` per prefix (each prefix standardised on its own, as a study of that size would
/// be).
pub fn convergence(y: &[f64], n: usize, g: usize) -> Result<Vec<(usize, Indices)>> {
    check_outputs(y, n, g)?;
    let mut out = Vec::new();
    let mut m = CONVERGENCE_FROM.min(n);
    while m <= n {
        out.push((m, estimate(&y[..m * (g + 2)], m, g)?));
        m *= 2;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Evaluates `f` on the design's points mapped by `map`, in SALib order, each factor one
    /// column.
    fn outputs(design: &SaltelliDesign, f: impl Fn(&[f64]) -> f64) -> Vec<f64> {
        let g = design.dims;
        let mut y = Vec::with_capacity(design.n * (g + 2));
        for r in 0..design.n {
            let (a, b) = (design.a(r), design.b(r));
            for p in 0..g + 2 {
                let x = match Block::at(p, g) {
                    Block::A => a.clone(),
                    Block::B => b.clone(),
                    Block::AB(i) => swap(&a, &b, &[i]),
                };
                y.push(f(&x));
            }
        }
        y
    }

    fn ishigami(u: &[f64]) -> f64 {
        let x: Vec<f64> = u.iter().map(|u| -PI + 2.0 * PI * u).collect();
        x[0].sin() + 7.0 * x[1].sin().powi(2) + 0.1 * x[2].powi(4) * x[0].sin()
    }

    /// The Ishigami function's closed-form indices (a = 7, b = 0.1) lie in the estimator's
    /// bootstrap intervals at N = 2^14, and the estimate is near them.
    #[test]
    fn ishigami_indices_match_the_closed_form() {
        let d = SaltelliDesign::new(1 << 14, 3, 11).unwrap();
        let y = outputs(&d, ishigami);
        let est = estimate_with_intervals(&y, d.n, 3, 200, 5, 0.99).unwrap();
        let first = [0.3139, 0.4424, 0.0];
        let total = [0.5576, 0.4424, 0.2437];
        for i in 0..3 {
            let e = est[i];
            // The closed forms are given to 4 digits: widen by their rounding.
            let near = |ci: Interval, v: f64| ci.lo - 5e-5 <= v && v <= ci.hi + 5e-5;
            assert!(near(e.first_ci, first[i]), "S{} {e:?}", i + 1);
            assert!(near(e.total_ci, total[i]), "ST{} {e:?}", i + 1);
            assert!((e.first - first[i]).abs() < 0.02 && (e.total - total[i]).abs() < 0.02);
        }
    }

    /// A linear model of independent uniforms: S_i = ST_i = c_i^2 v_i / sum c_j^2 v_j, and a
    /// grouped factor (columns 2 and 3 together) carries the sum of its members' shares.
    #[test]
    fn linear_model_indices_are_the_variance_shares() {
        let c = [1.0, 2.0, 3.0, 0.5];
        let f = |u: &[f64]| c.iter().zip(u).map(|(c, u)| c * u).sum::<f64>();
        let total: f64 = c.iter().map(|c| c * c).sum();
        let d = SaltelliDesign::new(1 << 14, 4, 3).unwrap();
        let y = outputs(&d, f);
        let est = estimate_with_intervals(&y, d.n, 4, 200, 9, 0.99).unwrap();
        for (i, e) in est.iter().enumerate() {
            let share = c[i] * c[i] / total;
            assert!(e.first_ci.contains(share), "S{i} {share} {e:?}");
            assert!(e.total_ci.contains(share), "ST{i} {share} {e:?}");
        }
        // Groups: factor 0 = column 0, factor 1 = columns 1..4.
        let groups: [&[usize]; 2] = [&[0], &[1, 2, 3]];
        let mut y = Vec::new();
        for r in 0..d.n {
            let (a, b) = (d.a(r), d.b(r));
            y.push(f(&a));
            for g in groups {
                y.push(f(&swap(&a, &b, g)));
            }
            y.push(f(&b));
        }
        let est = estimate(&y, d.n, 2).unwrap();
        let share = (total - 1.0) / total;
        assert!(
            (est[1].0 - share).abs() < 0.01 && (est[1].1 - share).abs() < 0.01,
            "{est:?}"
        );
    }

    #[test]
    fn the_design_is_deterministic_balanced_and_bounded() {
        let d = SaltelliDesign::new(64, 5, 2).unwrap();
        assert_eq!(d.a(7), SaltelliDesign::new(64, 5, 2).unwrap().a(7));
        assert_ne!(d.a(7), SaltelliDesign::new(64, 5, 3).unwrap().a(7));
        // A (0, m, s)-net: each coordinate's 64 values fall one per bin of width 1/64.
        for k in 0..5 {
            let mut bins = [0; 64];
            for r in 0..64 {
                let u = d.b(r)[k];
                assert!((0.0..1.0).contains(&u));
                bins[(u * 64.0) as usize] += 1;
            }
            assert!(bins.iter().all(|&b| b == 1), "dim {k}");
        }
        assert!(SaltelliDesign::new(100, 3, 0).is_err());
        assert!(SaltelliDesign::new(1 << 17, 3, 0).is_err());
        assert!(SaltelliDesign::new(64, 0, 0).is_err());
        assert!(estimate(&[1.0; 9], 2, 3).is_err());
    }

    #[test]
    fn convergence_prefixes_double_up_to_n() {
        let d = SaltelliDesign::new(128, 3, 1).unwrap();
        let y = outputs(&d, ishigami);
        let c = convergence(&y, d.n, 3).unwrap();
        let rows: Vec<usize> = c.iter().map(|(m, _)| *m).collect();
        assert_eq!(rows, [16, 32, 64, 128]);
        assert_eq!(c.last().unwrap().1, estimate(&y, 128, 3).unwrap());
    }
}
