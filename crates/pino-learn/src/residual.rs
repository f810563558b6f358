//! The ODE residuals of a prediction, for the losses of algorithms 2 and 3 and the magnitude
//! weights: `R_i = m_i a_i - F_i` of every DOF with an equation, computed by the engine's own
//! element code (`mbd_engine::residual::Equations`) from the de-normalised prediction.
//!
//! At interior points `n = 1..T-2` of a z-scored prediction `u_n [B, T, O]`
//! (`docs/learning.md`): the DOFs' physical displacements `z = s u + m`, their velocities and
//! accelerations by central differences (scaled by the channel std), the deflection under each
//! moving point an element rests on from its output column (and its rate by central
//! difference), the excitations from the inputs (physical) with their rates: the profile's own
//! rate `eta_<element>_v` where the element reads it (an input beside its profile, stored by
//! the solver from the profile's interpolation), else the central difference of the profile
//! column. The loss is
//! ```text
//! L = mean_{k,n,i} c_{k,i} |R_i(k, n)|     c = 1 / F_ref (global)  or  rho / phi_{k,i} (phi)
//! ```
//! On the CPU it is one fused op ([`OdeLoss`]); its backward pass uses that the residual is
//! linear in the state once the nonlinear elements' forces (Hertz, tables) are given: the
//! per-sample Jacobian is taken on unit vectors (exact for a linear map), `dL/d(state, f) = J^T
//! (c sign R)`, then each nonlinear force's tangent back onto the state of its deflection,
//! then the transposed stencils. Elsewhere (CUDA) [`composed_residuals`] computes the same as
//! candle ops: the per-sample linear map as a batched product plus the Hertz terms.

use crate::layout::Layout;
use crate::norm::ChannelStats;
use crate::{Error, Result};
use candle_core::{CpuStorage, CustomOp1, DType, Layout as CLayout, Shape, Tensor};
use mbd_engine::residual::{EquationState, Equations, StateEntry};
use mbd_system::model::ModelLaw;
use mbd_system::system::Quantity;
use mbd_system::System;

/// Where the residual's state comes from in the learner's channels (the same for every
/// sample of a system).
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelMap {
    /// Rigid DOFs (the first outputs).
    pub dofs: usize,
    /// Per moving point: the output channel of its deflection, if predicted.
    pub point: Vec<Option<usize>>,
    /// Per element: the excitation channel of its profile, if it reads one.
    pub eta: Vec<Option<usize>>,
    /// Per element: the excitation channel of its profile's own rate, if it reads one (a
    /// damper on a profile); without one the rate is the profile's central difference.
    pub eta_rate: Vec<Option<usize>>,
    /// The DOFs with equations.
    pub equations: Vec<usize>,
}

impl ChannelMap {
    /// The map of `layout` over `system`.
    pub fn new(system: &System, layout: &Layout) -> Self {
        // The layout's column holding `quantity` (the description names it, once).
        let find = |columns: &[String], quantity| {
            let name = system.column_of(quantity)?;
            columns.iter().position(|c| c == name)
        };
        let point = (0..system.points.len())
            .map(|p| find(&layout.outputs, Quantity::Point(p)))
            .collect();
        let eta = (0..system.elements.len())
            .map(|e| find(&layout.excitations, Quantity::Excitation(e)))
            .collect();
        let eta_rate = (0..system.elements.len())
            .map(|e| find(&layout.excitations, Quantity::ExcitationRate(e)))
            .collect();
        Self {
            dofs: layout.n_dofs(),
            point,
            eta,
            eta_rate,
            equations: layout.equations.clone(),
        }
    }

    /// Element `e`'s deflection in the learner's channels (`eq` one sample's equations), or
    /// `None` when a term of it (a moving point's deflection, a profile) is neither an output
    /// nor an input of this layout.
    pub fn deflection(&self, eq: &Equations, e: usize) -> Option<DeflectionReader> {
        let terms = eq
            .deflection_terms(e)
            .into_iter()
            .map(|(entry, coef)| {
                let slot = match entry {
                    StateEntry::Dof(j) => Slot::Output(j),
                    StateEntry::Point(p) => Slot::Output(self.point[p]?),
                    StateEntry::Eta(x) => Slot::Excitation(self.eta[x]?),
                };
                Some((slot, coef))
            })
            .collect::<Option<_>>()?;
        Some(DeflectionReader { terms })
    }

