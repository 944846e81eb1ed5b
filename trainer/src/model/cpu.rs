//! Plumbing shared by the CPU custom-op kernels (depthwise, pointwise,
//! im2col): reading candle's storage as f32 slices, uninitialised output
//! buffers, and the parallel loop over output planes.

use candle_core::{CpuStorage, Layout, Result};
use rayon::prelude::*;

/// The contiguous f32 data of one operand of kernel `op`; errors name the
/// kernel and the operand (`what`).
pub(crate) fn f32_slice<'a>(
    op: &str,
    s: &'a CpuStorage,
    l: &Layout,
    what: &str,
) -> Result<&'a [f32]> {
    let data = match s {
        CpuStorage::F32(d) => d.as_slice(),
        _ => candle_core::bail!("{op}: {what} must be f32"),
    };
    match l.contiguous_offsets() {
        Some((a, b)) => Ok(&data[a..b]),
        None => candle_core::bail!("{op}: {what} must be contiguous"),
    }
}

/// An output buffer without the cost of zeroing it, as candle's own CPU
/// kernels allocate theirs. Callers must write every element before any read.
pub(crate) fn alloc_uninit(len: usize) -> Vec<f32> {
    let mut v = Vec::with_capacity(len);
    // SAFETY: f32 has no invalid bit patterns and callers overwrite every
    // element before reading it.
    #[allow(clippy::uninit_vec)]
    unsafe {
        v.set_len(len)
    };
    v
}

/// Runs `f(scratch, index, chunk)` over the consecutive `chunk`-sized pieces
/// of `out` in parallel on candle's rayon pool. Each worker thread gets one
/// zeroed scratch buffer of `scratch` floats, reused across its chunks (its
/// contents carry over: `f` resets what it needs).
pub(crate) fn par_chunks<F>(out: &mut [f32], chunk: usize, scratch: usize, f: F)
where
    F: Fn(&mut [f32], usize, &mut [f32]) + Sync + Send,
{
    out.par_chunks_mut(chunk)
        .enumerate()
        .for_each_init(|| vec![0f32; scratch], |buf, (i, dst)| f(buf, i, dst));
}
