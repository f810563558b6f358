//! Sweeps of designs (`predict --sweep FILE`): a grid or a seeded random sample over ranges.

use super::DesignSpace;
use crate::Error;
use crate::Result;
use std::collections::BTreeMap;
use std::path::Path;

/// How a sweep is written (`predict --sweep FILE`): `base` (optional, values of the parameters
/// not swept; the rest nominal) and exactly one of `grid` (every combination of the listed
/// axes, the last varying fastest; an axis is a list of values or `{from, to, steps}`, evenly
/// spaced, ends included) or `random` (`seed`, `count`, `ranges: {name: [lo, hi]}`: design `i`
/// draws each listed parameter uniformly, in spec order, from the stream
/// `(seed, Parameters, i)`, so a design depends only on the seed and its index).
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepDoc {
    #[serde(default)]
    base: BTreeMap<String, f64>,
    #[serde(default)]
    grid: Option<serde_yaml::Mapping>,
    #[serde(default)]
    random: Option<RandomDoc>,
}

#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RandomDoc {
    seed: u64,
    count: usize,
    ranges: BTreeMap<String, [f64; 2]>,
}

#[derive(Debug, Clone, serde::Deserialize)]
#[serde(untagged)]
enum Axis {
    Values(Vec<f64>),
    Range { from: f64, to: f64, steps: usize },
}

/// Most designs a sweep may produce (a typo in `steps` should not exhaust the memory).
pub const MAX_SWEEP: usize = 10_000_000;

/// Parses a sweep (see the YAML layout above) into designs of `space` (`origin` names the
/// file).
pub fn parse_sweep(space: &DesignSpace, text: &str, origin: &Path) -> Result<Vec<Vec<f64>>> {
    let doc: SweepDoc = serde_yaml::from_str(text).map_err(|e| {
        Error::format(
            origin,
            format!("expected `base:` and one of `grid:` or `random:`: {e}"),
        )
    })?;
    let mut base = space.nominal();
    for (k, v) in &doc.base {
        space.set(&mut base, k, *v, origin)?;
    }
    match (doc.grid, doc.random) {
        (Some(grid), None) => {
            let axes = grid_axes(space, grid, origin)?;
            grid_sets(space, &base, &axes, origin)
        }
        (None, Some(r)) => random_sets(space, &base, &r, origin),
        _ => Err(Error::format(
            origin,
            "give exactly one of `grid:` or `random:`".into(),
        )),
    }
}

/// The axes of a `grid:`: each parameter's index in `space` and its values.
fn grid_axes(
    space: &DesignSpace,
    grid: serde_yaml::Mapping,
    origin: &Path,
) -> Result<Vec<(usize, Vec<f64>)>> {
    let mut axes: Vec<(usize, Vec<f64>)> = Vec::new();
    for (k, v) in grid {
        let name = k
            .as_str()
            .ok_or_else(|| Error::format(origin, format!("grid: key {k:?} is not a name")))?
            .to_owned();
        let axis: Axis = serde_yaml::from_value(v).map_err(|e| {
            Error::format(
                origin,
                format!("grid.{name}: a list of values or {{from, to, steps}}: {e}"),
            )
        })?;
        let values = match axis {
            Axis::Values(v) => v,
            Axis::Range { from, to, steps } => {
                if steps < 1 {
                    return Err(Error::format(
                        origin,
                        format!("grid.{name}.steps = 0: at least 1"),
                    ));
                }
                if steps == 1 {
                    vec![from]
                } else {
                    (0..steps)
                        .map(|i| from + (to - from) * i as f64 / (steps - 1) as f64)
                        .collect()
                }
            }
        };
        if values.is_empty() {
            return Err(Error::format(origin, format!("grid.{name}: no values")));
        }
        axes.push((space.index(&name, origin)?, values));
    }
    Ok(axes)
}

/// Every design of the grid over `axes` from `base` (the last axis varying fastest).
fn grid_sets(
    space: &DesignSpace,
    base: &[f64],
    axes: &[(usize, Vec<f64>)],
    origin: &Path,
) -> Result<Vec<Vec<f64>>> {
    let total = axes
        .iter()
        .try_fold(1usize, |n, (_, v)| n.checked_mul(v.len()))
        .filter(|&n| n <= MAX_SWEEP)
        .ok_or_else(|| Error::format(origin, format!("grid: more than {MAX_SWEEP} designs")))?;
    let mut sets = Vec::with_capacity(total);
    for i in 0..total {
        let mut p = base.to_vec();
        let mut rest = i;
        for (k, values) in axes.iter().rev() {
            let v = values[rest % values.len()];
            rest /= values.len();
            if !v.is_finite() {
                return Err(Error::format(
                    origin,
                    format!("grid.{}: {v} must be finite", space.names()[*k]),
                ));
            }
            p[*k] = v;
        }
        sets.push(p);
    }
    Ok(sets)
}

/// The designs of a `random:` sweep from `base`: design `i` drawn uniformly over the ranges
/// from the stream keyed by (the sweep's seed, parameters, `i`).
fn random_sets(
    space: &DesignSpace,
    base: &[f64],
    r: &RandomDoc,
    origin: &Path,
) -> Result<Vec<Vec<f64>>> {
    if r.count == 0 || r.count > MAX_SWEEP {
        return Err(Error::format(
            origin,
            format!("random.count = {}: allowed 1 ..= {MAX_SWEEP}", r.count),
        ));
    }
    let mut ranges: Vec<(usize, [f64; 2])> = Vec::new();
    for (name, range) in &r.ranges {
        let [lo, hi] = *range;
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(Error::format(
                origin,
                format!("random.ranges.{name} = [{lo}, {hi}]: finite, lo <= hi"),
            ));
        }
        ranges.push((space.index(name, origin)?, *range));
    }
    ranges.sort_by_key(|(k, _)| *k);
    Ok((0..r.count)
        .map(|i| {
            let mut s = mbd_dataset::rng::SampleStream::new(
                r.seed,
                mbd_dataset::rng::Purpose::Parameters,
                i as u64,
            );
            let mut p = base.to_vec();
            for (k, [lo, hi]) in &ranges {
                p[*k] = s.uniform_in(*lo, *hi);
            }
            p
        })
        .collect())
}