    /// Columns of the linear state: `z, v, a` (D each), point deflections and rates (P each),
    /// excitations and their rates (one per element).
    fn columns(&self) -> usize {
        3 * self.dofs + 2 * self.point.len() + 2 * self.eta.len()
    }
}

/// Where a deflection term is read: an output column or an excitation column.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Slot {
    Output(usize),
    Excitation(usize),
}

/// An element's deflection `d = (u_from - u_to) - eta` (m) as a sum over the learner's
/// channels ([`ChannelMap::deflection`]).
#[derive(Debug, Clone, PartialEq)]
pub struct DeflectionReader {
    terms: Vec<(Slot, f64)>,
}

impl DeflectionReader {
    /// The deflection at one time point: `u` a physical output row `[O]`, `eta` an excitation
    /// row `[E]`.
    pub fn at(&self, u: &[f64], eta: &[f64]) -> f64 {
        self.terms
            .iter()
            .map(|&(slot, coef)| {
                coef * match slot {
                    Slot::Output(c) => u[c],
                    Slot::Excitation(c) => eta[c],
                }
            })
            .sum()
    }
}

/// The equations of DOFs `dofs` of the model of one design.
pub fn sample_equations(
    system: &System,
    params: &mbd_system::Sampled,
    dofs: Vec<usize>,
) -> Result<Equations> {
    let model = system.instantiate(params).map_err(|e| Error::OutOfRange {
        field: e.path.clone(),
        value: e.value.to_string(),
        allowed: e.allowed.clone(),
    })?;
    Ok(Equations::new(model, dofs))
}

/// Physical state of one sample at one time point, in the residual's slices (here at an
/// interior point of a prediction; in [`crate::weights`] at a point of a noised record).
#[derive(Debug, Clone)]
pub(crate) struct State {
    pub(crate) z: Vec<f64>,
    pub(crate) v: Vec<f64>,
    pub(crate) a: Vec<f64>,
    pub(crate) point_w: Vec<f64>,
    pub(crate) point_rate: Vec<f64>,
    pub(crate) eta: Vec<f64>,
    pub(crate) eta_rate: Vec<f64>,
}

impl State {
    /// Zeroed buffers sized for `map`.
    pub(crate) fn new(map: &ChannelMap) -> Self {
        let (d, p, e) = (map.dofs, map.point.len(), map.eta.len());
        Self {
            z: vec![0.0; d],
            v: vec![0.0; d],
            a: vec![0.0; d],
            point_w: vec![0.0; p],
            point_rate: vec![0.0; p],
            eta: vec![0.0; e],
            eta_rate: vec![0.0; e],
        }
    }

    /// The state as the equations read it.
    pub(crate) fn view(&self) -> EquationState<'_> {
        EquationState {
            z: &self.z,
            v: &self.v,
            a: &self.a,
            point_w: &self.point_w,
            point_rate: &self.point_rate,
            eta: &self.eta,
            eta_rate: &self.eta_rate,
        }
    }

    /// The linear state as one vector in [`ChannelMap::columns`] order.
    fn set_column(&mut self, map: &ChannelMap, col: usize, value: f64) {
        let (d, p) = (map.dofs, map.point.len());
        match col {
            c if c < d => self.z[c] = value,
            c if c < 2 * d => self.v[c - d] = value,
            c if c < 3 * d => self.a[c - 2 * d] = value,
            c if c < 3 * d + p => self.point_w[c - 3 * d] = value,
            c if c < 3 * d + 2 * p => self.point_rate[c - 3 * d - p] = value,
            c if c < 3 * d + 2 * p + map.eta.len() => self.eta[c - 3 * d - 2 * p] = value,
            c => self.eta_rate[c - 3 * d - 2 * p - map.eta.len()] = value,
        }
    }
}

/// One sample's equations with the Jacobian of their linear form.
#[derive(Debug, Clone)]
pub struct SampleEquations {
    eq: Equations,
    /// `[Q, C + N]`: the linear state's columns, then the nonlinear forces.
    jacobian: Vec<Vec<f64>>,
    /// The same rows without their zeros, `(column, value)` in column order: an equation
    /// reads a few of the state's columns (the backward pass runs over these).
    jacobian_nonzeros: Vec<Vec<(usize, f64)>>,
    /// The residual at the zero state with zero nonlinear forces (loads, preloads).
    offset: Vec<f64>,
}

