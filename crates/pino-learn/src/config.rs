//! Checked configuration: the five algorithms of the paper's Table 3, model sizes, and the
//! training parameters of the `train` stage (parse, then validate, then run).

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// The algorithms of Table 3 (`docs/learning.md`, Algorithms).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "i64", into = "i64")]
pub enum Algorithm {
    /// 1: FNO, `L_data`, depth 3.
    Fno,
    /// 2: PINO, `L_data + lambda_ode L_ode_global`, depth 3.
    Pino,
    /// 3: PINO-MBD with ODE magnitude weights, `L_data + lambda_ode L_ode_phi`, depth 3.
    PinoMbdWeights,
    /// 4: PINO-MBD with direct derivatives, `L_data + lambda_d L_deriv`, depth 3.
    PinoMbdDerivatives,
    /// 5: as 4 with depth 5.
    PinoMbdDerivativesDeep,
}

impl Algorithm {
    /// All five, in Table 3 order.
    pub const ALL: [Algorithm; 5] = [
        Algorithm::Fno,
        Algorithm::Pino,
        Algorithm::PinoMbdWeights,
        Algorithm::PinoMbdDerivatives,
        Algorithm::PinoMbdDerivativesDeep,
    ];

    /// The Table 3 number (1..=5).
    pub fn id(self) -> i64 {
        match self {
            Algorithm::Fno => 1,
            Algorithm::Pino => 2,
            Algorithm::PinoMbdWeights => 3,
            Algorithm::PinoMbdDerivatives => 4,
            Algorithm::PinoMbdDerivativesDeep => 5,
        }
    }

    /// From the Table 3 number.
    pub fn from_id(id: i64) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|a| a.id() == id)
            .ok_or(Error::UnknownAlgorithm(id))
    }

    /// Human name as in Table 3.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Fno => "FNO",
            Algorithm::Pino => "PINO",
            Algorithm::PinoMbdWeights => "PINO-MBD (ODE weights)",
            Algorithm::PinoMbdDerivatives | Algorithm::PinoMbdDerivativesDeep => {
                "PINO-MBD (direct derivatives)"
            }
        }
    }

    /// Default number of Fourier layers (Table 3).
    pub fn default_depth(self) -> usize {
        match self {
            Algorithm::PinoMbdDerivativesDeep => 5,
            _ => 3,
        }
    }

    /// Whether the loss needs the per-sample ODE magnitude weights phi.
    pub fn needs_phi(self) -> bool {
        self == Algorithm::PinoMbdWeights
    }
}

impl TryFrom<i64> for Algorithm {
    type Error = Error;
    fn try_from(id: i64) -> Result<Self> {
        Self::from_id(id)
    }
}

impl From<Algorithm> for i64 {
    fn from(a: Algorithm) -> i64 {
        a.id()
    }
}

/// Sizes of the Fourier neural operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelConfig {
    /// Input channels (the layout's, `1 + E + P`).
    pub in_channels: usize,
    /// Output channels (the layout's solutions and forces).
    pub out_channels: usize,
    /// Channel width `W` of the Fourier layers.
    pub width: usize,
    /// Retained Fourier modes `M` (lowest, including the mean).
    pub modes: usize,
    /// Number of Fourier layers `L`.
    pub depth: usize,
    /// Hidden width of the projection MLP.
    pub projection_width: usize,
    /// Zeros appended to the time axis inside the network, in percent of the window
    /// (0 = none; models saved before padding existed read as 0).
    #[serde(default)]
    pub padding_percent: usize,
}

impl ModelConfig {
    /// Points of the padded time axis for a window of `t_points`: `T` itself without
    /// padding, else the smallest `2^a 3^b 5^c 7^d >= T (1 + padding/100)` (fast FFT sizes).
    pub fn padded_points(&self, t_points: usize) -> usize {
        if self.padding_percent == 0 {
            return t_points;
        }
        let target = t_points + (t_points * self.padding_percent).div_ceil(100);
        (target..)
            .find(|&n| {
                let mut r = n;
                for p in [2, 3, 5, 7] {
                    while r % p == 0 {
                        r /= p;
                    }
                }
                r == 1
            })
            .expect("smooth numbers are unbounded")
    }

