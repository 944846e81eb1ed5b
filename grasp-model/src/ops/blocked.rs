//! Inference kernels on channel-blocked activations, for one image at a
//! time on AVX-512 CPUs: the inference path of EfficientNet-Lite
//! (`networks::lite_blocked`).
//!
//! A [`BlockedMap`] holds a (C, H, W) map as `[C / 16][H][W][16]` (NCHW16c,
//! oneDNN's and ONNX Runtime's NCHWc): each pixel's 16 channels of a block
//! are one AVX-512 vector. In this layout
//! - a 1x1 convolution ([`PointwiseWeights`]) keeps a tile of 16 output
//!   channels x a few pixels in registers and reads the input in place,
//!   each output written once with its bias, residual and ReLU6;
//! - a depthwise convolution ([`DepthwiseWeights`]) is one vector per
//!   output pixel and tap, reading its neighbours in place: no padded copy
//!   of the plane, no polyphase split, no throwaway outputs;
//! - the stem ([`StemWeights`]) reads the NCHW image in place.
//!
//! Channel counts that are not multiples of 16 (EfficientNet-Lite's 24 and
//! 40) fill their last block with zero lanes, which every kernel writes as
//! zeros and reads past. Each output is summed in the order of the NCHW
//! kernels (`ops::pointwise`, `ops::depthwise`), so the two paths agree to
//! the bit up to the sign of zero (grasp-model's parity tests).

use super::depthwise::Padding;
use region::Region;
use std::ops::Range;
use std::sync::Arc;

mod depthwise;
mod pointwise;
mod region;
mod stem;
mod team;
#[cfg(test)]
mod tests;

pub use depthwise::DepthwiseWeights;
pub use pointwise::PointwiseWeights;
pub use stem::StemWeights;

/// Channels per block: one AVX-512 vector of f32.
pub const LANES: usize = 16;

/// Whether this CPU runs the blocked kernels (AVX-512).
pub fn available() -> bool {
    super::cpu::has_avx512()
}

/// One vector of f32: a pixel's channels of one block.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(64))]
struct Vector([f32; LANES]);

/// A k x k window's geometry over an h x w input at a stride, padded as a
/// [`Padding`] says (the stem's and the depthwise layers').
#[derive(Clone, Copy, Debug)]
struct Geometry {
    h: usize,
    w: usize,
    oh: usize,
    ow: usize,
    /// Padding above and to the left.
    pt: usize,
    pl: usize,
}

impl Geometry {
    /// `None` when the kernel does not fit the padded input.
    fn new(h: usize, w: usize, k: usize, stride: usize, padding: Padding) -> Option<Self> {
        let (oh, pt) = padding.resolve(h, k, stride)?;
        let (ow, pl) = padding.resolve(w, k, stride)?;
        Some(Geometry {
            h,
            w,
            oh,
            ow,
            pt,
            pl,
        })
    }
}

/// A layer's packed weights or bias: a range of vectors in a region that
/// [`gather`] shares among a network's layers.
#[derive(Clone, Debug)]
pub struct Packed {
    region: Arc<Region>,
    start: usize,
    len: usize,
}

impl Packed {
    fn own(region: Region) -> Self {
        let len = region.as_slice().len() / LANES;
        Packed {
            region: Arc::new(region),
            start: 0,
            len,
        }
    }

    fn as_slice(&self) -> &[f32] {
        &self.region.as_slice()[self.start * LANES..(self.start + self.len) * LANES]
    }
}

/// Moves `parts` (a network's packed layers) into one region, on huge
/// pages where the kernel has them ([`region`]): a frame then walks a few
/// pages for its weights instead of thousands.
pub fn gather<'a>(parts: impl IntoIterator<Item = &'a mut Packed>) {
    let mut parts: Vec<&mut Packed> = parts.into_iter().collect();
    let total = parts.iter().map(|p| p.len).sum();
    let mut region = Region::uninit(total);
    let mut at = 0;
    for p in &parts {
        let n = p.len * LANES;
        region.as_mut_slice()[at..at + n].copy_from_slice(p.as_slice());
        at += n;
    }
    let region = Arc::new(region);
    let mut start = 0;
    for p in &mut parts {
        **p = Packed {
            region: Arc::clone(&region),
            start,
            len: p.len,
        };
        start += p.len;
    }
}

/// A layer's weights and bias packed for the kernels: `weight` holds one
/// row of `per` values (input channels, taps) for each of the bias's
/// outputs; they become `[output block][per][16]`, and the bias whole
/// blocks, both zero past the outputs.
fn pack(weight: &[f32], bias: &[f32], per: usize) -> (Packed, Packed) {
    let outputs = bias.len();
    assert_eq!(weight.len(), outputs * per, "{outputs} x {per} weights");
    let blocks = outputs.div_ceil(LANES);
    let mut w = Region::zeros(blocks * per);
    for (o, row) in weight.chunks_exact(per).enumerate() {
        let block = &mut w.as_mut_slice()[(o / LANES) * per * LANES..];
        for (i, &v) in row.iter().enumerate() {
            block[i * LANES + o % LANES] = v;
        }
    }
    let mut padded = Region::zeros(blocks);
    padded.as_mut_slice()[..outputs].copy_from_slice(bias);
    (Packed::own(w), Packed::own(padded))
}