impl SampleEquations {
    /// The equations of one design.
    pub fn new(system: &System, map: &ChannelMap, params: &mbd_system::Sampled) -> Result<Self> {
        let eq = sample_equations(system, params, map.equations.clone())?;
        let q = map.equations.len();
        let n_nl = eq.nonlinear().len();
        let cols = map.columns();
        let mut scratch = eq.scratch();
        let mut zero = State::new(map);
        let mut base = vec![0.0; q];
        eq.residuals_with(&zero.view(), &vec![0.0; n_nl], &mut scratch, &mut base);
        let mut jacobian = vec![vec![0.0; cols + n_nl]; q];
        let mut r = vec![0.0; q];
        for col in 0..cols {
            zero.set_column(map, col, 1.0);
            eq.residuals_with(&zero.view(), &vec![0.0; n_nl], &mut scratch, &mut r);
            zero.set_column(map, col, 0.0);
            for ((row, ri), bi) in jacobian.iter_mut().zip(&r).zip(&base) {
                row[col] = ri - bi;
            }
        }
        for j in 0..n_nl {
            let mut f = vec![0.0; n_nl];
            f[j] = 1.0;
            eq.residuals_with(&zero.view(), &f, &mut scratch, &mut r);
            for ((row, ri), bi) in jacobian.iter_mut().zip(&r).zip(&base) {
                row[cols + j] = ri - bi;
            }
        }
        let jacobian_nonzeros = jacobian
            .iter()
            .map(|row| {
                row.iter()
                    .enumerate()
                    .filter(|(_, v)| **v != 0.0)
                    .map(|(c, v)| (c, *v))
                    .collect()
            })
            .collect();
        Ok(Self {
            eq,
            jacobian,
            jacobian_nonzeros,
            offset: base,
        })
    }

    /// The equations.
    pub fn equations(&self) -> &Equations {
        &self.eq
    }
}

/// How residuals are weighted.
#[derive(Debug, Clone)]
pub enum OdeWeights {
    /// `1 / F_ref` for every equation (PINO).
    Global {
        /// Force scale (N).
        f_ref: f64,
    },
    /// `rho / phi_{k,i}` (PINO-MBD with ODE magnitude weights), `phi [B, Q]`.
    Phi {
        /// Residual level.
        rho: f64,
        /// Weights per sample and equation (N, N m).
        phi: Vec<f64>,
    },
}

/// Everything the residual loss of one batch needs besides the prediction.
pub struct OdeLoss {
    /// The channel map.
    pub map: std::sync::Arc<ChannelMap>,
    /// One sample's equations per batch row.
    pub samples: Vec<std::sync::Arc<SampleEquations>>,
    /// Excitations `[B, T, E]` (m).
    pub eta: Vec<f64>,
    /// Number of excitation channels `E`.
    pub n_eta: usize,
    /// Output channel means.
    pub mean: Vec<f64>,
    /// Output channel stds.
    pub std: Vec<f64>,
    /// Time step (s).
    pub dt: f64,
    /// Residual weights.
    pub weights: OdeWeights,
    /// Left by the forward pass for the backward pass of the same batch.
    pub forward: ForwardCache,
}

/// What the forward pass of an [`OdeLoss`] leaves for its backward pass: every residual
/// `[B, T-2, Q]` and every nonlinear element's deflection `[B, T-2, N]` at the interior points,
/// so the backward pass does not evaluate the equations again (they are half of its cost).
#[derive(Debug, Default)]
pub struct ForwardCache(std::sync::Mutex<Option<Evaluated>>);

/// The residuals and nonlinear deflections of a prediction (see [`ForwardCache`]).
#[derive(Debug)]
struct Evaluated {
    residuals: Vec<f64>,
    deflections: Vec<f64>,
}

