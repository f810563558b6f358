//! Z-score statistics per channel: `x_n = (x - mean) / std`, computed over the training split
//! only and stored with the model, so validation and prediction use them unchanged.
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

/// The statistics a model carries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Normalisation {
    /// The 19 inputs (`t`, `eta_1..4`, 14 parameters).
    pub inputs: ChannelStats,
    /// The 14 outputs.
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
}
