//! The 1-D Fourier neural operator over time (the paper's eq. 22).
//!
//! ```text
//! v_0     = P a + p                    a [B, T, 19] -> [W, B, T]   pointwise linear (lift)
//! v_0    <- v_0 zero-padded to T_p >= T points on the time axis (padding_percent)
//! v_{l+1} = s( K_l v_l + W_l v_l + b_l )   l = 0..L-1, s = GELU except after the last layer
//! u       = Q2 GELU(Q1 v_L[.., :T] + q1) + q2   -> [B, T, 14]
//! ```
//! Activations inside the network are channel-major, `[C, B, T]`: every pointwise layer is
//! one matrix product over the `B T` columns and every (channel, sample) row is contiguous for
//! the spectral convolution `K_l` of [`crate::spectral`] (lowest `M` modes of the padded
//! length, complex weights `R_l = wr + i wi` of shape `[M, W, W]`). Padding makes the window
//! non-periodic for the spectral layers: without it the end of the window wraps onto its
//! start. On the CPU the spectral convolution and each layer's `act(. + . + bias)` are fused
//! kernels ([`crate::kernels`]); elsewhere the same functions are candle compositions.
//!
//! Pointwise weights are stored `[in, out]` (so `y = x w + b`). Parameters are named
//! `lift.weight`, `lift.bias`, `layers.{l}.wr`, `layers.{l}.wi`, `layers.{l}.weight`,
//! `layers.{l}.bias`, `proj1.*`, `proj2.*`. Initialisation is seeded: pointwise weights and
//! biases uniform on `+-1/sqrt(in)`, spectral weights uniform on `[0, 1/(W W))` as in the
//! reference FNO, all drawn from the `Training` stream of the seed.