impl OdeLoss {
    /// The weighted sum of `|R|` over a prediction `[b, t, c]`, with every residual and every
    /// nonlinear element's deflection at the interior points.
    fn evaluate(&self, u: &[f32], b: usize, t: usize, c: usize) -> (f64, Evaluated) {
        let q = self.map.equations.len();
        let mut total = 0.0f64;
        let mut s = State::new(&self.map);
        let mut residuals = Vec::with_capacity(b * (t - 2) * q);
        let mut deflections = Vec::new();
        let mut r = vec![0.0; q];
        for k in 0..b {
            let eq = &self.samples[k].eq;
            let mut scratch = eq.scratch();
            let w: Vec<f64> = (0..q).map(|i| self.weight(k, i)).collect();
            for n in 1..t - 1 {
                self.state(u, k, t, c, n, &mut s);
                eq.residuals(&s.view(), &mut scratch, &mut r);
                total += r.iter().zip(&w).map(|(r, w)| r.abs() * w).sum::<f64>();
                residuals.extend_from_slice(&r);
                deflections.extend(eq.nonlinear().iter().map(|&e| eq.element(&scratch, e).1));
            }
        }
        (
            total,
            Evaluated {
                residuals,
                deflections,
            },
        )
    }

    /// The physical state of sample `k` at interior point `n` from `u` (rows of `c`
    /// channels, `t` points per sample).
    fn state(&self, u: &[f32], k: usize, t: usize, c: usize, n: usize, s: &mut State) {
        let base = k * t * c;
        let at = |r: usize, ch: usize| u[base + r * c + ch] as f64;
        let dt = self.dt;
        for i in 0..self.map.dofs {
            let (prev, mid, next) = (at(n - 1, i), at(n, i), at(n + 1, i));
            s.z[i] = mid * self.std[i] + self.mean[i];
            s.v[i] = (next - prev) / (2.0 * dt) * self.std[i];
            s.a[i] = (next - 2.0 * mid + prev) / (dt * dt) * self.std[i];
        }
        for (p, ch) in self.map.point.iter().enumerate() {
            if let Some(ch) = *ch {
                s.point_w[p] = at(n, ch) * self.std[ch] + self.mean[ch];
                s.point_rate[p] = (at(n + 1, ch) - at(n - 1, ch)) / (2.0 * dt) * self.std[ch];
            }
        }
        let e = self.n_eta;
        let eta = |r: usize, j: usize| self.eta[(k * t + r) * e + j];
        for (el, ch) in self.map.eta.iter().enumerate() {
            if let Some(j) = *ch {
                s.eta[el] = eta(n, j);
                s.eta_rate[el] = match self.map.eta_rate[el] {
                    Some(r) => eta(n, r),
                    None => (eta(n + 1, j) - eta(n - 1, j)) / (2.0 * dt),
                };
            }
        }
    }

    fn weight(&self, k: usize, i: usize) -> f64 {
        match &self.weights {
            OdeWeights::Global { f_ref } => 1.0 / f_ref,
            OdeWeights::Phi { rho, phi } => rho / phi[k * self.map.equations.len() + i],
        }
    }
}

fn dims(shape: &Shape, map: &ChannelMap) -> candle_core::Result<(usize, usize, usize)> {
    let (b, t, c) = shape.dims3()?;
    if t < 3 || c < map.dofs {
        return Err(candle_core::Error::Msg(format!(
            "fused ODE loss: prediction {shape:?} needs >= 3 points and >= {} channels",
            map.dofs
        )));
    }
    Ok((b, t, c))
}

/// `upstream * df/dd` of a nonlinear law at deflection `d` (Hertz 3/2 written as the
/// historical `1.5 sqrt(d / G) / G`).
fn chain(law: &ModelLaw, d: f64, upstream: f64) -> f64 {
    match law {
        ModelLaw::Hertz { g, exponent } if *exponent == 1.5 => {
            if d > 0.0 {
                upstream * 1.5 * (d / g).sqrt() / g
            } else {
                0.0
            }
        }
        law => upstream * law.stiffness(d),
    }
}

