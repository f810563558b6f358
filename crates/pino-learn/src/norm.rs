//! Z-score statistics per channel: `x_n = (x - mean) / std`, computed over the training split
//! only and stored with the model, so validation and prediction use them unchanged.
//!
//! [`StatsAccumulator`] builds the same statistics sample by sample (streaming): each block's
//! per-channel count, mean and sum of squared deviations are computed exactly (two passes
//! over the block) and merged with the pairwise update of Chan, Golub and LeVeque, in f64, so
//! the result equals [`ChannelStats::from_blocks`] to round-off without holding the data.
//!
//! A channel that is constant over the training split (std below 1e-9 of its magnitude, e.g.
//! the rail displacement of a rigid-track dataset) gets std = 1 so that it stays finite.

use serde::{Deserialize, Serialize};

/// Mean and standard deviation of named channels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelStats {
    /// Channel names.
    pub names: Vec<String>,
    /// Means, physical units.
    pub mean: Vec<f64>,
    /// Standard deviations, physical units (> 0).
    pub std: Vec<f64>,
}

impl ChannelStats {
    /// Statistics of row-major `[rows, names.len()]` blocks, all rows weighted equally.
    pub fn from_blocks<'a>(
        names: &[&str],
        blocks: impl Iterator<Item = &'a [f64]> + Clone,
    ) -> Self {
        let c = names.len();
        let mut sum = vec![0.0; c];
        let mut n = 0usize;
        for b in blocks.clone() {
            for row in b.chunks_exact(c) {
                for (s, x) in sum.iter_mut().zip(row) {
                    *s += x;
                }
                n += 1;
            }
        }
        let n = n.max(1) as f64;
        let mean: Vec<f64> = sum.iter().map(|s| s / n).collect();
        let mut var = vec![0.0; c];
        for b in blocks {
            for row in b.chunks_exact(c) {
                for ((v, x), m) in var.iter_mut().zip(row).zip(&mean) {
                    *v += (x - m) * (x - m);
                }
            }
        }
        let std = var
            .iter()
            .zip(&mean)
            .map(|(v, m)| {
                let s = (v / n).sqrt();
                if s > 1e-9 * m.abs() && s > 0.0 {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        Self {
            names: names.iter().map(|s| s.to_string()).collect(),
            mean,
            std,
        }
    }

    /// Number of channels.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether there are no channels.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Normalises a row-major `[rows, C]` block into f32.
    pub fn normalise(&self, block: &[f64]) -> Vec<f32> {
        let c = self.len();
        block
            .iter()
            .enumerate()
            .map(|(i, x)| ((x - self.mean[i % c]) / self.std[i % c]) as f32)
            .collect()
    }

    /// Back to physical units.
    pub fn denormalise(&self, block: &[f32]) -> Vec<f64> {
        let c = self.len();
        block
            .iter()
            .enumerate()
            .map(|(i, x)| *x as f64 * self.std[i % c] + self.mean[i % c])
            .collect()
    }

    /// The first `k` channels.
    pub fn head(&self, k: usize) -> Self {
        Self {
            names: self.names[..k].to_vec(),
            mean: self.mean[..k].to_vec(),
            std: self.std[..k].to_vec(),
        }
    }
}

/// Streaming per-channel mean and variance (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct StatsAccumulator {
    names: Vec<String>,
    n: f64,
    mean: Vec<f64>,
    m2: Vec<f64>,
}

impl StatsAccumulator {
    /// An empty accumulator over `names`.
    pub fn new(names: &[&str]) -> Self {
        Self {
            names: names.iter().map(|s| s.to_string()).collect(),
            n: 0.0,
            mean: vec![0.0; names.len()],
            m2: vec![0.0; names.len()],
        }
    }

    /// Merges channel `c`'s block statistics `(n, mean, m2)`.
    fn merge(&mut self, c: usize, nb: f64, mb: f64, m2b: f64, n_total: f64) {
        let na = self.n;
        let delta = mb - self.mean[c];
        self.mean[c] += delta * nb / n_total;
        self.m2[c] += m2b + delta * delta * na * nb / n_total;
    }

    /// Adds a row-major `[rows, C]` block.
    pub fn add_block(&mut self, block: &[f64]) {
        let c = self.names.len();
        let rows = block.len() / c;
        if rows == 0 {
            return;
        }
        let columns: Vec<Vec<f64>> = (0..c)
            .map(|k| block.chunks_exact(c).map(|r| r[k]).collect())
            .collect();
        let refs: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
        self.add_columns(&refs);
    }

    /// Adds one block given column by column (every column the same length).
    pub fn add_columns(&mut self, columns: &[&[f64]]) {
        let rows = columns.first().map_or(0, |c| c.len());
        if rows == 0 {
            return;
        }
        let nb = rows as f64;
        let n_total = self.n + nb;
        for (k, col) in columns.iter().enumerate() {
            let mb = col.iter().sum::<f64>() / nb;
            let m2b: f64 = col.iter().map(|x| (x - mb) * (x - mb)).sum();
            self.merge(k, nb, mb, m2b, n_total);
        }
        self.n = n_total;
    }

    /// Adds `rows` rows whose channel `k` is the constant `values[k]` (a per-sample
    /// parameter repeated at every time step, without materialising it).
    pub fn add_constant(&mut self, values: &[f64], rows: usize) {
        if rows == 0 {
            return;
        }
        let nb = rows as f64;
        let n_total = self.n + nb;
        for (k, &v) in values.iter().enumerate() {
            self.merge(k, nb, v, 0.0, n_total);
        }
        self.n = n_total;
    }

    /// Concatenates the channels of `other` (same row count) after these.
    pub fn join(mut self, other: StatsAccumulator) -> Self {
        debug_assert_eq!(self.n, other.n);
        self.names.extend(other.names);
        self.mean.extend(other.mean);
        self.m2.extend(other.m2);
        self
    }

    /// The statistics (std 1 for a constant channel, as [`ChannelStats::from_blocks`]).
    pub fn finish(&self) -> ChannelStats {
        let n = self.n.max(1.0);
        let std = self
            .m2
            .iter()
            .zip(&self.mean)
            .map(|(v, m)| {
                let s = (v.max(0.0) / n).sqrt();
                if s > 1e-9 * m.abs() && s > 0.0 {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        ChannelStats {
            names: self.names.clone(),
            mean: self.mean.clone(),
            std,
        }
    }
}

/// The statistics a model carries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Normalisation {
    /// The 19 inputs (`t`, `eta_1..4`, 14 parameters).
    pub inputs: ChannelStats,
    /// The 18 outputs (14 displacements, 4 contact forces).
    pub outputs: ChannelStats,
    /// The 10 vehicle velocities (`_v`).
    pub velocities: ChannelStats,
    /// The 10 vehicle accelerations (`_a`).
    pub accelerations: ChannelStats,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_are_exact_and_round_trip() {
        let a = [1.0, 10.0, 3.0, 10.0];
        let b = [5.0, 10.0];
        let s = ChannelStats::from_blocks(&["x", "c"], [&a[..], &b[..]].into_iter());
        // x = {1, 3, 5}: mean 3, population std sqrt(8/3); c is constant -> std 1.
        assert_eq!(s.mean, vec![3.0, 10.0]);
        assert!((s.std[0] - (8.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(s.std[1], 1.0);
        let n = s.normalise(&a);
        let back = s.denormalise(&n);
        // f32 storage: relative 6e-8 of the normalised value.
        for (x, y) in a.iter().zip(back) {
            assert!((x - y).abs() < 1e-6, "{x} {y}");
        }
    }

    #[test]
    fn streaming_accumulator_equals_the_two_pass_statistics() {
        // Three blocks of two channels with a large offset (cancellation-prone) and a
        // constant channel; the accumulator must match from_blocks to round-off.
        let blocks: Vec<Vec<f64>> = (0..3)
            .map(|b| {
                (0..50)
                    .flat_map(|r| {
                        let x = 1e6 + (r as f64 * 0.37 + b as f64).sin();
                        [x, 4.0]
                    })
                    .collect()
            })
            .collect();
        let exact = ChannelStats::from_blocks(&["x", "c"], blocks.iter().map(Vec::as_slice));
        let mut acc = StatsAccumulator::new(&["x", "c"]);
        for b in &blocks {
            acc.add_block(b);
        }
        let got = acc.finish();
        assert!((got.mean[0] - exact.mean[0]).abs() < 1e-15 * exact.mean[0]);
        assert!((got.std[0] - exact.std[0]).abs() < 1e-9 * exact.std[0]);
        assert_eq!((got.mean[1], got.std[1]), (4.0, 1.0));
        // A constant block equals the same block materialised.
        let mut a = StatsAccumulator::new(&["p", "q"]);
        a.add_constant(&[2.0, 3.0], 10);
        a.add_constant(&[4.0, 3.0], 30);
        let mut b = StatsAccumulator::new(&["p", "q"]);
        let rows: Vec<f64> = (0..40)
            .flat_map(|r| [if r < 10 { 2.0 } else { 4.0 }, 3.0])
            .collect();
        b.add_block(&rows);
        let (a, b) = (a.finish(), b.finish());
        assert!((a.mean[0] - 3.5).abs() < 1e-15 && (a.std[0] - b.std[0]).abs() < 1e-15);
        assert_eq!(a.std[1], 1.0);
    }
}
