//! The spectral convolution as one fused CPU op with its backward pass.
//!
//! Activations are channel-major, `[C, B, T]`: each (channel, sample) row of `T` points is
//! contiguous, so the truncated DFT runs on rows ([`super::rdft`]) and the pointwise layers are
//! single matrix products over `B T` columns. With `R_m = wr_m + i wi_m` (`[M, C, C']`):
//! ```text
//! forward   X[m,b,c] = DFT_m x[c,b,:]      Y[m,b,o] = sum_c X[m,b,c] R[m,c,o]
//!           y[o,b,t] = sum_m s_m Re(Y[m,b,o] e^{i theta_mt})      s_0 = 1/T, s_m = 2/T
//! backward  G[m,b,o] = s_m DFT_m g[o,b,:]
//!           dR[m,c,o] = sum_b conj(X[m,b,c]) G[m,b,o]      dX[m,b,c] = sum_o G[m,b,o] conj(R[m,c,o])
//!           dx[c,b,t] = sum_m Re(dX[m,b,c] e^{i theta_mt})
//! ```
//! The forward keeps `X` for the backward pass. Rows, row pairs and modes are spread over
//! rayon's pool. The reference composition (dense bases, [`crate::spectral`]) computes the same
//! function on any device; tests check values and gradients against it.

use super::rdft::{RealDft, Workspace};
use candle_core::{CpuStorage, CustomOp3, Layout, Shape, Tensor};
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use std::sync::{Arc, Mutex};

pub(crate) type C32 = Complex<f32>;

/// The fused spectral convolution for one call (it holds the forward spectrum for backward).
pub struct SpectralConvOp {
    dft: Arc<RealDft>,
    batch: usize,
    spectrum: Mutex<Option<Vec<C32>>>,
}

impl SpectralConvOp {
    /// An op over rows of the plan's length for `batch` samples.
    pub fn new(dft: Arc<RealDft>, batch: usize) -> Self {
        Self {
            dft,
            batch,
            spectrum: Mutex::new(None),
        }
    }

    /// Kept modes `M`.
    pub fn modes(&self) -> usize {
        self.dft.modes()
    }

    /// Samples per call `B`.
    pub fn batch(&self) -> usize {
        self.batch
    }

    /// Row length `T`.
    pub fn t_points(&self) -> usize {
        self.dft.len()
    }

    fn synthesis_weights(&self, unit: bool) -> Vec<f32> {
        let t = self.dft.len() as f32;
        (0..self.dft.modes())
            .map(|k| match (unit, k) {
                (true, _) => 1.0,
                (false, 0) => 1.0 / t,
                (false, _) => 2.0 / t,
            })
            .collect()
    }

    /// `rows [R, T]` -> modes `[R, M]`.
    fn analyse_rows(&self, rows: &[f32]) -> Vec<C32> {
        let (t, m) = (self.dft.len(), self.dft.modes());
        let n_rows = rows.len() / t;
        let mut out = vec![C32::default(); n_rows * m];
        out.par_chunks_mut(2 * m)
            .zip(rows.par_chunks(2 * t))
            .for_each_init(
                || self.dft.workspace(),
                |ws: &mut Workspace, (o, r)| {
                    let (oa, ob) = o.split_at_mut(m.min(o.len()));
                    let mut spare = Vec::new();
                    let ob = if ob.is_empty() {
                        spare.resize(m, C32::default());
                        &mut spare[..]
                    } else {
                        ob
                    };
                    let b = (r.len() == 2 * t).then(|| &r[t..]);
                    self.dft.analyse_pair(&r[..t], b, oa, ob, ws);
                },
            );
        out
    }

    /// Modes `[R, M]` -> rows `[R, T]` with synthesis weights `w`.
    fn synthesise_rows(&self, modes: &[C32], w: &[f32]) -> Vec<f32> {
        let mut out = vec![0.0f32; modes.len() / self.dft.modes() * self.dft.len()];
        self.synthesise_rows_into(modes, w, &mut out);
        out
    }

    /// [`Self::synthesise_rows`] into `out [R, T]` (every element written).
    fn synthesise_rows_into(&self, modes: &[C32], w: &[f32], out: &mut [f32]) {
        let (t, m) = (self.dft.len(), self.dft.modes());
        debug_assert_eq!(out.len(), modes.len() / m * t);
        out.par_chunks_mut(2 * t)
            .zip(modes.par_chunks(2 * m))
            .for_each_init(
                || self.dft.workspace(),
                |ws: &mut Workspace, (o, y)| {
                    let (oa, ob) = o.split_at_mut(t);
                    let (ya, yb) = y.split_at(m);
                    let ob = (!ob.is_empty()).then_some(ob);
                    self.dft.synthesise_pair(ya, yb, w, oa, ob, ws);
                },
            );
    }
}

/// `[R = C B, M]` row-major modes -> `[M, B, C]`.
fn rows_to_modes(rows: &[C32], c: usize, b: usize, m: usize) -> Vec<C32> {
    let mut out = vec![C32::default(); rows.len()];
    for ci in 0..c {
        for bi in 0..b {
            let src = &rows[(ci * b + bi) * m..(ci * b + bi + 1) * m];
            for (k, &v) in src.iter().enumerate() {
                out[(k * b + bi) * c + ci] = v;
            }
        }
    }
    out
}

