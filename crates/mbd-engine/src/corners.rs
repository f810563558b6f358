//! The corners of the box of sampling ranges: the designs at which the checks over the whole
//! box (the time-step bound, [`crate::stability::parameter_box`]; the profile starts and
//! reaches, [`crate::coverage`]) assemble and examine a model.
//!
//! Each check asks where a few quantities of a corner's model are largest (the frequency and
//! damping bounds; per element, how far back and how far ahead it reads its profile). Up to
//! [`ALL_CORNERS_UP_TO`] sampled parameters every corner is visited. Beyond, the corner each
//! quantity is largest at is searched for ([`largest_corners`]): each parameter's direction is
//! read from a one-at-a-time probe (every parameter at its minimum, then each alone at its
//! maximum), the corner that takes every parameter in its direction is visited, and single
//! parameters are flipped from there as long as one raises the quantity. When a quantity moves
//! monotonically with each parameter, in a direction the other parameters do not turn (as the
//! bound's terms and the positions read do), the probe's corner is the largest, and the flips
//! confirm it; they also climb past an interaction the probe misreads. About `2 n` models are
//! assembled instead of `2^n`.

use crate::Result;
use rayon::prelude::*;
use std::collections::HashMap;

/// Most sampled parameters for which the box checks visit every corner (`2^10` models).
pub const ALL_CORNERS_UP_TO: usize = 10;

/// The design at corner `mask` of `system`'s box of sampling ranges (`ranges`:
/// [`mbd_system::System::ranges`]; bit `j % 64` of `mask` set: parameter `j` at its maximum).
pub fn corner_values(
    system: &mbd_system::System,
    ranges: &[[f64; 2]],
    mask: u64,
) -> mbd_system::Sampled {
    let values: Vec<f64> = ranges
        .iter()
        .enumerate()
        .map(|(j, r)| r[((mask >> (j % 64)) & 1) as usize])
        .collect();
    system
        .sampled_values(values)
        .expect("one sampling range per sampled parameter")
}

/// For each of the quantities `eval` gives at a corner (as many at every corner) of a box of
/// `n` parameters, its largest value over the corners and the corner (mask, as
/// [`corner_values`] reads it) that gives it: every corner up to [`ALL_CORNERS_UP_TO`]
/// parameters (the first corner in mask order at a tie), else the search of the module's
/// documentation. The first error of a corner (in mask order when all are visited) is
/// returned.
pub fn largest_corners(
    n: usize,
    eval: impl Fn(u64) -> Result<Vec<f64>> + Sync,
) -> Result<Vec<(f64, u64)>> {
    largest_corners_up_to(n, ALL_CORNERS_UP_TO, &eval)
}

/// [`largest_corners`], visiting every corner up to `all_up_to` parameters.
pub(crate) fn largest_corners_up_to(
    n: usize,
    all_up_to: usize,
    eval: &(dyn Fn(u64) -> Result<Vec<f64>> + Sync),
) -> Result<Vec<(f64, u64)>> {
    if n <= all_up_to {
        every_corner(n, eval)
    } else {
        searched_corners(n.min(64), eval)
    }
}

/// Every corner, in mask order; per quantity the first corner with the largest value.
fn every_corner(
    n: usize,
    eval: &(dyn Fn(u64) -> Result<Vec<f64>> + Sync),
) -> Result<Vec<(f64, u64)>> {
    let values = in_order((0..1u64 << n).into_par_iter().map(eval).collect())?;
    let mut best: Vec<(f64, u64)> = values[0].iter().map(|&v| (v, 0)).collect();
    for (mask, v) in values.iter().enumerate().skip(1) {
        for (b, &x) in best.iter_mut().zip(v) {
            if x > b.0 {
                *b = (x, mask as u64);
            }
        }
    }
    Ok(best)
}

/// The values of corners evaluated in parallel, or the first error in their order.
fn in_order(values: Vec<Result<Vec<f64>>>) -> Result<Vec<Vec<f64>>> {
    values.into_iter().collect()
}

