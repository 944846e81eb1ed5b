//! The CPU kernels of the networks, as candle custom ops: depthwise and
//! pointwise convolutions, the linear layer, the fused LSTM recurrence, the
//! feature-row gather, the channel-blocked inference kernels (`blocked`),
//! and the plumbing they share (`cpu`: the vector unit
//! chosen at run time, storage read as f32 slices, `gemm` calls).

pub mod blocked;
pub(crate) mod cpu;
pub mod depthwise;
pub mod gather;
pub mod linear;
pub mod lstm;
pub mod pointwise;

/// The first NaN or infinite value of `t` (read in place when contiguous).
pub fn first_non_finite(t: &candle_core::Tensor) -> candle_core::Result<Option<f32>> {
    cpu::with_f32("finite check", t, "tensor", |v| {
        // x * 0 is NaN exactly for NaN and infinite x; summing lane-wise
        // keeps the common all-finite case a vectorized pass.
        let mut lanes = [0f32; 16];
        let chunks = v.chunks_exact(16);
        let tail = chunks.remainder();
        for c in chunks {
            for (l, x) in lanes.iter_mut().zip(c) {
                *l += x * 0.0;
            }
        }
        let clean = lanes.iter().all(|l| *l == 0.0) && tail.iter().all(|x| x.is_finite());
        if clean {
            None
        } else {
            v.iter().copied().find(|x| !x.is_finite())
        }
    })
}