    /// Checks the sizes against each other and against `t_points` time points (the
    /// truncated DFT needs `M <= T/2`).
    pub fn validate(&self, t_points: usize) -> Result<()> {
        let check = |field: &str, value: usize, ok: bool, allowed: String| {
            if ok {
                Ok(())
            } else {
                Err(Error::OutOfRange {
                    field: field.to_owned(),
                    value: value.to_string(),
                    allowed,
                })
            }
        };
        check(
            "width",
            self.width,
            (1..=4096).contains(&self.width),
            "1..=4096".into(),
        )?;
        check(
            "depth",
            self.depth,
            (1..=64).contains(&self.depth),
            "1..=64".into(),
        )?;
        check(
            "projection_width",
            self.projection_width,
            (1..=4096).contains(&self.projection_width),
            "1..=4096".into(),
        )?;
        check(
            "padding",
            self.padding_percent,
            self.padding_percent <= 400,
            "0..=400 (% of the window)".into(),
        )?;
        check(
            "modes",
            self.modes,
            self.modes >= 1 && 2 * self.modes <= t_points,
            format!("1..={} (half the {t_points} time points)", t_points / 2),
        )
    }
}

impl std::fmt::Display for ModelConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "width {} modes {} depth {} projection {} padding {}%",
            self.width, self.modes, self.depth, self.projection_width, self.padding_percent
        )
    }
}

/// Where tensors live.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DeviceKind {
    /// CPU (default; repeatable).
    Cpu,
    /// First CUDA GPU (needs the `cuda` cargo feature).
    Cuda,
}

impl DeviceKind {
    /// The candle device; CUDA without the `cuda` feature is a clear error.
    pub fn device(self) -> Result<candle_core::Device> {
        match self {
            DeviceKind::Cpu => Ok(candle_core::Device::Cpu),
            DeviceKind::Cuda => {
                if cfg!(feature = "cuda") {
                    Ok(candle_core::Device::new_cuda(0)?)
                } else {
                    Err(Error::OutOfRange {
                        field: "device".into(),
                        value: "cuda".into(),
                        allowed: "\"cpu\" (this build has no `cuda` feature; rebuild with --features cuda)".into(),
                    })
                }
            }
        }
    }
}

/// Optimisation and loss parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    /// The algorithm (Table 3).
    pub algorithm: Algorithm,
    /// Passes over the training split.
    pub epochs: usize,
    /// Samples per optimizer step.
    pub batch_size: usize,
    /// Initial Adam learning rate (paper: 5e-4).
    pub learning_rate: f64,
    /// Step-decay factor (paper: 0.75).
    pub lr_decay: f64,
    /// Decay every this many epochs (paper: 30; one scheduler step per epoch).
    pub lr_decay_every: usize,
    /// Weight of the ODE loss (algorithms 2, 3).
    pub lambda_ode: f64,
    /// Weight of the direct-derivative loss (algorithms 4, 5).
    pub lambda_d: f64,
    /// Weight of an extra relative-L2 term on the beam deflections alone (the solutions after
    /// the rigid DOFs: `z_r1..z_r4` of the vehicle-track model; 0 = the paper's loss).
    pub beam_weight: f64,
    /// Target residual level rho of the weighted ODE loss (algorithm 3).
    pub rho: f64,
    /// Seed of initialisation and shuffling.
    pub seed: u64,
    /// Weight of the rate outputs' own relative-L2 term in `L_data` (with `rate_outputs`;
    /// absent: 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate_weight: Option<f64>,
    /// Weight of an extra relative-L2 term on the force outputs alone (the contact forces
    /// `p_1..p_4` of the vehicle-track model, which its peak-force and wheel-load indices
    /// read; absent: 0, the paper's loss).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_weight: Option<f64>,
    /// Decay per step of the weights' moving average ([`crate::optim::Average`]), in
    /// `[0, 1)`: the model validated every epoch and written at the end is the average
    /// (absent: the last iterate, the paper's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub average_decay: Option<f64>,
}