/// `[M, B, C]` -> `[R = C B, M]` row-major modes.
fn modes_to_rows(modes: &[C32], c: usize, b: usize, m: usize) -> Vec<C32> {
    let mut out = vec![C32::default(); modes.len()];
    for k in 0..m {
        for bi in 0..b {
            let src = &modes[(k * b + bi) * c..(k * b + bi + 1) * c];
            for (ci, &v) in src.iter().enumerate() {
                out[(ci * b + bi) * m + k] = v;
            }
        }
    }
    out
}

/// `Y[m,b,:] = sum_c X[m,b,c] R[m,c,:]` for every mode, `x [M, B, C]` -> `[M, B, O]`.
fn mix(x: &[C32], wr: &[f32], wi: &[f32], b: usize, c: usize, o: usize) -> Vec<C32> {
    let mut y = vec![C32::default(); x.len() / c * o];
    y.par_chunks_mut(b * o).enumerate().for_each(|(k, yk)| {
        let (wr, wi) = (
            &wr[k * c * o..(k + 1) * c * o],
            &wi[k * c * o..(k + 1) * c * o],
        );
        let mut acc_re = vec![0.0f32; o];
        let mut acc_im = vec![0.0f32; o];
        for bi in 0..b {
            acc_re.fill(0.0);
            acc_im.fill(0.0);
            for ci in 0..c {
                let xv = x[(k * b + bi) * c + ci];
                let (rr, ri) = (&wr[ci * o..(ci + 1) * o], &wi[ci * o..(ci + 1) * o]);
                super::simd::complex_axpy(xv.re, xv.im, rr, ri, &mut acc_re, &mut acc_im);
            }
            for (oi, v) in yk[bi * o..(bi + 1) * o].iter_mut().enumerate() {
                *v = C32::new(acc_re[oi], acc_im[oi]);
            }
        }
    });
    y
}

/// Gradients of the mixing: `g [M, B, O]`, `x [M, B, C]` -> (`dx [M, B, C]`, `dwr`, `dwi`
/// `[M, C, O]`).
#[allow(clippy::type_complexity)]
fn mix_backward(
    g: &[C32],
    x: &[C32],
    wr: &[f32],
    wi: &[f32],
    b: usize,
    c: usize,
    o: usize,
) -> (Vec<C32>, Vec<f32>, Vec<f32>) {
    let m = x.len() / (b * c);
    let per_mode: Vec<(Vec<C32>, Vec<f32>, Vec<f32>)> = (0..m)
        .into_par_iter()
        .map(|k| {
            let (wr, wi) = (
                &wr[k * c * o..(k + 1) * c * o],
                &wi[k * c * o..(k + 1) * c * o],
            );
            let mut dx = vec![C32::default(); b * c];
            let mut dwr = vec![0.0f32; c * o];
            let mut dwi = vec![0.0f32; c * o];
            let mut g_re = vec![0.0f32; o];
            let mut g_im = vec![0.0f32; o];
            for bi in 0..b {
                for (oi, gv) in g[(k * b + bi) * o..(k * b + bi + 1) * o].iter().enumerate() {
                    g_re[oi] = gv.re;
                    g_im[oi] = gv.im;
                }
                for ci in 0..c {
                    let (rr, ri) = (&wr[ci * o..(ci + 1) * o], &wi[ci * o..(ci + 1) * o]);
                    // dX = sum_o G conj(R)
                    let (re, im) = super::simd::complex_dot_conj(&g_re, &g_im, rr, ri);
                    dx[bi * c + ci] = C32::new(re, im);
                    // dR += conj(X) G
                    let xv = x[(k * b + bi) * c + ci];
                    super::simd::complex_axpy(
                        xv.re,
                        -xv.im,
                        &g_re,
                        &g_im,
                        &mut dwr[ci * o..(ci + 1) * o],
                        &mut dwi[ci * o..(ci + 1) * o],
                    );
                }
            }
            (dx, dwr, dwi)
        })
        .collect();
    let mut dx = Vec::with_capacity(m * b * c);
    let mut dwr = Vec::with_capacity(m * c * o);
    let mut dwi = Vec::with_capacity(m * c * o);
    for (a, r, i) in per_mode {
        dx.extend(a);
        dwr.extend(r);
        dwi.extend(i);
    }
    (dx, dwr, dwi)
}

fn host_f32(t: &Tensor) -> candle_core::Result<Vec<f32>> {
    t.flatten_all()?.to_vec1::<f32>()
}

impl SpectralConvOp {
    fn check(&self, x: &Shape, wr: &Shape, wi: &Shape) -> candle_core::Result<(usize, usize)> {
        let (c, b, t) = x.dims3()?;
        let (m, c2, o) = wr.dims3()?;
        if wr != wi || c2 != c || t != self.dft.len() || m != self.dft.modes() || b != self.batch {
            return Err(candle_core::Error::Msg(format!(
                "fused spectral convolution: x {x:?}, wr {wr:?}, wi {wi:?} do not fit a plan of \
                 T {} and M {} for batch {}",
                self.dft.len(),
                self.dft.modes(),
                self.batch
            )));
        }
        Ok((c, o))
    }