impl CustomOp1 for OdeLoss {
    fn name(&self) -> &'static str {
        "fused-ode-loss"
    }

    fn cpu_fwd(
        &self,
        storage: &CpuStorage,
        layout: &CLayout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (b, t, c) = dims(layout.shape(), &self.map)?;
        let u = crate::kernels::cpu_f32(storage, layout, "fused ODE loss", "prediction")?;
        let q = self.map.equations.len();
        let (total, evaluated) = self.evaluate(u, b, t, c);
        *self.forward.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(evaluated);
        let mean = total / (b * (t - 2) * q) as f64;
        Ok((CpuStorage::F32(vec![mean as f32]), Shape::from(())))
    }

    fn bwd(
        &self,
        arg: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        let (b, t, c) = dims(arg.shape(), &self.map)?;
        let q = self.map.equations.len();
        let upstream = grad_res.to_dtype(DType::F64)?.to_scalar::<f64>()?;
        let scale = upstream / (b * (t - 2) * q) as f64;
        let (d, p) = (self.map.dofs, self.map.point.len());
        let cols = self.map.columns();
        let cached = self
            .forward
            .0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        let grad = crate::kernels::with_host(arg, |u| {
            let mut g = vec![0.0f64; u.len()];
            // The forward pass's residuals and deflections (evaluated again when this op's
            // backward runs without its forward, as a graph may).
            let evaluated = match cached {
                Some(e) if e.residuals.len() == b * (t - 2) * q => e,
                _ => self.evaluate(u, b, t, c).1,
            };
            for k in 0..b {
                let se = &self.samples[k];
                let eq = &se.eq;
                let terms: Vec<Vec<(StateEntry, f64)>> = eq
                    .nonlinear()
                    .iter()
                    .map(|&e| eq.deflection_terms(e))
                    .collect();
                let base = k * t * c;
                let n_nl = eq.nonlinear().len();
                let mut dx = vec![0.0f64; cols + n_nl];
                let (mut dz, mut dw) = (vec![0.0f64; d], vec![0.0f64; p]);
                for n in 1..t - 1 {
                    let point = k * (t - 2) + n - 1;
                    let r = &evaluated.residuals[point * q..(point + 1) * q];
                    let defl = &evaluated.deflections[point * n_nl..(point + 1) * n_nl];
                    // dL/dR, then dL/d(state, f) = J^T dL/dR over the Jacobian's nonzeros
                    // (row by row, as the dense product: the same sums).
                    dx.fill(0.0);
                    for (i, row) in se.jacobian_nonzeros.iter().enumerate() {
                        let dr = scale * self.weight(k, i) * r[i].signum();
                        if dr != 0.0 {
                            for &(col, j) in row {
                                dx[col] += dr * j;
                            }
                        }
                    }
                    // Nonlinear forces back onto the state of their deflections.
                    dz.copy_from_slice(&dx[..d]);
                    dw.copy_from_slice(&dx[3 * d..3 * d + p]);
                    for (j, &e) in eq.nonlinear().iter().enumerate() {
                        let ge = chain(eq.law(e), defl[j], dx[cols + j]);
                        for &(entry, coef) in &terms[j] {
                            match entry {
                                StateEntry::Dof(i) => dz[i] += ge * coef,
                                StateEntry::Point(pt) => dw[pt] += ge * coef,
                                StateEntry::Eta(_) => {}
                            }
                        }
                    }
                    for (pt, ch) in self.map.point.iter().enumerate() {
                        let Some(ch) = *ch else { continue };
                        let sd = self.std[ch];
                        g[base + n * c + ch] += dw[pt] * sd;
                        let gr = dx[3 * d + p + pt] * sd / (2.0 * self.dt);
                        if gr != 0.0 {
                            g[base + (n + 1) * c + ch] += gr;
                            g[base + (n - 1) * c + ch] -= gr;
                        }
                    }
                    for i in 0..d {
                        let sd = self.std[i];
                        let gv = dx[d + i] * sd / (2.0 * self.dt);
                        let ga = dx[2 * d + i] * sd / (self.dt * self.dt);
                        g[base + (n + 1) * c + i] += gv + ga;
                        g[base + (n - 1) * c + i] += -gv + ga;
                        g[base + n * c + i] += dz[i] * sd - 2.0 * ga;
                    }
                }
            }
            g.into_iter().map(|x| x as f32).collect::<Vec<f32>>()
        })?;
        Ok(Some(Tensor::from_vec(grad, arg.shape(), arg.device())?))
    }
}

