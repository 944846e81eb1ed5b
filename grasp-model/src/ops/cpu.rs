//! Plumbing shared by the CPU custom-op kernels (depthwise, pointwise,
//! im2col, linear, LSTM): the run-time choice of the vector unit, candle's
//! storage read as f32 slices, uninitialised output buffers, the parallel
//! loop over output planes, a pointer the threads share, and `gemm` calls.

use candle_core::{CpuStorage, Layout, Result};

/// Defines `fn $name` to run `$body` compiled for AVX-512 or AVX2 when the
/// CPU has them, and for baseline x86-64 (SSE2) otherwise. The release
/// build targets the baseline, so without this the kernels' loops would
/// vectorize 4 lanes wide instead of 16 or 8. `$body` should call only
/// `#[inline(always)]` functions, so that they are compiled with the
/// features too.
macro_rules! simd_dispatch {
    ($(#[$doc:meta])* fn $name:ident($($arg:ident: $ty:ty),*) $body:block) => {
        $(#[$doc])*
        fn $name($($arg: $ty),*) {
            #[inline(always)]
            fn body($($arg: $ty),*) $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx2,fma")]
                unsafe fn avx512($($arg: $ty),*) {
                    body($($arg),*)
                }
                #[target_feature(enable = "avx2,fma")]
                unsafe fn avx2($($arg: $ty),*) {
                    body($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU supports the enabled features.
                    return unsafe { avx512($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: as above.
                    return unsafe { avx2($($arg),*) };
                }
            }
            body($($arg),*)
        }
    };
}
use rayon::prelude::*;
pub(crate) use simd_dispatch;

/// Whether this CPU has AVX-512 (the kernels written for it alone).
pub(crate) fn has_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

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

/// Raw pointer that may cross threads: every task writes a disjoint tile
/// (the pointwise convolution's `gemm` tiles and its narrow kernel).
#[derive(Clone, Copy)]
pub(crate) struct SendPtr(pub(crate) *mut f32);
unsafe impl Send for SendPtr {}
unsafe impl Sync for SendPtr {}

impl SendPtr {
    /// # Safety
    /// `offset` must stay inside the buffer.
    pub(crate) unsafe fn at(self, offset: usize) -> *mut f32 {
        self.0.add(offset)
    }
}

/// Runs `f` on the f32 data of `t` (copied to a contiguous layout first when
/// it is strided); errors name the kernel `op` and the operand `what`.
pub(crate) fn with_f32<R>(
    op: &str,
    t: &candle_core::Tensor,
    what: &str,
    f: impl FnOnce(&[f32]) -> R,
) -> Result<R> {
    let t = t.contiguous()?;
    let (storage, layout) = t.storage_and_layout();
    match &*storage {
        candle_core::Storage::Cpu(s) => Ok(f(f32_slice(op, s, layout, what)?)),
        _ => candle_core::bail!("{op}: {what} must be on the CPU"),
    }
}

/// A read-only matrix operand of [`gemm_into`]: element (i, j) is
/// `data[i * rs + j * cs]`.
#[derive(Clone, Copy)]
pub(crate) struct MatRef<'a> {
    pub data: &'a [f32],
    pub rs: usize,
    pub cs: usize,
}

impl<'a> MatRef<'a> {
    /// A row-major matrix with `cols` columns.
    pub fn rows(data: &'a [f32], cols: usize) -> Self {
        MatRef {
            data,
            rs: cols,
            cs: 1,
        }
    }

    /// The transpose of a row-major matrix with `cols` columns.
    pub fn transposed(data: &'a [f32], cols: usize) -> Self {
        MatRef {
            data,
            rs: 1,
            cs: cols,
        }
    }

    fn fits(&self, rows: usize, cols: usize) -> bool {
        rows == 0 || cols == 0 || (rows - 1) * self.rs + (cols - 1) * self.cs < self.data.len()
    }
}

/// Products below this many multiply-adds run on one thread: splitting them
/// costs more than it saves.
const PARALLEL_MACS: usize = 1 << 23;

/// `dst (m x n, row-major) = [dst +] lhs (m x k) @ rhs (k x n)` with `gemm`,
/// on candle's rayon pool when the product is large.
pub(crate) fn gemm_into(
    dst: &mut [f32],
    (m, n, k): (usize, usize, usize),
    accumulate: bool,
    lhs: MatRef,
    rhs: MatRef,
) {
    assert!(dst.len() >= m * n, "gemm_into: destination too small");
    assert!(
        lhs.fits(m, k) && rhs.fits(k, n),
        "gemm_into: operand too small"
    );
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        if !accumulate {
            dst[..m * n].fill(0.0);
        }
        return;
    }
    let threads = rayon::current_num_threads();
    let parallelism = if threads > 1 && m * n * k >= PARALLEL_MACS {
        gemm::Parallelism::Rayon(threads)
    } else {
        gemm::Parallelism::None
    };
    // SAFETY: the asserts above keep every index gemm touches in bounds, and
    // `dst` is borrowed mutably for the whole call.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            n as isize,
            accumulate,
            lhs.data.as_ptr(),
            lhs.cs as isize,
            lhs.rs as isize,
            rhs.data.as_ptr(),
            rhs.cs as isize,
            rhs.rs as isize,
            1.0,
            1.0,
            false,
            false,
            false,
            parallelism,
        )
    }
}

/// The transpose of a row-major `rows x cols` matrix, in cache-sized tiles.
pub(crate) fn transpose(m: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    const TILE: usize = 32;
    let mut out = alloc_uninit(rows * cols);
    for r0 in (0..rows).step_by(TILE) {
        for c0 in (0..cols).step_by(TILE) {
            for r in r0..(r0 + TILE).min(rows) {
                for c in c0..(c0 + TILE).min(cols) {
                    out[c * rows + r] = m[r * cols + c];
                }
            }
        }
    }
    out
}
