//! The profiles under the elements, each part read once per position and evaluation.
//!
//! An element on a moving point reads its profile there (`eta`, and its rate where the force or
//! a stored column needs it). Several elements often read the same thing at one position: a
//! wheelset's two wheels (two moving points, one on each rail, at one offset from the frame)
//! read the track's vertical profile and its cross-level through the two rails' combinations
//! (`rail_left = vertical - cross_level / 2`, `rail_right = vertical + cross_level / 2`), a
//! rail's two lateral fastenings at a wheel read the alignment. Here a model's profiles are
//! split into their parts (a combination's terms, which a description keeps to generated and
//! harmonic profiles; any other profile is its own part), the distinct `(part, offset)` reads
//! are listed once at assembly, and each evaluation reads each of them once (level and slope
//! from one cell search where a rate is needed), then combines them per element. The values
//! are those of [`ProfileSource::ramped`] and [`ProfileSource::ramped_rate`] to the bit: points
//! at one offset are at one `x`, and a combination's level and slope are summed term by term in
//! its order, as [`ProfileSource::at`] sums them.

use crate::profile::ProfileSource;
use mbd_system::model::{Model, ModelEnd, ModelProfile};

/// One distinct read: a part (a profile that is no combination) at a moving point (the first
/// of those at its offset from the frame).
#[derive(Debug, Clone, PartialEq)]
struct Read {
    part: usize,
    point: usize,
    /// Whether its slope is needed too.
    slope: bool,
}

/// How an element's profile combines the reads.
#[derive(Debug, Clone)]
enum Combine {
    /// A profile that is one part.
    One(usize),
    /// A combination: `sum_k w_k part_k`, the weights and reads in the combination's order.
    Sum(Vec<(f64, usize)>),
}

/// The element's reading: what it combines and whether its rate is evaluated.
#[derive(Debug, Clone)]
struct ElementRead {
    element: usize,
    combine: Combine,
    rate: bool,
}

/// Where and how [`ProfileReads::evaluate`] reads.
pub(crate) struct Evaluation<'a> {
    pub(crate) point_x: &'a [f64],
    pub(crate) eta: &'a mut [f64],
    pub(crate) eta_rate: &'a mut [f64],
    pub(crate) ramp: f64,
    pub(crate) ramp_rate: f64,
    pub(crate) speed: f64,
}

/// The compiled profile reads of a model (built once per engine).
#[derive(Debug, Clone)]
pub(crate) struct ProfileReads {
    reads: Vec<Read>,
    elements: Vec<ElementRead>,
}

impl ProfileReads {
    /// The reads of `model`'s elements on moving points with a profile; `rate[e]` says whether
    /// element `e`'s profile rate is evaluated.
    pub(crate) fn of(model: &Model, rate: &[bool]) -> Self {
        let mut reads: Vec<Read> = Vec::new();
        let mut elements = Vec::new();
        for (e, el) in model.elements.iter().enumerate() {
            let (Some(p), ModelEnd::Moving(point)) = (el.profile, el.to) else {
                continue;
            };
            let mut read_of = |part: usize| {
                // Points at one offset from the frame (a wheelset's two wheels) are at one `x`.
                let offset = model.points[point].1;
                match reads
                    .iter()
                    .position(|r| r.part == part && model.points[r.point].1 == offset)
                {
                    Some(i) => {
                        reads[i].slope |= rate[e];
                        i
                    }
                    None => {
                        reads.push(Read {
                            part,
                            point,
                            slope: rate[e],
                        });
                        reads.len() - 1
                    }
                }
            };
            let combine = match &model.profiles[p] {
                ModelProfile::Combination(terms) => {
                    Combine::Sum(terms.iter().map(|&(part, w)| (w, read_of(part))).collect())
                }
                _ => Combine::One(read_of(p)),
            };
            elements.push(ElementRead {
                element: e,
                combine,
                rate: rate[e],
            });
        }
        Self { reads, elements }
    }

    /// Writes `eta[e]` (m; and `eta_rate[e]`, m/s, where evaluated) of every element `e`
    /// reading a profile of `sources` (the engine's, one per model profile), at the moving points' positions `point_x` (m), under the start-up
    /// factor `ramp` and its rate `ramp_rate` (1/s) at `speed` (m/s). `scratch` keeps the
    /// reads' values (resized on the first call).
    pub(crate) fn evaluate(
        &self,
        sources: &[ProfileSource],
        at: Evaluation<'_>,
        scratch: &mut Vec<[f64; 2]>,
    ) {
        let Evaluation {
            point_x,
            eta,
            eta_rate,
            ramp,
            ramp_rate,
            speed,
        } = at;
        scratch.resize(self.reads.len(), [0.0; 2]);
        for (value, r) in scratch.iter_mut().zip(&self.reads) {
            let x = point_x[r.point];
            let part = &sources[r.part];
            *value = if r.slope {
                let (at, slope) = part.at_and_slope(x);
                [at, slope]
            } else {
                [part.at(x), 0.0]
            };
        }
        for el in &self.elements {
            let [at, slope] = match &el.combine {
                Combine::One(r) => scratch[*r],
                Combine::Sum(terms) => [
                    terms.iter().map(|&(w, r)| w * scratch[r][0]).sum(),
                    if el.rate {
                        terms.iter().map(|&(w, r)| w * scratch[r][1]).sum()
                    } else {
                        0.0
                    },
                ],
            };
            eta[el.element] = if ramp > 0.0 { ramp * at } else { 0.0 };
            if el.rate {
                eta_rate[el.element] = ramp * speed * slope + ramp_rate * at;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::Profile;
    use mbd_system::schema::Interpolation;

    fn points(seed: u64) -> ProfileSource {
        let x: Vec<f64> = (0..40).map(|i| i as f64 * 0.5).collect();
        let eta: Vec<f64> = x
            .iter()
            .map(|&x| 1e-3 * ((0.7 + seed as f64) * x).sin() + 2e-4 * (3.1 * x).cos())
            .collect();
        ProfileSource::Points(
            Profile::new(x, eta)
                .unwrap()
                .interpolated(Interpolation::Cubic)
                .unwrap(),
        )
    }

    /// Level and slope from one cell search equal the two separate reads to the bit, inside,
    /// on the points, in the fade of an ending profile and beyond both ends.
    #[test]
    fn level_and_slope_together_equal_each_alone() {
        let until = ProfileSource::Until {
            inner: Box::new(points(1)),
            end: 15.0,
            taper: 4.0,
        };
        let sum = ProfileSource::Sum(vec![(1.0, until.clone()), (-0.5, points(2))]);
        let linear = match points(3) {
            ProfileSource::Points(p) => {
                ProfileSource::Points(p.interpolated(Interpolation::Linear).unwrap())
            }
            _ => unreachable!(),
        };
        for source in [points(0), until, sum, linear] {
            for i in -20..460 {
                let x = i as f64 * 0.05 + 0.013 * (i % 3) as f64;
                let (at, slope) = source.at_and_slope(x);
                assert_eq!(at.to_bits(), source.at(x).to_bits(), "level at {x}");
                assert_eq!(slope.to_bits(), source.slope(x).to_bits(), "slope at {x}");
            }
        }
    }
}
