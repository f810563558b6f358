//! The description's indices in the graph, from the series [`crate::member::index_series`]
//! gives, as `pino_indices` computes them (`docs/indices.md`): the railway family (peaks,
//! minima, RMS of the bound columns, and Sperling's `W_z` through the graph's own spectrum of
//! the car-body signals) and the simple indices (`max`, `min`, `max_abs`, `rms`,
//! `peak_to_peak` of `(channel - subtract) / divide`).
//!
//! Sperling: with the window's `N` points at spacing `dt`, the lines `k = 1..N/2` at
//! `f_k = k / (N dt) >= f_min` of the signal in cm/s^2, `a_k = c_k |X_k| / N` (`c_k` 2, 1 at
//! the Nyquist line), `W_z = 0.896 (sum a_k^3 F(f_k) / f_k)^(1/10)`; `|X_k|` from fixed cosine
//! and sine rows (single precision, opset 13) or the `DFT` operator (double, opset 17). Only
//! the product's settings are exported: one spectrum over the whole window, no taper (a
//! segmented or tapered Sperling is refused by name).

use crate::expr::Expressions;
use crate::graph::{Graph, Value};
use crate::network::Spectral;
use crate::proto::{Attr, DataType};
use crate::{Error, Result};
use mbd_system::schema::IndexStat;
use mbd_system::System;
use pino_indices::sperling::weighting;
use pino_indices::{IndexConfig, Taper, INDEX_COLUMNS};

/// What the index values need.
pub struct IndexInputs<'a, 'b> {
    /// The system.
    pub system: &'a System,
    /// Its expressions over the design input.
    pub expressions: &'b mut Expressions<'a>,
    /// The series by column name, `[B, N]`, or why it is missing.
    pub series: &'b crate::member::Series,
    /// The window's points `N` and spacing (s).
    pub points: usize,
    /// Spacing `dt` (s).
    pub dt: f64,
    /// The indices' settings.
    pub config: &'b IndexConfig,
    /// The spectral form (the Sperling spectrum's).
    pub spectral: Spectral,
}

impl IndexInputs<'_, '_> {
    fn series(&self, name: &str) -> Result<Value> {
        match self.series.iter().find(|(n, _)| n == name) {
            Some((_, Ok(v))) => Ok(v.clone()),
            Some((_, Err(why))) => Err(Error::Unsupported(why.clone())),
            None => Err(Error::Unsupported(format!(
                "index input `{name}` is not derivable from the model's outputs"
            ))),
        }
    }

    /// Expression `e` per design: `[B]` (or a scalar), and `[B, 1]` to combine with a
    /// series `[B, N]`.
    fn per_design(&mut self, g: &mut Graph, e: &mbd_system::expr::Expr) -> Result<(Value, Value)> {
        Ok(match self.expressions.compile(g, e)? {
            crate::expr::Compiled::Const(v) => {
                let s = g.scalar(v);
                (s.clone(), s)
            }
            crate::expr::Compiled::Node(n) => {
                let c = g.unsqueeze(&n, &[1]);
                (n, c)
            }
        })
    }

    /// Every index `[B]`, in `IndexSet::columns` order, or why the graph cannot compute it.
    pub fn values(&mut self, g: &mut Graph) -> Vec<std::result::Result<Value, String>> {
        let system = self.system;
        let mut out = Vec::new();
        if let Some(binding) = &system.railway {
            let set = pino_indices::IndexSet::of(system);
            let cols = set
                .railway
                .as_ref()
                .expect("bound with the system's railway");
            match self.railway(g, cols, binding) {
                Ok(v) => out.extend(v),
                Err(e) => out.extend(INDEX_COLUMNS.iter().map(|_| Err(e.to_string()))),
            }
        }
        for ix in &system.indices {
            out.push(self.simple(g, ix).map_err(|e| e.to_string()));
        }
        out
    }

    fn simple(&mut self, g: &mut Graph, ix: &mbd_system::system::Index) -> Result<Value> {
        let x = self.series(&self.system.channels[ix.channel].name)?;
        let (_, sub) = self.per_design(g, &ix.subtract)?;
        let (div, _) = self.per_design(g, &ix.divide)?;
        let d = g.sub(&x, &sub);
        let v = stat(g, ix.stat, &d, self.points);
        Ok(g.div(&v, &div))
    }

    /// The railway family: every value, Sperling's separately refusable.
    fn railway(
        &mut self,
        g: &mut Graph,
        cols: &pino_indices::RailwayColumns,
        binding: &mbd_system::system::Railway,
    ) -> Result<Vec<std::result::Result<Value, String>>> {
        let (w, _) = self.per_design(g, &binding.static_wheel_load)?;
        let (_, l_c) = self.per_design(g, &binding.half_length)?;
        let stack = |this: &Self, g: &mut Graph, names: &[String]| -> Result<Value> {
            let mut parts = Vec::new();
            for n in names {
                let s = this.series(n)?;
                parts.push(g.unsqueeze(&s, &[1]));
            }
            let refs: Vec<&str> = parts.iter().map(String::as_str).collect();
            Ok(g.concat(1, &refs))
        };
        let p = stack(self, g, &cols.p)?;
        let p_max = g.reduce("ReduceMax", &p, &[1, 2], false);
        let p_min = g.reduce("ReduceMin", &p, &[1, 2], false);
        let kilo = g.scalar(1e-3);
        let peak = g.mul(&kilo, &p_max);
        let unloading = g.sub(&w, &p_min);
        let reduction = g.div(&unloading, &w);
        let z = self.series(&cols.z_c_a)?;
        let beta = self.series(&cols.beta_c_a)?;
        let lb = g.mul(&l_c, &beta);
        let front = g.sub(&z, &lb);
        let rear = g.add(&z, &lb);
        let car = [z, front, rear];
        let mut v: Vec<std::result::Result<Value, String>> = vec![Ok(peak), Ok(reduction)];
        v.extend(car.iter().map(|s| Ok(abs_max(g, s))));
        v.extend(
            car.iter()
                .map(|s| Ok(stat(g, IndexStat::Rms, s, self.points))),
        );
        v.extend(
            car.iter()
                .map(|s| self.sperling(g, s).map_err(|e| e.to_string())),
        );
        for n in &cols.z_t_a {
            let s = self.series(n)?;
            v.push(Ok(abs_max(g, &s)));
        }
        let rails = stack(self, g, &cols.z_r)?;
        let rail_max = g.reduce("ReduceMax", &rails, &[1, 2], false);
        let milli = g.scalar(1e3);
        v.push(Ok(g.mul(&milli, &rail_max)));
        debug_assert_eq!(v.len(), INDEX_COLUMNS.len());
        Ok(v)
    }

