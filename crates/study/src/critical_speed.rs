//! The `critical_speed` study: at each point of a grid over one or two parameters (the yaw
//! dampers' damping and the equivalent conicity, say), the speed at which a growth index
//! turns positive: the lateral oscillation after the irregularity ends feeds itself
//! (hunting). The speed is swept over its training range at `speeds` points; the other
//! parameters stand at their distributions' medians (the centre of the training range unless
//! `parameters:` says otherwise). Every design runs under the same `excitations` tracks
//! (excitation ids `0..excitations` at the study's seed) and its growth is their mean.
//!
//! The critical speed of a sweep is where the mean growth first turns positive, interpolated
//! linearly between that speed and the one before it ([`crossing`]); `below` when it is
//! positive already at the lowest speed, `above` when it never is. With calibrated intervals
//! the same crossing of the mean of the intervals' upper ends gives the lower end of the
//! critical speed's band, that of their lower ends its upper end. The solver sweeps
//! `solver_check` grid points spread over the grid, under the same tracks.

use super::evaluate::{spread, Evaluator};
use super::spec::{CriticalSpeed, Study};
use crate::Result;
use pino_predict::DesignAnswer;
use pino_studies::stats::mean;
use std::time::Instant;

/// Where a sweep's growth turns positive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Crossing {
    /// Already positive at the lowest speed: the critical speed is at or below it.
    Below,
    /// Between two speeds of the sweep, interpolated (the speed's unit).
    At(f64),
    /// Never positive: the critical speed is above the highest speed.
    Above,
    /// A growth of the sweep is missing (a failed or non-finite answer).
    Unknown,
}

impl Crossing {
    /// Its name in tables (`below`, `crossing`, `above`, `unknown`).
    pub fn state(self) -> &'static str {
        match self {
            Self::Below => "below",
            Self::At(_) => "crossing",
            Self::Above => "above",
            Self::Unknown => "unknown",
        }
    }

    /// The interpolated speed (NaN unless [`Crossing::At`]).
    pub fn speed(self) -> f64 {
        match self {
            Self::At(v) => v,
            _ => f64::NAN,
        }
    }
}

/// The crossing of `growth` over increasing `speeds`: the first positive value `g_k` and the
/// one before it (`g_{k-1} <= 0`) give `v_{k-1} - g_{k-1} (v_k - v_{k-1}) / (g_k - g_{k-1})`.
pub fn crossing(speeds: &[f64], growth: &[f64]) -> Crossing {
    if growth.iter().any(|g| !g.is_finite()) {
        return Crossing::Unknown;
    }
    match growth.iter().position(|&g| g > 0.0) {
        None => Crossing::Above,
        Some(0) => Crossing::Below,
        Some(k) => {
            let (g0, g1) = (growth[k - 1], growth[k]);
            let (v0, v1) = (speeds[k - 1], speeds[k]);
            Crossing::At(v0 - g0 * (v1 - v0) / (g1 - g0))
        }
    }
}

/// Per grid point, per speed, per excitation: a value of the growth (or its interval's ends).
pub type PerRun<T> = Vec<Vec<Vec<T>>>;

/// Per grid point, per speed: a mean over the excitations.
pub type PerSpeed = Vec<Vec<f64>>;

/// One side's sweeps (the surrogate's or the solver's) over some grid points.
#[derive(Debug, Clone)]
pub struct Sweeps {
    /// The grid points (positions in [`CriticalSpeedStudy::points`]).
    pub cells: Vec<usize>,
    /// Per grid point, per speed: the growth under each excitation.
    pub growth: PerRun<f64>,
    /// The calibrated intervals' ends of the same, when the side has them (`(lo, hi)`).
    pub bounds: Option<PerRun<(f64, f64)>>,
    /// Per grid point, why a run of its sweep has no answer (the first such), if one has not.
    pub failures: Vec<Option<String>>,
}

impl Sweeps {
    /// Per grid point, per speed: the mean growth over the excitations.
    pub fn mean(&self) -> PerSpeed {
        self.growth
            .iter()
            .map(|cell| cell.iter().map(|v| mean(v)).collect())
            .collect()
    }

    /// Per grid point, per speed: the mean of the intervals' lower and upper ends.
    pub fn mean_bounds(&self) -> Option<(PerSpeed, PerSpeed)> {
        let b = self.bounds.as_ref()?;
        let side = |hi: bool| {
            b.iter()
                .map(|cell| {
                    cell.iter()
                        .map(|v| {
                            mean(
                                &v.iter()
                                    .map(|p| if hi { p.1 } else { p.0 })
                                    .collect::<Vec<_>>(),
                            )
                        })
                        .collect()
                })
                .collect()
        };
        Some((side(false), side(true)))
    }

    /// Per grid point: the crossing of the mean growth.
    pub fn critical(&self, speeds: &[f64]) -> Vec<Crossing> {
        self.mean().iter().map(|g| crossing(speeds, g)).collect()
    }