impl TrainConfig {
    /// [`TrainConfig::rate_weight`], 1 when not given.
    pub fn rate_weight(&self) -> f64 {
        self.rate_weight.unwrap_or(1.0)
    }

    /// [`TrainConfig::force_weight`], 0 when not given.
    pub fn force_weight(&self) -> f64 {
        self.force_weight.unwrap_or(0.0)
    }

    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, value: String, allowed: &str| {
            Err(Error::OutOfRange {
                field: field.into(),
                value,
                allowed: allowed.into(),
            })
        };
        if self.epochs == 0 {
            return bad("epochs", "0".into(), ">= 1");
        }
        if self.batch_size == 0 {
            return bad("batch_size", "0".into(), ">= 1");
        }
        if !(self.learning_rate > 0.0 && self.learning_rate.is_finite()) {
            return bad("learning_rate", self.learning_rate.to_string(), "> 0");
        }
        if !(self.lr_decay > 0.0 && self.lr_decay <= 1.0) {
            return bad("lr_decay", self.lr_decay.to_string(), "(0, 1]");
        }
        if self.lr_decay_every == 0 {
            return bad("lr_decay_every", "0".into(), ">= 1 epoch");
        }
        for (f, v) in [
            ("lambda_ode", self.lambda_ode),
            ("lambda_d", self.lambda_d),
            ("beam_weight", self.beam_weight),
            ("rate_weight", self.rate_weight()),
            ("force_weight", self.force_weight()),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return bad(f, v.to_string(), ">= 0");
            }
        }
        if !(self.rho > 0.0 && self.rho.is_finite()) {
            return bad("rho", self.rho.to_string(), "> 0");
        }
        if let Some(d) = self.average_decay.filter(|d| !(0.0..1.0).contains(d)) {
            return bad(
                "average_decay",
                d.to_string(),
                "[0, 1) (absent: no average)",
            );
        }
        Ok(())
    }

    /// Learning rate during epoch `epoch` (0-based): `lr0 * decay^floor(epoch / every)`.
    pub fn lr_at(&self, epoch: usize) -> f64 {
        self.learning_rate * self.lr_decay.powi((epoch / self.lr_decay_every) as i32)
    }
}

fn d_device() -> DeviceKind {
    DeviceKind::Cpu
}