/// De-normalised interior values, first and second differences of `u_n [B, T, C]` (z-scored,
/// any float dtype) with channel statistics `stats` (first C channels used): three f64 tensors
/// `[B, T-2, C]` in physical units:
/// `v_n = (u_{n+1} - u_{n-1}) / (2 dt)`, `a_n = (u_{n+1} - 2 u_n + u_{n-1}) / dt^2`, taken on
/// z-scored values and scaled by the channel std (the mean cancels).
pub fn derivatives(
    u_n: &Tensor,
    stats: &ChannelStats,
    dt: f64,
) -> Result<(Tensor, Tensor, Tensor)> {
    let (_, t, c) = u_n.dims3()?;
    let u = u_n.to_dtype(DType::F64)?;
    let row = |v: &[f64]| Tensor::from_slice(v, (1, 1, v.len()), u.device());
    let std = row(&stats.std[..c])?;
    let mean = row(&stats.mean[..c])?;
    let prev = u.narrow(1, 0, t - 2)?;
    let mid = u.narrow(1, 1, t - 2)?;
    let next = u.narrow(1, 2, t - 2)?;
    let z = mid.broadcast_mul(&std)?.broadcast_add(&mean)?;
    let v = ((&next - &prev)? * (1.0 / (2.0 * dt)))?.broadcast_mul(&std)?;
    let a = ((&next - (&mid * 2.0)?)? + &prev)?
        .affine(1.0 / (dt * dt), 0.0)?
        .broadcast_mul(&std)?;
    Ok((z, v, a))
}

/// The residuals `[B, T-2, Q]` (f64, N or N m) of a z-scored prediction as candle ops on any
/// device: `R = J [state, f_nl] + offset` per sample, the state from [`derivatives`] of the
/// predicted channels and the excitations, `f_nl` the Hertz forces `(max(d, 0) / G)^(3/2)` of
/// the contacts' deflections `d = D state`. Tables are refused (the CPU's fused op has them).
pub fn composed_residuals(
    map: &ChannelMap,
    samples: &[std::sync::Arc<SampleEquations>],
    u_n: &Tensor,
    eta: &Tensor,
    outputs: &ChannelStats,
    dt: f64,
) -> Result<Tensor> {
    let (b, _, _) = u_n.dims3()?;
    let dev = u_n.device();
    let state = composed_state(map, u_n, eta, outputs, dt)?;
    let cols = map.columns();
    let q = map.equations.len();
    let hertz = HertzTerms::of(map, samples, b, cols)?;
    let nl = hertz.nl;
    let (jl, jn, off) = jacobian_blocks(samples, b, cols, nl, q);
    let jl = Tensor::from_vec(jl, (b, cols, q), dev)?;
    let off = Tensor::from_vec(off, (b, 1, q), dev)?;
    let mut r = state.matmul(&jl)?.broadcast_add(&off)?;
    if nl > 0 {
        let dm = Tensor::from_vec(hertz.dmat, (b, cols, nl), dev)?;
        let inv_g = Tensor::from_vec(hertz.inv_g, (b, 1, nl), dev)?;
        let defl = state.matmul(&dm)?; // [B, T-2, N]
        let f = defl.relu()?.broadcast_mul(&inv_g)?.powf(1.5)?;
        let jn = Tensor::from_vec(jn[..b * nl * q].to_vec(), (b, nl, q), dev)?;
        r = (r + f.matmul(&jn)?)?;
    }
    Ok(r)
}

/// The state `[B, T-2, C]` (f64, physical units, contiguous) the residual's Jacobian reads:
/// the DOFs' values, first and second differences, the points' deflections and rates, the
/// excitations and their rates (zeros for a point or excitation not predicted or stored).
fn composed_state(
    map: &ChannelMap,
    u_n: &Tensor,
    eta: &Tensor,
    outputs: &ChannelStats,
    dt: f64,
) -> Result<Tensor> {
    let (b, t, _) = u_n.dims3()?;
    let (z, v, a) = derivatives(&u_n.narrow(2, 0, map.dofs)?, outputs, dt)?;
    let mut parts = vec![z, v, a];
    let zeros = Tensor::zeros((b, t - 2, 1), DType::F64, u_n.device())?;
    let (w, w_rate) = point_parts(map, u_n, outputs, dt, &zeros)?;
    let (e, e_rate) = excitation_parts(map, eta, t, dt, &zeros)?;
    parts.extend(w);
    parts.extend(w_rate);
    parts.extend(e);
    parts.extend(e_rate);
    // [B, T-2, C]. Contiguous: `cat` along the last axis of strided parts (the narrowed
    // excitations) leaves a permuted layout, which the CPU's matmul reads but cuBLAS refuses
    // ("matmul is only supported for contiguous tensors"; found by the CUDA parity test).
    Ok(Tensor::cat(&parts, 2)?.contiguous()?)
}