    fn forward(&self, x: &[f32], wr: &[f32], wi: &[f32], c: usize, o: usize) -> Vec<f32> {
        let (out, spectrum) = self.forward_host(x, wr, wi, c, o);
        *self.spectrum.lock().unwrap_or_else(|e| e.into_inner()) = Some(spectrum);
        out
    }

    /// `K x` of host `x [C, B, T]`: (`[O, B, T]`, the spectrum `X [M, B, C]` for backward).
    pub(crate) fn forward_host(
        &self,
        x: &[f32],
        wr: &[f32],
        wi: &[f32],
        c: usize,
        o: usize,
    ) -> (Vec<f32>, Vec<C32>) {
        let mut out = vec![0.0f32; x.len() / c * o];
        let spectrum = self.convolve_into(x, wr, wi, c, o, &mut out);
        (out, spectrum)
    }

    /// `K x` of host `x [C, B, T]` written into `out [O, B, T]` (every element), nothing
    /// kept: the inference form of [`Self::forward_host`].
    pub(crate) fn infer_into(
        &self,
        x: &[f32],
        wr: &[f32],
        wi: &[f32],
        c: usize,
        o: usize,
        out: &mut [f32],
    ) {
        self.convolve_into(x, wr, wi, c, o, out);
    }

    /// `K x` into `out [O, B, T]`; returns the spectrum `X [M, B, C]`.
    fn convolve_into(
        &self,
        x: &[f32],
        wr: &[f32],
        wi: &[f32],
        c: usize,
        o: usize,
        out: &mut [f32],
    ) -> Vec<C32> {
        let (b, m) = (self.batch, self.dft.modes());
        let spectrum = rows_to_modes(&self.analyse_rows(x), c, b, m);
        let y = mix(&spectrum, wr, wi, b, c, o);
        self.synthesise_rows_into(
            &modes_to_rows(&y, o, b, m),
            &self.synthesis_weights(false),
            out,
        );
        spectrum
    }

    /// Backward of [`Self::forward_host`] for the upstream gradient `g [O, B, T]`:
    /// (`dx [C, B, T]`, `dwr`, `dwi [M, C, O]`).
    pub(crate) fn backward_host(
        &self,
        spectrum: &[C32],
        wr: &[f32],
        wi: &[f32],
        grad: &[f32],
        c: usize,
        o: usize,
    ) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
        let (b, m) = (self.batch, self.dft.modes());
        let s = self.synthesis_weights(false);
        let mut g = rows_to_modes(&self.analyse_rows(grad), o, b, m);
        for (k, chunk) in g.chunks_mut(b * o).enumerate() {
            for v in chunk {
                *v *= s[k];
            }
        }
        let (dx_modes, dwr, dwi) = mix_backward(&g, spectrum, wr, wi, b, c, o);
        let dx = self.synthesise_rows(
            &modes_to_rows(&dx_modes, c, b, m),
            &self.synthesis_weights(true),
        );
        (dx, dwr, dwi)
    }

    /// The spectrum `X [M, B, C]` of host `x [C, B, T]`.
    pub(crate) fn spectrum_of(&self, x: &[f32], c: usize) -> Vec<C32> {
        rows_to_modes(&self.analyse_rows(x), c, self.batch, self.dft.modes())
    }
}

impl CustomOp3 for SpectralConvOp {
    fn name(&self) -> &'static str {
        "fused-spectral-conv"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (c, o) = self.check(l1.shape(), l2.shape(), l3.shape())?;
        let op = "fused spectral convolution";
        let x = super::cpu_f32(s1, l1, op, "x")?;
        let wr = super::cpu_f32(s2, l2, op, "wr")?;
        let wi = super::cpu_f32(s3, l3, op, "wi")?;
        let out = self.forward(x, wr, wi, c, o);
        Ok((
            CpuStorage::F32(out),
            Shape::from((o, self.batch, self.dft.len())),
        ))
    }

    fn bwd(
        &self,
        x: &Tensor,
        wr: &Tensor,
        wi: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let (c, b, t) = x.dims3()?;
        let (m, _, o) = wr.dims3()?;
        debug_assert_eq!(b, self.batch);
        let cached = self
            .spectrum
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        let spectrum = match cached {
            Some(s) => s,
            None => self.spectrum_of(&host_f32(x)?, c),
        };
        let (dx, dwr, dwi) = self.backward_host(
            &spectrum,
            &host_f32(wr)?,
            &host_f32(wi)?,
            &host_f32(grad)?,
            c,
            o,
        );
        let dev = x.device();
        Ok((
            Some(Tensor::from_vec(dx, (c, b, t), dev)?),
            Some(Tensor::from_vec(dwr, (m, c, o), dev)?),
            Some(Tensor::from_vec(dwi, (m, c, o), dev)?),
        ))
    }
}