/// The `train` stage's parameters as they appear in pipeline.yaml, every one required (their
/// one home is the pipeline file) except `depth` (Table 3's: 3, or 5 for algorithm 5) and
/// `device` (the CPU).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainParams {
    /// Table 3 algorithm, 1..=5 (the matrix key).
    pub algorithm: i64,
    /// Channel width W.
    pub width: usize,
    /// Fourier modes M.
    pub modes: usize,
    /// Fourier layers L (default: 3, or 5 for algorithm 5).
    #[serde(default)]
    pub depth: Option<usize>,
    /// Hidden width of the projection MLP.
    pub projection_width: usize,
    /// Zeros appended to the time axis inside the network (% of the window).
    pub padding: usize,
    /// Epochs.
    pub epochs: usize,
    /// Batch size.
    pub batch_size: usize,
    /// Initial learning rate.
    pub learning_rate: f64,
    /// Step-decay factor.
    pub lr_decay: f64,
    /// Decay period in epochs.
    pub lr_decay_every: usize,
    /// ODE loss weight.
    pub lambda_ode: f64,
    /// Derivative loss weight.
    pub lambda_d: f64,
    /// Weight of the extra data term on the beam deflections.
    pub beam_weight: f64,
    /// Target residual level of the weighted ODE loss.
    pub rho: f64,
    /// Seed.
    pub seed: u64,
    /// Fraction of each record dropped at its start (start-up).
    pub startup_fraction: f64,
    /// Keep every n-th time point of the window (1 = all).
    pub time_stride: usize,
    /// "cpu" or "cuda".
    #[serde(default = "d_device")]
    pub device: DeviceKind,
    /// Train on the first N samples of the training split only (by sample id; absent: all):
    /// a budget study's knob, judged on the same validation split.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub train_samples: Option<usize>,
    /// Stored velocity or acceleration columns (`z_c_a`, `z_mid_a`) the network outputs
    /// directly beside its displacements and forces, supervised by the exact columns in the
    /// data loss; the indices and histories read them instead of differences
    /// (`docs/learning.md`, Rate outputs). Empty: the paper's networks.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rate_outputs: Vec<String>,
    /// Weight of the rate outputs' term in `L_data` (absent: 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate_weight: Option<f64>,
    /// Weight of an extra relative-L2 term on the force outputs (absent: 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_weight: Option<f64>,
    /// Decay per step of the weights' moving average, the model kept (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub average_decay: Option<f64>,
}

impl TrainParams {
    /// The training's work relative to other settings on the same data, for scheduling only:
    /// epochs x Fourier layers x width^2 (each layer's channel mixing, spectral and pointwise)
    /// / time stride (points kept). The algorithm's default depth when none is set.
    pub fn relative_work(&self) -> Result<f64> {
        let depth = match self.depth {
            Some(d) => d,
            None => Algorithm::from_id(self.algorithm)?.default_depth(),
        };
        let width = self.width as f64;
        Ok(self.epochs as f64 * depth as f64 * width * width / self.time_stride.max(1) as f64)
    }

    /// Small settings for tests and examples: width 8, 8 modes, projection 16, 2 epochs of
    /// batches of 2 (the product's settings are `pipeline.yaml`'s).
    pub fn small(algorithm: i64) -> Self {
        serde_json::from_value(serde_json::json!({
            "algorithm": algorithm, "width": 8, "modes": 8, "projection_width": 16, "padding": 0,
            "epochs": 2, "batch_size": 2, "learning_rate": 1e-3, "lr_decay": 0.75,
            "lr_decay_every": 10, "lambda_ode": 0.25, "lambda_d": 1.0, "beam_weight": 0.0,
            "rho": 0.025, "seed": 1, "startup_fraction": 0.1, "time_stride": 1
        }))
        .expect("complete parameters")
    }

    /// Splits into checked model and training configurations for a system of `layout`
    /// (`t_points` checked later).
    pub fn configs(
        &self,
        layout: &crate::layout::Layout,
    ) -> Result<(ModelConfig, TrainConfig, WindowConfig)> {
        let algorithm = Algorithm::from_id(self.algorithm)?;
        let model = ModelConfig {
            in_channels: layout.n_inputs(),
            out_channels: layout.n_outputs(),
            width: self.width,
            modes: self.modes,
            depth: self.depth.unwrap_or(algorithm.default_depth()),
            projection_width: self.projection_width,
            padding_percent: self.padding,
        };
        let train = TrainConfig {
            algorithm,
            epochs: self.epochs,
            batch_size: self.batch_size,
            learning_rate: self.learning_rate,
            lr_decay: self.lr_decay,
            lr_decay_every: self.lr_decay_every,
            lambda_ode: self.lambda_ode,
            lambda_d: self.lambda_d,
            beam_weight: self.beam_weight,
            rho: self.rho,
            seed: self.seed,
            rate_weight: self.rate_weight,
            force_weight: self.force_weight,
            average_decay: self.average_decay,
        };
        train.validate()?;
        let window = WindowConfig {
            startup_fraction: self.startup_fraction,
            time_stride: self.time_stride,
        };
        window.validate()?;
        Ok((model, train, window))
    }
}