/// Point deflections and rates at interior points (physical; `zeros` where not predicted).
fn point_parts(
    map: &ChannelMap,
    u_n: &Tensor,
    outputs: &ChannelStats,
    dt: f64,
    zeros: &Tensor,
) -> Result<(Vec<Tensor>, Vec<Tensor>)> {
    let p = map.point.len();
    let mut w = Vec::with_capacity(p);
    let mut w_rate = Vec::with_capacity(p);
    for ch in &map.point {
        match *ch {
            Some(ch) => {
                let stats = ChannelStats {
                    names: vec![outputs.names[ch].clone()],
                    mean: vec![outputs.mean[ch]],
                    std: vec![outputs.std[ch]],
                };
                let (x, xr, _) = derivatives(&u_n.narrow(2, ch, 1)?, &stats, dt)?;
                w.push(x);
                w_rate.push(xr);
            }
            None => {
                w.push(zeros.clone());
                w_rate.push(zeros.clone());
            }
        }
    }
    Ok((w, w_rate))
}

/// Excitations (physical) and their rates at the interior points of `t`: the stored rate column when
/// the map has one, else the central difference (`zeros` where not stored).
fn excitation_parts(
    map: &ChannelMap,
    eta: &Tensor,
    t: usize,
    dt: f64,
    zeros: &Tensor,
) -> Result<(Vec<Tensor>, Vec<Tensor>)> {
    let eta = eta.to_dtype(DType::F64)?;
    let ne = map.eta.len();
    let mut e = Vec::with_capacity(ne);
    let mut e_rate = Vec::with_capacity(ne);
    for (ch, rate) in map.eta.iter().zip(&map.eta_rate) {
        match *ch {
            Some(j) => {
                let col = eta.narrow(2, j, 1)?;
                e.push(col.narrow(1, 1, t - 2)?);
                e_rate.push(match *rate {
                    Some(r) => eta.narrow(2, r, 1)?.narrow(1, 1, t - 2)?,
                    None => {
                        ((col.narrow(1, 2, t - 2)? - col.narrow(1, 0, t - 2)?)?
                            * (1.0 / (2.0 * dt)))?
                    }
                });
            }
            None => {
                e.push(zeros.clone());
                e_rate.push(zeros.clone());
            }
        }
    }
    Ok((e, e_rate))
}

/// The nonlinear elements' part of the composed residual for `B` samples (row-major over
/// samples): each one's deflection matrix `D [cols, nl]` (`d = D state`) and `1 / G` of each
/// Hertz element (the same elements in every sample).
struct HertzTerms {
    /// Number of nonlinear elements.
    nl: usize,
    /// `[B, cols, nl]`.
    dmat: Vec<f64>,
    /// `[B, 1, nl]`.
    inv_g: Vec<f64>,
}

impl HertzTerms {
    /// The terms of `samples`; an element other than Hertz 3/2 is refused (the fused CPU op
    /// has them).
    fn of(
        map: &ChannelMap,
        samples: &[std::sync::Arc<SampleEquations>],
        b: usize,
        cols: usize,
    ) -> Result<Self> {
        let (d, p) = (map.dofs, map.point.len());
        let nl = samples.first().map_or(0, |s| s.eq.nonlinear().len());
        let mut dmat = vec![0.0; b * cols * nl];
        let mut inv_g = vec![0.0; b * nl];
        for (k, s) in samples.iter().enumerate() {
            for (j, &el) in s.eq.nonlinear().iter().enumerate() {
                match s.eq.law(el) {
                    ModelLaw::Hertz { g, exponent } if *exponent == 1.5 => inv_g[k * nl + j] = 1.0 / g,
                    _ => {
                        return Err(Error::OutOfRange {
                            field: "device".into(),
                            value: "cuda".into(),
                            allowed: "\"cpu\" for descriptions with tabulated elements or a Hertz exponent other than 3/2 (the composed residual has Hertz 3/2 only)".into(),
                        })
                    }
                }
                for (entry, coef) in s.eq.deflection_terms(el) {
                    let col = match entry {
                        StateEntry::Dof(i) => i,
                        StateEntry::Point(pt) => 3 * d + pt,
                        StateEntry::Eta(x) => 3 * d + 2 * p + x,
                    };
                    dmat[(k * cols + col) * nl + j] += coef;
                }
            }
        }
        Ok(Self { nl, dmat, inv_g })
    }
}