/// The probe and ascent of the module's documentation over `n` (at most 64) parameters.
fn searched_corners(
    n: usize,
    eval: &(dyn Fn(u64) -> Result<Vec<f64>> + Sync),
) -> Result<Vec<(f64, u64)>> {
    let mut seen: HashMap<u64, Vec<f64>> = HashMap::new();
    let visit = |masks: Vec<u64>, seen: &mut HashMap<u64, Vec<f64>>| -> Result<()> {
        let new: Vec<u64> = masks
            .into_iter()
            .filter(|m| !seen.contains_key(m))
            .collect();
        let values = in_order(new.par_iter().map(|&m| eval(m)).collect())?;
        seen.extend(new.into_iter().zip(values));
        Ok(())
    };
    let flips = |mask: u64| -> Vec<u64> {
        std::iter::once(mask)
            .chain((0..n).map(|j| mask ^ (1 << j)))
            .collect()
    };
    visit(flips(0), &mut seen)?;
    let quantities = seen[&0].len();
    let mut out = Vec::with_capacity(quantities);
    for q in 0..quantities {
        let base = seen[&0][q];
        let mut mask = (0..n)
            .filter(|&j| seen[&(1 << j)][q] > base)
            .fold(0u64, |m, j| m | 1 << j);
        loop {
            let around = flips(mask);
            visit(around.clone(), &mut seen)?;
            // The neighbour that raises the quantity most (the first at a tie), if one does.
            let mut next = mask;
            for &m in &around[1..] {
                if seen[&m][q] > seen[&next][q] {
                    next = m;
                }
            }
            if next == mask {
                break;
            }
            mask = next;
        }
        out.push((seen[&mask][q], mask));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every corner of `n` parameters, the largest value of each quantity and the first corner
    /// that gives it (the reference the search is held to).
    fn brute(n: usize, f: &(dyn Fn(u64) -> Vec<f64> + Sync)) -> Vec<(f64, u64)> {
        every_corner(n, &|m| Ok(f(m))).unwrap()
    }

    /// Parameter `j`'s value at corner `mask` on the box `[1, 2]^n`.
    fn x(mask: u64, j: usize) -> f64 {
        1.0 + ((mask >> j) & 1) as f64
    }

    /// Quantities monotone in each parameter, in directions that differ between parameters
    /// and between quantities (a sum of stiffness-over-mass terms, a product of lengths, the
    /// least of two), with interactions: the search finds the largest corner and its value,
    /// visiting far fewer than `2^n` models.
    #[test]
    fn the_search_finds_the_largest_corner_of_monotone_quantities() {
        let n = 14;
        let f = |m: u64| -> Vec<f64> {
            let k: f64 = (0..7).map(|j| x(m, j) / x(m, j + 7)).sum();
            let lever = x(m, 0) * x(m, 3) * x(m, 3) / (x(m, 9) * x(m, 12));
            let least = -(x(m, 1) + x(m, 5)).min(3.0 * x(m, 13) - x(m, 2));
            vec![k, lever, least]
        };
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let counted = |m: u64| {
            calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            Ok(f(m))
        };
        let found = largest_corners_up_to(n, 0, &counted).unwrap();
        let want = brute(n, &f);
        for (q, (got, want)) in found.iter().zip(&want).enumerate() {
            assert_eq!(got.0, want.0, "quantity {q}");
            assert_eq!(f(got.1)[q], want.0, "quantity {q} at its corner");
        }
        let calls = calls.into_inner();
        assert!(calls <= 5 * n, "{calls} models");
    }

    /// A quantity whose largest corner is not in the directions of the one-at-a-time probe
    /// (parameter 1 lowers it alone, raises it together with parameter 0): the flips from the
    /// probe's corner find it.
    #[test]
    fn the_ascent_corrects_an_interaction_the_probe_misreads() {
        let f = |m: u64| vec![x(m, 0) * x(m, 1) * 3.0 - 3.5 * x(m, 1) + 0.1 * x(m, 2)];
        let found = largest_corners_up_to(3, 0, &|m| Ok(f(m))).unwrap();
        assert_eq!(found, brute(3, &f));
        assert_eq!(found[0].1, 0b111);
    }

    /// Up to the threshold every corner is visited and ties go to the first corner in mask
    /// order; the first error in mask order is returned.
    #[test]
    fn small_boxes_visit_every_corner() {
        let f = |m: u64| vec![(m.count_ones() as f64).min(2.0)];
        let found = largest_corners(4, |m| Ok(f(m))).unwrap();
        assert_eq!(found, vec![(2.0, 0b0011)]);
        let err = largest_corners(4, |m| {
            if m == 5 || m == 9 {
                Err(crate::Error::Statics {
                    what: format!("corner {m}"),
                })
            } else {
                Ok(f(m))
            }
        });
        assert!(
            matches!(&err, Err(crate::Error::Statics { what }) if what == "corner 5"),
            "{err:?}"
        );
    }
}