    /// Per grid point: the band of the critical speed, `(from the upper ends, from the lower
    /// ends)`: the upper ends turn positive first.
    pub fn critical_band(&self, speeds: &[f64]) -> Option<Vec<(Crossing, Crossing)>> {
        let (lo, hi) = self.mean_bounds()?;
        Some(
            hi.iter()
                .zip(&lo)
                .map(|(h, l)| (crossing(speeds, h), crossing(speeds, l)))
                .collect(),
        )
    }
}

/// A critical-speed study's results.
#[derive(Debug, Clone)]
pub struct CriticalSpeedStudy {
    /// The sweep's declaration.
    pub spec: CriticalSpeed,
    /// The grid points: the grid parameters' values (declaration order), first parameter
    /// outermost.
    pub points: Vec<Vec<f64>>,
    /// The speeds of the sweep (increasing).
    pub speeds: Vec<f64>,
    /// Every parameter's value at the grid's first point and lowest speed (the others
    /// differ only in the grid parameters and the speed; model parameter order).
    pub base: Vec<f64>,
    /// The surrogate's sweeps (every grid point).
    pub surrogate: Sweeps,
    /// The solver's sweeps (the checked grid points).
    pub solver: Sweeps,
    /// Wall time of the surrogate's evaluations (s).
    pub surrogate_s: f64,
    /// Wall time of the solver's (s).
    pub solver_s: f64,
}

impl CriticalSpeedStudy {
    /// Surrogate evaluations made.
    pub fn surrogate_runs(&self) -> usize {
        self.points.len() * self.speeds.len() * self.spec.excitations
    }

    /// Solver runs made.
    pub fn solver_runs(&self) -> usize {
        self.solver.cells.len() * self.speeds.len() * self.spec.excitations
    }
}

/// `n` points from `lo` to `hi`, ends included.
fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
        .collect()
}

/// The grid points of `grid` (each parameter's points over its range), first outermost.
fn grid_points(axes: &[Vec<f64>]) -> Vec<Vec<f64>> {
    axes.iter().fold(vec![Vec::new()], |acc, axis| {
        acc.iter()
            .flat_map(|p| {
                axis.iter().map(move |&x| {
                    let mut q = p.clone();
                    q.push(x);
                    q
                })
            })
            .collect()
    })
}

/// Runs the critical-speed study `spec` of `study`; `parameters` are the model's sampled
/// parameters with their training ranges.
pub fn run(
    ev: &Evaluator<'_>,
    study: &Study,
    spec: &CriticalSpeed,
    parameters: &[(String, [f64; 2])],
) -> Result<CriticalSpeedStudy> {
    let position = |name: &str| {
        parameters
            .iter()
            .position(|(n, _)| n == name)
            .expect("checked by the declaration: a sampled parameter of the model")
    };
    let base: Vec<f64> = study
        .distributions(parameters)
        .iter()
        .map(|d| d.at(0.5))
        .collect();
    let v = position(&spec.speed);
    let speeds = linspace(parameters[v].1[0], parameters[v].1[1], spec.speeds);
    let grid: Vec<usize> = spec.grid.iter().map(|(p, _)| position(p)).collect();
    let axes: Vec<Vec<f64>> = spec
        .grid
        .iter()
        .zip(&grid)
        .map(|((_, n), &k)| linspace(parameters[k].1[0], parameters[k].1[1], *n))
        .collect();
    let points = grid_points(&axes);
    let design = |point: &[f64], speed: f64| {
        let mut d = base.clone();
        for (&k, &x) in grid.iter().zip(point) {
            d[k] = x;
        }
        d[v] = speed;
        d
    };
    let runs = |cells: &[usize]| -> (Vec<Vec<f64>>, Vec<u64>) {
        let mut designs = Vec::new();
        let mut excitation = Vec::new();
        for &c in cells {
            for &s in &speeds {
                for e in 0..spec.excitations as u64 {
                    designs.push(design(&points[c], s));
                    excitation.push(e);
                }
            }
        }
        (designs, excitation)
    };
    let index = ev
        .predictor
        .index_inputs()
        .columns()
        .iter()
        .position(|c| c.name == spec.index)
        .expect("checked by the declaration: an index of the model");
    let all: Vec<usize> = (0..points.len()).collect();
    let (designs, excitation) = runs(&all);
    let t0 = Instant::now();
    let answers = ev.surrogate(&designs, &excitation)?;
    let surrogate_s = t0.elapsed().as_secs_f64();
    let surrogate = surrogate_sweeps(&answers, all, speeds.len(), spec.excitations, index);
    let checked = spread(points.len(), study.solver_check);
    let (designs, excitation) = runs(&checked);
    let t1 = Instant::now();
    let solved = ev.solver(&designs, &excitation)?;
    let solver_s = t1.elapsed().as_secs_f64();
    let per_cell = speeds.len() * spec.excitations;
    let solver = Sweeps {
        growth: nest(&solved, speeds.len(), spec.excitations, |s| {
            s.indices[index]
        }),
        bounds: None,
        failures: solved
            .chunks(per_cell.max(1))
            .map(|cell| cell.iter().find_map(|s| s.failure.clone()))
            .collect(),
        cells: checked,
    };
    Ok(CriticalSpeedStudy {
        spec: spec.clone(),
        base: design(&points[0], speeds[0]),
        points,
        speeds,
        surrogate,
        solver,
        surrogate_s,
        solver_s,
    })
}