/// One image's (C, H, W) activations in blocks of [`LANES`] channels,
/// `[block][y][x][lane]`; the lanes past C are zero.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockedMap {
    data: Region,
    channels: usize,
    h: usize,
    w: usize,
}

impl BlockedMap {
    /// A map whose every element the caller writes before any read, in a
    /// buffer of an earlier map of this thread when one is large enough.
    fn uninit(channels: usize, h: usize, w: usize) -> Self {
        let len = channels.div_ceil(LANES) * h * w * LANES;
        BlockedMap {
            data: spare::take(len / LANES),
            channels,
            h,
            w,
        }
    }

    /// The blocked form of a (C, H, W) map in NCHW order.
    pub fn from_nchw(x: &[f32], channels: usize, h: usize, w: usize) -> Self {
        assert_eq!(x.len(), channels * h * w, "from_nchw: {channels}x{h}x{w}");
        let mut map = BlockedMap {
            data: Region::zeros(channels.div_ceil(LANES) * h * w),
            channels,
            h,
            w,
        };
        let hw = h * w;
        for (c, plane) in x.chunks_exact(hw).enumerate() {
            let block = &mut map.data.as_mut_slice()[(c / LANES) * hw * LANES..];
            for (p, &v) in plane.iter().enumerate() {
                block[p * LANES + c % LANES] = v;
            }
        }
        map
    }

    /// The map in NCHW order (C, H, W).
    pub fn to_nchw(&self) -> Vec<f32> {
        let hw = self.hw();
        let mut out = vec![0.0; self.channels * hw];
        for (c, plane) in out.chunks_exact_mut(hw).enumerate() {
            let block = &self.data.as_slice()[(c / LANES) * hw * LANES..];
            for (p, v) in plane.iter_mut().enumerate() {
                *v = block[p * LANES + c % LANES];
            }
        }
        out
    }

    pub fn channels(&self) -> usize {
        self.channels
    }

    /// (height, width).
    pub fn dims(&self) -> (usize, usize) {
        (self.h, self.w)
    }

    fn hw(&self) -> usize {
        self.h * self.w
    }

    fn blocks(&self) -> usize {
        self.channels.div_ceil(LANES)
    }

    /// Each channel's mean over the pixels (global average pooling),
    /// summed pixel by pixel in order.
    pub fn mean_pool(&self) -> Vec<f32> {
        let hw = self.hw();
        let mut out = Vec::with_capacity(self.blocks() * LANES);
        for block in self.data.as_slice().chunks_exact(hw * LANES) {
            let mut sums = [0f32; LANES];
            for px in block.chunks_exact(LANES) {
                for (s, v) in sums.iter_mut().zip(px) {
                    *s += v;
                }
            }
            out.extend(sums.iter().map(|s| s / hw as f32));
        }
        out.truncate(self.channels);
        out
    }
}

impl Drop for BlockedMap {
    fn drop(&mut self) {
        spare::give(std::mem::take(&mut self.data));
    }
}

/// The buffers of dropped maps, kept per thread for the next ones: a
/// frame's maps are the last frame's sizes, and a fresh allocation of a
/// megabyte comes from the kernel zeroed, page by page.
mod spare {
    use super::Region;
    use std::cell::RefCell;

    /// Buffers kept per thread (a network's largest maps live at once).
    const KEEP: usize = 8;

    thread_local! {
        static SPARE: RefCell<Vec<Region>> = const { RefCell::new(Vec::new()) };
    }

    /// `len` vectors, not initialised: the smallest spare buffer that
    /// holds them, or a new one.
    pub(super) fn take(len: usize) -> Region {
        let reused = SPARE.with_borrow_mut(|spare| {
            let best = (0..spare.len())
                .filter(|&i| spare[i].capacity() >= len)
                .min_by_key(|&i| spare[i].capacity())?;
            Some(spare.swap_remove(best))
        });
        let mut r = reused.unwrap_or_else(|| Region::uninit(len));
        r.set_len(len);
        r
    }

    /// Keeps `r` for a later map, dropping the smallest when full.
    pub(super) fn give(r: Region) {
        if r.capacity() == 0 {
            return;
        }
        SPARE.with_borrow_mut(|spare| {
            spare.push(r);
            if spare.len() > KEEP {
                let smallest = (0..spare.len()).min_by_key(|&i| spare[i].capacity());
                spare.swap_remove(smallest.unwrap_or(0));
            }
        });
    }
}

/// A contiguous f32 vector's pointer that may cross threads: every job of
/// a kernel writes its own outputs.
#[derive(Clone, Copy)]
struct OutPtr(*mut f32);
unsafe impl Send for OutPtr {}
unsafe impl Sync for OutPtr {}

/// Runs `f` on `0..items` split into [`JOBS`] nearly equal ranges (fewer
/// when there are fewer items), on the kernels' [`team::Team`]. Measured
/// against one range per thread in the same order every layer (so that a
/// thread reads what it wrote): dynamic claims of smaller jobs were faster.
fn split(items: usize, f: &(impl Fn(Range<usize>) + Sync)) {
    let jobs = JOBS.min(items.max(1));
    team::Team::global().run(jobs, &|j| f(j * items / jobs..(j + 1) * items / jobs));
}

/// Jobs per layer: enough that a thread the host slows for a moment holds
/// up little of the layer (32 was faster than 8, 16, 64 and 128 in
/// alternating rounds on 2 cores: BENCHMARKS.md).
const JOBS: usize = 32;
