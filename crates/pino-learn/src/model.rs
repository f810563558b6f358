//! The 1-D Fourier neural operator over time (the paper's eq. 22).
//!
//! ```text
//! v_0     = P a                        a [B, T, 19] -> [B, T, W]   pointwise linear (lift)
//! v_{l+1} = s( K_l v_l + W_l v_l + b_l )   l = 0..L-1, s = GELU except after the last layer
//! u       = Q2 GELU(Q1 v_L + q1) + q2  [B, T, W] -> [B, T, P] -> [B, T, 14]
//! ```
//! `K_l` is the spectral convolution of [`crate::spectral`] on the lowest `M` modes with
//! complex weights `R_l = wr + i wi` of shape `[M, W, W]`. Pointwise weights are stored
//! `[in, out]` (so `y = x w + b`).
//!
//! Parameters are named `lift.weight`, `lift.bias`, `layers.{l}.wr`, `layers.{l}.wi`,
//! `layers.{l}.weight`, `layers.{l}.bias`, `proj1.*`, `proj2.*`. Initialisation is seeded:
//! pointwise weights and biases uniform on `+-1/sqrt(in)`, spectral weights uniform on
//! `[0, 1/(W W))` as in the reference FNO, all drawn from the `Training` stream of the seed.

use crate::config::ModelConfig;
use crate::spectral::{spectral_conv, Dft, Transform};
use crate::{Error, Result};
use candle_core::{DType, Device, Tensor, Var};
use std::collections::HashMap;
use std::path::Path;

/// Stream index (within the `Training` purpose) of the initialisation draws.
const INIT_STREAM: u64 = 0;

/// A Fourier neural operator with its trainable variables.
#[derive(Debug, Clone)]
pub struct Fno {
    /// Sizes.
    pub config: ModelConfig,
    vars: Vec<(String, Var)>,
    dft: Dft,
}

/// Names and shapes of every parameter for a configuration, in a fixed order.
pub fn parameter_shapes(c: &ModelConfig) -> Vec<(String, Vec<usize>)> {
    let (w, m, p) = (c.width, c.modes, c.projection_width);
    let mut out = vec![
        ("lift.weight".to_owned(), vec![c.in_channels, w]),
        ("lift.bias".to_owned(), vec![w]),
    ];
    for l in 0..c.depth {
        out.push((format!("layers.{l}.wr"), vec![m, w, w]));
        out.push((format!("layers.{l}.wi"), vec![m, w, w]));
        out.push((format!("layers.{l}.weight"), vec![w, w]));
        out.push((format!("layers.{l}.bias"), vec![w]));
    }
    out.push(("proj1.weight".to_owned(), vec![w, p]));
    out.push(("proj1.bias".to_owned(), vec![p]));
    out.push(("proj2.weight".to_owned(), vec![p, c.out_channels]));
    out.push(("proj2.bias".to_owned(), vec![c.out_channels]));
    out
}

impl Fno {
    /// A freshly initialised model for windows of `t_points` points.
    pub fn new(
        config: ModelConfig,
        t_points: usize,
        seed: u64,
        transform: Transform,
        device: &Device,
    ) -> Result<Self> {
        config.validate(t_points)?;
        let mut rng = vtcd::rng::SampleStream::new(seed, vtcd::rng::Purpose::Training, INIT_STREAM);
        let mut vars = Vec::new();
        for (name, shape) in parameter_shapes(&config) {
            let n: usize = shape.iter().product();
            let values: Vec<f32> = if name.ends_with(".wr") || name.ends_with(".wi") {
                let scale = 1.0 / (config.width * config.width) as f64;
                (0..n).map(|_| (scale * rng.uniform()) as f32).collect()
            } else {
                let fan_in = if name.ends_with(".bias") {
                    // The bias belongs to the weight listed just before it.
                    vars.last()
                        .map(|(_, v): &(String, Var)| v.dims()[0])
                        .unwrap_or(1)
                } else {
                    shape[0]
                };
                let bound = 1.0 / (fan_in as f64).sqrt();
                (0..n)
                    .map(|_| rng.uniform_in(-bound, bound) as f32)
                    .collect()
            };
            vars.push((name, Var::from_vec(values, shape, device)?));
        }
        let dft = Dft::new(t_points, config.modes, transform, DType::F32, device)?;
        Ok(Self { config, vars, dft })
    }