use crate::config::ModelConfig;
use crate::kernels;
use crate::spectral::{Dft, Transform};
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
    t_points: usize,
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
        let mut rng = mbd_dataset::rng::SampleStream::new(
            seed,
            mbd_dataset::rng::Purpose::Training,
            INIT_STREAM,
        );
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
        Self::with_vars(config, vars, t_points, transform, device)
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
                config: config.to_string().into(),
            })?;
            if t.dims() != shape.as_slice() {
                return Err(Error::ModelMismatch {
                    path: origin.to_owned(),
                    tensor: name,
                    found: t.dims().to_vec(),
                    expected: shape,
                    config: config.to_string().into(),
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
        Self::with_vars(config, vars, t_points, transform, device)
    }

    /// The model of `vars` with its spectral transform planned for the padded window.
    fn with_vars(
        config: ModelConfig,
        vars: Vec<(String, Var)>,
        t_points: usize,
        transform: Transform,
        device: &Device,
    ) -> Result<Self> {
        let dft = Dft::new(
            config.padded_points(t_points),
            config.modes,
            transform,
            DType::F32,
            device,
        )?;
        Ok(Self {
            config,
            vars,
            dft,
            t_points,
        })
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

    /// `w^T x` of channel-major `x [C, N]` with the stored `[C, C']` weight: `[C', N]`.
    fn pointwise(&self, x: &Tensor, prefix: &str) -> Result<Tensor> {
        Ok(self.var(&format!("{prefix}.weight")).t()?.matmul(x)?)
    }

    /// `act(a [+ b] + bias)` over channel-major tensors (composition).
    fn bias_act(&self, a: &Tensor, b: Option<&Tensor>, prefix: &str, gelu: bool) -> Result<Tensor> {
        let bias = self.var(&format!("{prefix}.bias"));
        let sum = match b {
            Some(b) => (a + b)?,
            None => a.clone(),
        };
        let mut shape = vec![bias.dim(0)?];
        shape.resize(a.rank(), 1);
        let z = sum.broadcast_add(&bias.reshape(shape)?)?;
        Ok(if gelu { z.gelu()? } else { z })
    }

    /// `x [B, T, 19]` (z-scored) -> `u [B, T, 14]` (z-scored).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        match self.dft.plan() {
            Some(plan) => self.forward_fused(x, plan),
            None => self.forward_composed(x),
        }
    }

    /// The forward pass as candle compositions (any device; the reference of the fused one).
    fn forward_composed(&self, x: &Tensor) -> Result<Tensor> {
        let (b, t, c_in) = x.dims3()?;
        let (w, t_pad) = (self.config.width, self.dft.t_points);
        let columns = x.reshape((b * t, c_in))?.t()?; // [19, B T]
        let lifted = self.bias_act(&self.pointwise(&columns, "lift")?, None, "lift", false)?;
        let mut v = lifted.reshape((w, b, t))?;
        if t_pad > t {
            v = v.pad_with_zeros(2, 0, t_pad - t)?;
        }
        for l in 0..self.config.depth {
            let prefix = format!("layers.{l}");
            let k = self.dft.conv(
                &v,
                self.var(&format!("{prefix}.wr")),
                self.var(&format!("{prefix}.wi")),
            )?;
            let p = self
                .pointwise(&v.reshape((w, b * t_pad))?, &prefix)?
                .reshape((w, b, t_pad))?;
            v = self.bias_act(&k, Some(&p), &prefix, l + 1 < self.config.depth)?;
        }
        self.project(v, b, t)
    }

    /// The forward pass as one fused CPU op ([`kernels::FusedNetwork`]).
    fn forward_fused(&self, x: &Tensor, plan: &std::sync::Arc<kernels::RealDft>) -> Result<Tensor> {
        let (b, t, _) = x.dims3()?;
        let op = kernels::FusedNetwork::new(self.network_shape(), plan, b, t);
        Ok(x.contiguous()?.apply_op2(&self.flat_parameters()?, op)?)
    }

    fn network_shape(&self) -> kernels::NetworkShape {
        let c = &self.config;
        kernels::NetworkShape {
            c_in: c.in_channels,
            width: c.width,
            projection: c.projection_width,
            c_out: c.out_channels,
            depth: c.depth,
        }
    }

    /// Every parameter in one flat tensor, in the fused network's order.
    fn flat_parameters(&self) -> Result<Tensor> {
        let c = &self.config;
        let mut names = vec!["lift.weight".to_owned(), "lift.bias".to_owned()];
        for l in 0..c.depth {
            for part in ["weight", "bias", "wr", "wi"] {
                names.push(format!("layers.{l}.{part}"));
            }
        }
        for p in ["proj1", "proj2"] {
            names.push(format!("{p}.weight"));
            names.push(format!("{p}.bias"));
        }
        let parts = names
            .iter()
            .map(|n| self.var(n).flatten_all())
            .collect::<candle_core::Result<Vec<_>>>()?;
        Ok(Tensor::cat(&parts, 0)?)
    }

    /// The model frozen for forward passes only (evaluation, prediction).
    pub fn predictor(&self) -> Result<Predictor<'_>> {
        let fused = match self.dft.plan() {
            Some(plan) => Some((
                std::sync::Arc::clone(plan),
                self.flat_parameters()?.to_vec1::<f32>()?,
            )),
            None => None,
        };
        Ok(Predictor { model: self, fused })
    }

    /// Crop `v [W, B, T_p]` to `T` points and apply the projection MLP: `[B, T, 14]`.
    fn project(&self, v: Tensor, b: usize, t: usize) -> Result<Tensor> {
        let (w, _, t_pad) = v.dims3()?;
        let v = if t_pad > t {
            v.narrow(2, 0, t)?.contiguous()?
        } else {
            v
        };
        let v = v.reshape((w, b * t))?;
        let h = self.bias_act(&self.pointwise(&v, "proj1")?, None, "proj1", true)?;
        let u = self.bias_act(&self.pointwise(&h, "proj2")?, None, "proj2", false)?;
        let c_out = u.dim(0)?;
        Ok(u.reshape((c_out, b, t))?.permute((1, 2, 0))?.contiguous()?)
    }

    /// Window length `T` the model was built for.
    pub fn t_points(&self) -> usize {
        self.t_points
    }
}

/// A model frozen for forward passes only. On the fused CPU path the parameters are gathered
/// once and each pass runs [`kernels::FusedNetwork::infer`] (one sample at a time, nothing
/// kept for a backward pass, activations updated in place; equal to [`Fno::forward`] to f32
/// round-off); elsewhere it is [`Fno::forward`], detached.
pub struct Predictor<'a> {
    model: &'a Fno,
    fused: Option<(std::sync::Arc<kernels::RealDft>, Vec<f32>)>,
}