/// `f` of every run of a side, in [`run`]'s order (grid point, then speed, then excitation),
/// nested by grid point and speed.
fn nest<R, T>(runs: &[R], speeds: usize, excitations: usize, f: impl Fn(&R) -> T) -> PerRun<T> {
    runs.chunks((speeds * excitations).max(1))
        .map(|cell| {
            cell.chunks(excitations.max(1))
                .map(|r| r.iter().map(&f).collect())
                .collect()
        })
        .collect()
}

/// The surrogate's answers (grid point, then speed, then excitation) as sweeps of index
/// `index`.
fn surrogate_sweeps(
    answers: &[DesignAnswer],
    cells: Vec<usize>,
    speeds: usize,
    excitations: usize,
    index: usize,
) -> Sweeps {
    let calibrated = !answers.is_empty() && answers.iter().all(|a| a.calibrated.is_some());
    let bounds = calibrated.then(|| {
        nest(answers, speeds, excitations, |a| {
            let i = a.calibrated.as_ref().map(|c| c.indices[index]);
            i.map_or((f64::NAN, f64::NAN), |i| (i.lo, i.hi))
        })
    });
    Sweeps {
        growth: nest(answers, speeds, excitations, |a| a.indices.values[index]),
        bounds,
        failures: vec![None; cells.len()],
        cells,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_linear_growth_crosses_at_its_root() {
        let speeds = linspace(300.0, 350.0, 11);
        // g = 0.02 (v - 317.3) 1/s: the root between two sweep points is found exactly.
        let g: Vec<f64> = speeds.iter().map(|v| 0.02 * (v - 317.3)).collect();
        let Crossing::At(v) = crossing(&speeds, &g) else {
            panic!("{:?}", crossing(&speeds, &g));
        };
        assert!((v - 317.3).abs() < 1e-9, "{v}");
        // A growth that stays at 0 (within its standard errors) and then turns positive:
        // the crossing is the last speed without growth.
        let flat = [0.0, 0.0, 0.0, 0.4, 0.9];
        assert_eq!(
            crossing(&[1.0, 2.0, 3.0, 4.0, 5.0], &flat),
            Crossing::At(3.0)
        );
    }

    #[test]
    fn sweeps_without_a_root_say_where_it_lies() {
        let speeds = [300.0, 325.0, 350.0];
        assert_eq!(crossing(&speeds, &[-0.3, -0.2, 0.0]), Crossing::Above);
        assert_eq!(crossing(&speeds, &[0.1, 0.2, 0.3]), Crossing::Below);
        assert_eq!(crossing(&speeds, &[-0.1, f64::NAN, 0.3]), Crossing::Unknown);
        assert_eq!(Crossing::Above.state(), "above");
        assert!(Crossing::Below.speed().is_nan());
    }

    #[test]
    fn the_grid_runs_its_first_parameter_outermost() {
        let p = grid_points(&[vec![1.0, 2.0], vec![10.0, 20.0, 30.0]]);
        assert_eq!(p.len(), 6);
        assert_eq!(p[0], [1.0, 10.0]);
        assert_eq!(p[2], [1.0, 30.0]);
        assert_eq!(p[3], [2.0, 10.0]);
        assert_eq!(linspace(0.05, 0.4, 8)[7], 0.4);
    }

    #[test]
    fn the_band_comes_from_the_intervals_ends() {
        let speeds = [300.0, 310.0, 320.0, 330.0];
        // One grid point, two excitations: growth crosses at 315; the upper ends (growth +
        // 0.1) cross earlier, the lower ends (growth - 0.1) later.
        let g = |v: f64| 0.01 * (v - 315.0);
        let growth = vec![speeds.iter().map(|&v| vec![g(v), g(v)]).collect()];
        let bounds = vec![speeds
            .iter()
            .map(|&v| vec![(g(v) - 0.1, g(v) + 0.1); 2])
            .collect()];
        let s = Sweeps {
            cells: vec![0],
            growth,
            bounds: Some(bounds),
            failures: vec![None],
        };
        let Crossing::At(v) = s.critical(&speeds)[0] else {
            panic!()
        };
        assert!((v - 315.0).abs() < 1e-9);
        let (early, late) = s.critical_band(&speeds).unwrap()[0];
        assert!((early.speed() - 305.0).abs() < 1e-9, "{early:?}");
        assert!((late.speed() - 325.0).abs() < 1e-9, "{late:?}");
    }
}