/// Which part of each record the model sees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindowConfig {
    /// Fraction of each record dropped at its start (0.1).
    pub startup_fraction: f64,
    /// Keep every n-th point (1 = all).
    pub time_stride: usize,
}

impl WindowConfig {
    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        if !(0.0..0.9).contains(&self.startup_fraction) {
            return Err(Error::OutOfRange {
                field: "startup_fraction".into(),
                value: self.startup_fraction.to_string(),
                allowed: "[0, 0.9)".into(),
            });
        }
        if self.time_stride == 0 {
            return Err(Error::OutOfRange {
                field: "time_stride".into(),
                value: "0".into(),
                allowed: ">= 1".into(),
            });
        }
        Ok(())
    }

    /// Index of the first kept point of a record of `n` points.
    pub fn first_index(&self, n: usize) -> usize {
        (self.startup_fraction * n as f64).floor() as usize
    }

    /// The kept points of a record of `n` points.
    pub fn rows(&self, n: usize) -> std::iter::StepBy<std::ops::Range<usize>> {
        (self.first_index(n)..n).step_by(self.time_stride)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default job's algorithm 5 (five layers) announces more work than algorithms 1-4
    /// (three) with the same settings; a set depth counts; an unknown algorithm is refused.
    #[test]
    fn relative_work_counts_epochs_layers_and_width() {
        let four = TrainParams::small(4).relative_work().unwrap();
        let five = TrainParams::small(5).relative_work().unwrap();
        assert_eq!(five / four, 5.0 / 3.0);
        let mut deeper = TrainParams::small(4);
        deeper.depth = Some(6);
        deeper.width *= 2;
        assert_eq!(deeper.relative_work().unwrap() / four, 8.0);
        assert!(TrainParams::small(9).relative_work().is_err());
    }

    #[test]
    fn algorithms_round_trip_and_unknown_is_refused() {
        for a in Algorithm::ALL {
            assert_eq!(Algorithm::from_id(a.id()).unwrap(), a);
        }
        let err = Algorithm::from_id(7).unwrap_err().to_string();
        assert!(
            err.contains("unknown algorithm 7") && err.contains("1 (FNO)"),
            "{err}"
        );
        let layout = crate::synthetic::vehicle_track_layout();
        let err = TrainParams::small(9)
            .configs(&layout)
            .unwrap_err()
            .to_string();
        assert!(err.contains("unknown algorithm 9"), "{err}");
        let p: std::result::Result<TrainParams, _> =
            serde_json::from_value(serde_json::json!({"algorithm": 1, "width": 3}));
        assert!(p.unwrap_err().to_string().contains("missing field"));
        let p: std::result::Result<TrainParams, _> =
            serde_json::from_value(serde_json::json!({"algorithm": 1, "widht": 3}));
        assert!(p.unwrap_err().to_string().contains("unknown field `widht`"));
    }

    #[test]
    fn depth_defaults_by_algorithm_and_lr_decays_in_steps() {
        let layout = crate::synthetic::vehicle_track_layout();
        let (m, t, _) = TrainParams::small(5).configs(&layout).unwrap();
        assert_eq!((m.depth, m.in_channels, m.out_channels), (5, 19, 18));
        let (m, _, _) = TrainParams::small(4).configs(&layout).unwrap();
        assert_eq!(m.depth, 3);
        assert_eq!(t.lr_at(9), 1e-3);
        assert!((t.lr_at(10) - 7.5e-4).abs() < 1e-15);
        assert!((t.lr_at(25) - 1e-3 * 0.75 * 0.75).abs() < 1e-15);
        assert!(m.validate(16).is_ok());
        assert!(m.validate(15).is_err(), "8 modes need 16 points");
    }
}