impl Predictor<'_> {
    /// `x [B, T, 19]` (z-scored) -> `u [B, T, 18]` (z-scored), f32, no gradient.
    pub fn predict(&self, x: &Tensor) -> Result<Tensor> {
        let Some((plan, params)) = &self.fused else {
            return Ok(self
                .model
                .forward(x)?
                .detach()
                .to_dtype(candle_core::DType::F32)?);
        };
        let (b, t, _) = x.dims3()?;
        let expected = [b, t, self.model.config.in_channels];
        if x.dims() != expected {
            return Err(candle_core::Error::Msg(format!(
                "model input {:?}, expected {expected:?}",
                x.dims()
            ))
            .into());
        }
        let shape = self.model.network_shape();
        let u = kernels::with_host(&x.to_dtype(candle_core::DType::F32)?, |x| {
            kernels::FusedNetwork::infer(shape, plan, t, x, params)
        })?;
        Ok(Tensor::from_vec(
            u,
            (b, t, self.model.config.out_channels),
            x.device(),
        )?)
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
            padding_percent: 0,
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

    /// The predictor's inference pass (one sample at a time, buffers updated in place,
    /// nothing saved) gives the forward pass's values to f32 round-off, with and without
    /// padding, for batches split evenly and unevenly by the training op; a sample's output
    /// does not depend on the other samples of its batch (bit for bit); the composition's
    /// predictor is its forward pass.
    #[test]
    fn predictor_equals_the_forward_pass() {
        let dev = Device::Cpu;
        for padding_percent in [0, 25] {
            let config = ModelConfig {
                padding_percent,
                ..cfg()
            };
            let t = 24;
            for transform in [Transform::Fused, Transform::Matmul] {
                let model = Fno::new(config, t, 11, transform, &dev).unwrap();
                let predictor = model.predictor().unwrap();
                for b in [1, 2, 5] {
                    let mut s = mbd_dataset::rng::SampleStream::new(
                        4,
                        mbd_dataset::rng::Purpose::Training,
                        b,
                    );
                    let x: Vec<f32> = (0..b as usize * t * 19)
                        .map(|_| s.normal() as f32)
                        .collect();
                    let x = Tensor::from_vec(x, (b as usize, t, 19), &dev).unwrap();
                    let flat = |u: Tensor| u.flatten_all().unwrap().to_vec1::<f32>().unwrap();
                    let forward = flat(model.forward(&x).unwrap());
                    let predicted = flat(predictor.predict(&x).unwrap());
                    assert_eq!(forward.len(), b as usize * t * config.out_channels);
                    let scale = forward.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                    for (p, q) in forward.iter().zip(&predicted) {
                        assert!(
                            (p - q).abs() <= 1e-5 * scale,
                            "{transform:?}, padding {padding_percent}, batch {b}: {p} vs {q}"
                        );
                    }
                    let last = x.narrow(0, b as usize - 1, 1).unwrap();
                    let alone = flat(predictor.predict(&last).unwrap());
                    assert_eq!(
                        alone,
                        predicted[(b as usize - 1) * t * config.out_channels..],
                        "{transform:?}, padding {padding_percent}, batch {b}"
                    );
                }
            }
            let wrong = Tensor::zeros((2, t, 7), candle_core::DType::F32, &dev).unwrap();
            let model = Fno::new(config, t, 11, Transform::Fused, &dev).unwrap();
            let err = model
                .predictor()
                .unwrap()
                .predict(&wrong)
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("[2, 24, 7]") && err.contains("[2, 24, 19]"),
                "{err}"
            );
        }
    }

    /// The fused network (one CPU op) against the candle composition with the same weights:
    /// outputs and the gradient of every parameter, with and without time padding.
    #[test]
    fn fused_network_matches_the_composition_values_and_gradients() {
        let dev = Device::Cpu;
        for padding_percent in [0, 25] {
            let config = ModelConfig {
                padding_percent,
                ..cfg()
            };
            let (b, t) = (3, 24);
            let reference = Fno::new(config, t, 7, Transform::Matmul, &dev).unwrap();
            let fused = Fno::from_tensors(
                config,
                t,
                &reference.tensors(),
                Transform::Fused,
                Path::new("mem"),
                &dev,
            )
            .unwrap();
            let mut s =
                mbd_dataset::rng::SampleStream::new(3, mbd_dataset::rng::Purpose::Training, 5);
            let x: Vec<f32> = (0..b * t * 19).map(|_| s.normal() as f32).collect();
            let x = Tensor::from_vec(x, (b, t, 19), &dev).unwrap();
            let r: Vec<f32> = (0..b * t * 14).map(|_| s.normal() as f32).collect();
            let r = Tensor::from_vec(r, (b, t, 14), &dev).unwrap();
            let run = |m: &Fno| {
                let u = m.forward(&x).unwrap();
                // A loss with a nonlinearity so every gradient path is exercised.
                let loss = (u.sqr().unwrap() * &r).unwrap().sum_all().unwrap();
                let grads = loss.backward().unwrap();
                let flat = |t: &Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
                let g: Vec<(String, Vec<f32>)> = m
                    .vars()
                    .iter()
                    .map(|(n, v)| (n.clone(), flat(grads.get(v.as_tensor()).unwrap())))
                    .collect();
                (flat(&u), g)
            };
            let (u_ref, g_ref) = run(&reference);
            let (u_fused, g_fused) = run(&fused);
            let scale = u_ref.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            for (a, b) in u_ref.iter().zip(&u_fused) {
                assert!(
                    (a - b).abs() <= 1e-5 * scale,
                    "padding {padding_percent}: {a} vs {b}"
                );
            }
            for ((name, a), (_, b)) in g_ref.iter().zip(&g_fused) {
                let scale = a.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-6);
                for (i, (p, q)) in a.iter().zip(b).enumerate() {
                    assert!(
                        (p - q).abs() <= 1e-4 * scale,
                        "padding {padding_percent}: d{name}[{i}] composition {p} vs fused {q}"
                    );
                }
            }
        }
    }
}
