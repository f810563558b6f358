//! Fused CPU kernels of the Fourier neural operator, as candle custom ops with hand-written
//! backward passes.
//!
//! candle's generic ops are the cost of a CPU training step: the spectral convolution as two
//! dense-basis products grows as `4 M T` per row, and every elementwise op allocates and walks
//! memory once forward and again backward. Here:
//! - [`rdft`]: the truncated real DFT on rows, two real rows per rustfft complex FFT;
//! - [`spectral_op`]: the whole spectral convolution (analysis, complex mode mixing,
//!   synthesis) and its backward pass, over channel-major `[C, B, T]` activations;
//! - [`layer`]: one layer `act(W^T x + b [+ K x])` forward and backward on host memory;
//! - [`network`]: the whole FNO as one candle op built from those layers (one graph node);
//! - [`deriv_loss`]: the direct-derivative loss of algorithms 4 and 5 (stencils, z-scores,
//!   relative L2) and its gradient in one pass;
//! - the ODE-residual losses of algorithms 2 and 3 and their gradient are the fused op of
//!   [`crate::residual`] (they read the system's equations);
//! - [`simd`]: the inner loops, compiled for AVX2 + FMA and AVX-512 with a run-time switch.
//!
//! The candle composition in [`crate::spectral`] and [`crate::model`] computes the same
//! functions on any device (it is the CUDA path) and is the reference the tests check these
//! kernels and their gradients against.

pub mod deriv_loss;
pub mod layer;
pub mod network;
pub mod rdft;
pub mod simd;
pub mod spectral_op;

use crate::Result;
use candle_core::Tensor;
use std::sync::Arc;

pub use layer::FusedLayer;
pub use network::{FusedNetwork, NetworkShape};
pub use rdft::RealDft;
pub use spectral_op::SpectralConvOp;

/// The spectral convolution of channel-major `x [C, B, T]` with weights `wr, wi [M, C, C']`
/// on the plan `dft` (length `T`, `M` modes): `[C', B, T]`.
pub fn spectral_conv(dft: &Arc<RealDft>, x: &Tensor, wr: &Tensor, wi: &Tensor) -> Result<Tensor> {
    let (_, b, _) = x.dims3()?;
    let op = SpectralConvOp::new(Arc::clone(dft), b);
    Ok(x.contiguous()?
        .apply_op3(&wr.contiguous()?, &wi.contiguous()?, op)?)
}

/// The contiguous f32 data of an op's input, or an error naming the op and the input.
pub(crate) fn cpu_f32<'a>(
    storage: &'a candle_core::CpuStorage,
    layout: &candle_core::Layout,
    op: &str,
    what: &str,
) -> candle_core::Result<&'a [f32]> {
    let candle_core::CpuStorage::F32(v) = storage else {
        return Err(candle_core::Error::Msg(format!("{op}: {what} must be f32")));
    };
    let (a, b) = layout
        .contiguous_offsets()
        .ok_or_else(|| candle_core::Error::Msg(format!("{op}: {what} must be contiguous")))?;
    Ok(&v[a..b])
}

/// Runs `f` on the host f32 data of `t` without copying when it is contiguous on the CPU
/// (a copy otherwise).
pub(crate) fn with_host<R>(t: &Tensor, f: impl FnOnce(&[f32]) -> R) -> candle_core::Result<R> {
    {
        let (storage, layout) = t.storage_and_layout();
        if let (candle_core::Storage::Cpu(candle_core::CpuStorage::F32(v)), Some((a, b))) =
            (&*storage, layout.contiguous_offsets())
        {
            return Ok(f(&v[a..b]));
        }
    }
    let copy = t.flatten_all()?.to_vec1::<f32>()?;
    Ok(f(&copy))
}