    /// `W_z` `[B]` of an acceleration series `[B, N]` (m/s^2).
    fn sperling(&self, g: &mut Graph, a: &str) -> Result<Value> {
        let p = &self.config.sperling;
        if p.segment_s.is_some() || p.taper != Taper::None {
            return Err(Error::Unsupported(
                "Sperling with `segment_s` or a taper: only one spectrum over the whole window without taper is exported".into(),
            ));
        }
        let n = self.points;
        let span = n as f64 * self.dt;
        let lines: Vec<usize> = (1..=n / 2)
            .filter(|&k| k as f64 / span >= p.f_min_hz)
            .collect();
        if lines.is_empty() {
            return Ok(g.scalar(0.0));
        }
        let k_n = lines.len();
        let cm = g.scalar(100.0);
        let a = g.mul(a, &cm);
        let (re, im) = match self.spectral {
            Spectral::Matmul => {
                let mut cos = vec![0.0f32; n * k_n];
                let mut sin = vec![0.0f32; n * k_n];
                for t in 0..n {
                    for (j, &k) in lines.iter().enumerate() {
                        let th = 2.0 * std::f64::consts::PI * ((k * t) % n) as f64 / n as f64;
                        cos[t * k_n + j] = th.cos() as f32;
                        sin[t * k_n + j] = th.sin() as f32;
                    }
                }
                let a32 = g.cast(&a, DataType::Float);
                let (c, s) = (g.f32s(&[n, k_n], &cos), g.f32s(&[n, k_n], &sin));
                let re = g.matmul(&a32, &c);
                let im = g.matmul(&a32, &s);
                (g.cast(&re, DataType::Double), g.cast(&im, DataType::Double))
            }
            Spectral::Dft => {
                let rows = g.unsqueeze(&a, &[2]);
                let spec = g.op(
                    "DFT",
                    &[&rows],
                    &[("axis", Attr::Int(1)), ("onesided", Attr::Int(1))],
                );
                let picked = g.gather(
                    &spec,
                    1,
                    &lines.iter().map(|&k| k as i64).collect::<Vec<_>>(),
                );
                let re = g.slice(&picked, 2, 0, 1);
                let im = g.slice(&picked, 2, 1, 2);
                (g.reshape(&re, &[0, -1]), g.reshape(&im, &[0, -1]))
            }
        };
        let re2 = g.mul(&re, &re);
        let im2 = g.mul(&im, &im);
        let sq = g.add(&re2, &im2);
        let modulus = g.unary("Sqrt", &sq);
        let scale: Vec<f64> = lines
            .iter()
            .map(|&k| if 2 * k == n { 1.0 } else { 2.0 } / n as f64)
            .collect();
        let weight: Vec<f64> = lines
            .iter()
            .map(|&k| {
                let f = k as f64 / span;
                weighting(f) / f
            })
            .collect();
        let scale = g.f64s(&[k_n], &scale);
        let weight = g.f64s(&[k_n], &weight);
        let amp = g.mul(&modulus, &scale);
        let amp2 = g.mul(&amp, &amp);
        let amp3 = g.mul(&amp2, &amp);
        let terms = g.mul(&amp3, &weight);
        let sum = g.reduce_sum(&terms, &[1], false);
        let tenth = g.scalar(0.1);
        let root = g.op("Pow", &[&sum, &tenth], &[]);
        let c = g.scalar(0.896);
        Ok(g.mul(&c, &root))
    }
}

/// `max_t |x|` `[B]` of `[B, N]`.
fn abs_max(g: &mut Graph, x: &str) -> Value {
    let a = g.unary("Abs", x);
    g.reduce("ReduceMax", &a, &[1], false)
}

/// A statistic `[B]` over the window of `x [B, N]` (`n` = N points).
fn stat(g: &mut Graph, stat: IndexStat, x: &str, n: usize) -> Value {
    match stat {
        IndexStat::Max => g.reduce("ReduceMax", x, &[1], false),
        IndexStat::Min => g.reduce("ReduceMin", x, &[1], false),
        IndexStat::MaxAbs => abs_max(g, x),
        IndexStat::Rms => {
            let sq = g.mul(x, x);
            let sum = g.reduce_sum(&sq, &[1], false);
            let count = g.scalar(n as f64);
            let mean = g.div(&sum, &count);
            g.unary("Sqrt", &mean)
        }
        IndexStat::PeakToPeak => {
            let hi = g.reduce("ReduceMax", x, &[1], false);
            let lo = g.reduce("ReduceMin", x, &[1], false);
            g.sub(&hi, &lo)
        }
    }
}