/// The Jacobians of `B` samples as the composed residual multiplies them, row-major over samples:
/// the linear block `[B, cols, q]`, the nonlinear forces' block `[B, max(nl, 1), q]` and the
/// offsets `[B, 1, q]`.
fn jacobian_blocks(
    samples: &[std::sync::Arc<SampleEquations>],
    b: usize,
    cols: usize,
    nl: usize,
    q: usize,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut jl = vec![0.0; b * cols * q];
    let mut jn = vec![0.0; b * nl.max(1) * q];
    let mut off = vec![0.0; b * q];
    for (k, s) in samples.iter().enumerate() {
        for i in 0..q {
            for col in 0..cols {
                jl[(k * cols + col) * q + i] = s.jacobian[i][col];
            }
            for j in 0..nl {
                jn[(k * nl + j) * q + i] = s.jacobian[i][cols + j];
            }
            off[k * q + i] = s.offset[i];
        }
    }
    (jl, jn, off)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    fn bridge() -> System {
        let path = format!("{}/../../systems/bridge.yaml", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).unwrap();
        mbd_system::load_str(&text, "bridge.yaml", &Default::default()).unwrap()
    }

    /// The bridge's suspension damper reads its profile's rate from the stored column
    /// `eta_suspension_v`: with a rate that is not the profile's central difference, the
    /// fused op's residual differs from the difference-based one by exactly `c` times the two
    /// rates' gap, and the composed (any-device) residuals equal the fused ones.
    #[test]
    fn a_dampers_profile_rate_is_read_from_its_column() {
        let system = bridge();
        let layout = Layout::of(&system);
        let map = ChannelMap::new(&system, &layout);
        let e = system
            .elements
            .iter()
            .position(|e| e.name == "suspension")
            .unwrap();
        assert_eq!((map.eta[e], map.eta_rate[e]), (Some(0), Some(1)));
        let nominal = system.nominal();
        let sample = Arc::new(SampleEquations::new(&system, &map, &nominal).unwrap());
        let (t, o, ne, dt) = (8, layout.n_outputs(), layout.n_excitations(), 1e-3);
        // Outputs with unit statistics (physical = z-scored); a profile whose stored rate is
        // not its central difference.
        let u: Vec<f32> = (0..t * o).map(|i| 1e-3 * (0.37 * i as f32).sin()).collect();
        let eta: Vec<f64> = (0..t)
            .flat_map(|n| {
                let x = n as f64 * dt;
                [1e-3 * (40.0 * x).sin(), 0.2 * (40.0 * x).cos() + 0.05]
            })
            .collect();
        let stats = ChannelStats {
            names: layout.outputs.clone(),
            mean: vec![0.0; o],
            std: vec![1.0; o],
        };
        let residuals = |map: &ChannelMap| {
            let op = OdeLoss {
                map: Arc::new(map.clone()),
                samples: vec![sample.clone()],
                eta: eta.clone(),
                n_eta: ne,
                mean: stats.mean.clone(),
                std: stats.std.clone(),
                dt,
                weights: OdeWeights::Global { f_ref: 1.0 },
                forward: ForwardCache::default(),
            };
            op.evaluate(&u, 1, t, o).1.residuals
        };
        let stored = residuals(&map);
        let mut differenced = map.clone();
        differenced.eta_rate[e] = None;
        let central = residuals(&differenced);
        let c = match sample.equations().law(e) {
            ModelLaw::SpringDamper { c, .. } => *c,
            law => panic!("{law:?}"),
        };
        assert!(c > 0.0);
        for n in 1..t - 1 {
            let rate = eta[n * ne + 1];
            let difference = (eta[(n + 1) * ne] - eta[(n - 1) * ne]) / (2.0 * dt);
            let gap = (stored[n - 1] - central[n - 1]).abs();
            let want = c * (rate - difference).abs();
            assert!(
                want > 1.0 && (gap - want).abs() <= 1e-9 * want,
                "n = {n}: {gap} vs {want}"
            );
        }
        let dev = candle_core::Device::Cpu;
        let composed = composed_residuals(
            &map,
            std::slice::from_ref(&sample),
            &Tensor::from_vec(u.clone(), (1, t, o), &dev).unwrap(),
            &Tensor::from_vec(eta.clone(), (1, t, ne), &dev).unwrap(),
            &stats,
            dt,
        )
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1::<f64>()
        .unwrap();
        assert_eq!(composed.len(), stored.len());
        for (a, b) in composed.iter().zip(&stored) {
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{a} vs {b}");
        }
    }
}