    /// Rebuilds a model from named tensors, checking every name and shape against `config`.
    pub fn from_tensors(
        config: ModelConfig,
        t_points: usize,
        tensors: &HashMap<String, Tensor>,
        transform: Transform,
        origin: &Path,
        device: &Device,
    ) -> Result<Self> {
        config.validate(t_points)?;
        let mut vars = Vec::new();
        for (name, shape) in parameter_shapes(&config) {
            let t = tensors.get(&name).ok_or_else(|| Error::ModelMismatch {
                path: origin.to_owned(),
                tensor: name.clone(),
                found: vec![],
                expected: shape.clone(),
                config: config.to_string(),
            })?;
            if t.dims() != shape.as_slice() {
                return Err(Error::ModelMismatch {
                    path: origin.to_owned(),
                    tensor: name,
                    found: t.dims().to_vec(),
                    expected: shape,
                    config: config.to_string(),
                });
            }
            vars.push((
                name,
                Var::from_tensor(&t.to_dtype(DType::F32)?.to_device(device)?)?,
            ));
        }
        let extra: Vec<&String> = tensors
            .keys()
            .filter(|k| !vars.iter().any(|(n, _)| n == *k))
            .collect();
        if let Some(name) = extra.iter().min() {
            return Err(Error::UnexpectedTensor {
                path: origin.to_owned(),
                tensor: (*name).clone(),
                config: config.to_string(),
            });
        }
        let dft = Dft::new(t_points, config.modes, transform, DType::F32, device)?;
        Ok(Self { config, vars, dft })
    }

    /// The trainable variables in their fixed order.
    pub fn vars(&self) -> &[(String, Var)] {
        &self.vars
    }

    /// Number of scalar parameters.
    pub fn num_parameters(&self) -> usize {
        self.vars.iter().map(|(_, v)| v.elem_count()).sum()
    }

    /// Named tensors (for saving).
    pub fn tensors(&self) -> HashMap<String, Tensor> {
        self.vars
            .iter()
            .map(|(n, v)| (n.clone(), v.as_tensor().clone()))
            .collect()
    }

    fn var(&self, name: &str) -> &Tensor {
        self.vars
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_tensor())
            .expect("parameter names come from parameter_shapes")
    }

    fn pointwise(&self, x: &Tensor, prefix: &str) -> Result<Tensor> {
        let (b, t, c) = x.dims3()?;
        let w = self.var(&format!("{prefix}.weight"));
        let bias = self.var(&format!("{prefix}.bias"));
        let y = x.reshape((b * t, c))?.matmul(w)?.broadcast_add(bias)?;
        Ok(y.reshape((b, t, w.dim(1)?))?)
    }

    /// `x [B, T, 19]` (z-scored) -> `u [B, T, 14]` (z-scored).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut v = self.pointwise(x, "lift")?;
        for l in 0..self.config.depth {
            let k = spectral_conv(
                &self.dft,
                &v,
                self.var(&format!("layers.{l}.wr")),
                self.var(&format!("layers.{l}.wi")),
            )?;
            let y = (k + self.pointwise(&v, &format!("layers.{l}"))?)?;
            v = if l + 1 < self.config.depth {
                y.gelu()?
            } else {
                y
            };
        }
        let h = self.pointwise(&v, "proj1")?.gelu()?;
        self.pointwise(&h, "proj2")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> ModelConfig {
        ModelConfig {
            in_channels: 19,
            out_channels: 14,
            width: 8,
            modes: 4,
            depth: 2,
            projection_width: 16,
        }
    }

    #[test]
    fn shapes_init_is_seeded_and_mismatch_is_named() {
        let dev = Device::Cpu;
        let a = Fno::new(cfg(), 20, 3, Transform::Matmul, &dev).unwrap();
        let b = Fno::new(cfg(), 20, 3, Transform::Matmul, &dev).unwrap();
        let x = Tensor::ones((2, 20, 19), DType::F32, &dev).unwrap();
        let ya = a.forward(&x).unwrap();
        assert_eq!(ya.dims(), &[2, 20, 14]);
        let yb = b.forward(&x).unwrap();
        assert_eq!(
            ya.flatten_all().unwrap().to_vec1::<f32>().unwrap(),
            yb.flatten_all().unwrap().to_vec1::<f32>().unwrap()
        );
        let mut other = cfg();
        other.width = 9;
        let err = Fno::from_tensors(
            other,
            20,
            &a.tensors(),
            Transform::Matmul,
            Path::new("m.safetensors"),
            &dev,
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("m.safetensors") && err.contains("lift.weight") && err.contains("width 9"),
            "{err}"
        );
    }
}
