//! Split conformal coverage on synthetic exchangeable data with a known noise law.
//!
//! `x ~ U(0, 1)`, `y = f(x) + (0.2 + x) xi`, `xi ~ N(0, 1)`, the model `f` exact. Plain scores
//! `|y - f|`; normalised scores `|y - f| / sigma(x)` with `sigma = 0.2 + x`. Over `R`
//! repetitions (a fresh calibration set of `n` and `M` fresh test points each), the mean
//! coverage must lie in `[1 - alpha, 1 - alpha + 1 / (n + 1)]` (for continuous scores it is
//! exactly `k / (n + 1)`, `k = ceil((n + 1)(1 - alpha))`), up to the noise of the estimate:
//! the tolerance is 4 standard errors of the mean over repetitions, the standard error taken
//! from the repetitions' own spread (Beta-binomial: calibration draw plus test draw).

use mbd_dataset::SampleStream;
use pino_conformal::ScoreSet;

const REPETITIONS: usize = 2000;
const TEST_POINTS: usize = 50;

struct Draw {
    x: f64,
    residual: f64,
}

fn draw(s: &mut SampleStream) -> Draw {
    let x = s.uniform();
    Draw {
        x,
        residual: (0.2 + x) * s.normal(),
    }
}

fn sigma(x: f64) -> f64 {
    0.2 + x
}

/// Mean and standard error of the coverage over repetitions, and the coverage of the test
/// points with `x` below and above 0.5 (pooled).
fn coverage(n: usize, level: f64, normalised: bool, seed: u64) -> (f64, f64, [f64; 2]) {
    let scale = |d: &Draw| if normalised { sigma(d.x) } else { 1.0 };
    let mut per_rep = Vec::with_capacity(REPETITIONS);
    let mut bins = [[0usize; 2]; 2];
    for rep in 0..REPETITIONS {
        let mut s = SampleStream::with_code(seed, 900, rep as u64);
        let scores: Vec<f64> = (0..n)
            .map(|_| {
                let d = draw(&mut s);
                d.residual.abs() / scale(&d)
            })
            .collect();
        let q = ScoreSet::new(scores).unwrap().quantile(level).unwrap();
        let mut inside = 0;
        for _ in 0..TEST_POINTS {
            let d = draw(&mut s);
            let hit = d.residual.abs() <= q * scale(&d);
            inside += hit as usize;
            let b = (d.x >= 0.5) as usize;
            bins[b][0] += hit as usize;
            bins[b][1] += 1;
        }
        per_rep.push(inside as f64 / TEST_POINTS as f64);
    }
    let r = per_rep.len() as f64;
    let mean = per_rep.iter().sum::<f64>() / r;
    let var = per_rep.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (r - 1.0);
    let bin = |b: usize| bins[b][0] as f64 / bins[b][1] as f64;
    (mean, (var / r).sqrt(), [bin(0), bin(1)])
}

fn check(n: usize, level: f64, normalised: bool) -> [f64; 2] {
    let (mean, se, bins) = coverage(n, level, normalised, 17);
    let tol = 4.0 * se;
    let (lo, hi) = (level, level + 1.0 / (n as f64 + 1.0));
    assert!(
        mean >= lo - tol && mean <= hi + tol,
        "n = {n}, level {level}, normalised {normalised}: mean coverage {mean:.4} outside [{lo:.4}, {hi:.4}] +- {tol:.4}"
    );
    let k = ScoreSet::new(vec![0.0; n]).unwrap().rank(level).unwrap();
    let exact = k as f64 / (n as f64 + 1.0);
    assert!(
        (mean - exact).abs() <= tol,
        "n = {n}, level {level}: mean coverage {mean:.4}, expected k / (n + 1) = {exact:.4} +- {tol:.4}"
    );
    bins
}

#[test]
fn plain_scores_cover_at_the_stated_level() {
    for (n, level) in [(19, 0.9), (200, 0.9), (200, 0.8), (40, 0.95)] {
        check(n, level, false);
    }
}

#[test]
fn normalised_scores_cover_at_the_stated_level_and_conditionally_better() {
    for (n, level) in [(19, 0.9), (200, 0.9), (200, 0.95)] {
        check(n, level, true);
    }
    // Conditional coverage: constant-width intervals over-cover where the noise is small and
    // under-cover where it is large; scores normalised by the true noise law do neither.
    let plain = check(200, 0.9, false);
    let normalised = check(200, 0.9, true);
    assert!(plain[0] > 0.95 && plain[1] < 0.86, "plain by bin {plain:?}");
    assert!(
        normalised.iter().all(|c| (c - 0.9).abs() < 0.01),
        "normalised by bin {normalised:?}"
    );
}
