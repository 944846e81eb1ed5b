//! The memory of blocked maps and packed weights: f32 vectors on 64-byte
//! boundaries, so that every vector load and store of the kernels is one
//! cache line (glibc's large allocations start 16 bytes past a page, where
//! each would straddle two), and large buffers on 2 MiB pages where the
//! kernel has transparent huge pages.
//!
//! Why huge pages: at the camera's pace the network sleeps ~30 ms between
//! frames, and the host evicts its translations and cache lines meanwhile;
//! each 4 KiB page of the 14 MB of weights and the megabyte maps then
//! costs a page walk from memory, and the first read of a megabyte took
//! 10x as long as back to back (BENCHMARKS.md, issue 59). On 2 MiB pages
//! that is a few walks per frame.

use super::{Vector, LANES};
use std::ptr::NonNull;

/// Buffers of at least this many bytes are mapped on their own, 2 MiB
/// aligned, and advised to huge pages.
const HUGE_FROM: usize = 1 << 18;
/// A transparent huge page.
const HUGE_PAGE: usize = 2 << 20;

/// `len` vectors of f32, owned.
pub(super) struct Region {
    ptr: NonNull<Vector>,
    len: usize,
    /// The vectors the allocation holds (at least `len`).
    capacity: usize,
    /// Whether the allocation is its own mapping (else the heap's).
    mapped: bool,
}

// SAFETY: a Region owns its allocation alone, like a Vec<Vector>.
unsafe impl Send for Region {}
unsafe impl Sync for Region {}

impl Region {
    /// An empty region (no allocation).
    pub const fn empty() -> Self {
        Region {
            ptr: NonNull::dangling(),
            len: 0,
            capacity: 0,
            mapped: false,
        }
    }

    /// `len` vectors of zeros.
    pub fn zeros(len: usize) -> Self {
        let mut r = Self::uninit(len);
        if !r.mapped {
            r.as_mut_vectors().fill(Vector::default());
        }
        // a fresh mapping is zero already, and untouched: its pages come
        // when first written, huge where the advice took
        r
    }

    /// `len` vectors whose values the caller writes before reading (an
    /// unwritten mapped vector reads as zeros, a heap one as garbage f32s,
    /// which have no invalid bit patterns).
    pub fn uninit(len: usize) -> Self {
        if len == 0 {
            return Self::empty();
        }
        let bytes = len * size_of::<Vector>();
        let ptr = if bytes >= HUGE_FROM {
            map::huge(bytes)
        } else {
            None
        };
        let (ptr, capacity, mapped) = match ptr {
            Some(p) => (
                p,
                bytes.next_multiple_of(HUGE_PAGE) / size_of::<Vector>(),
                true,
            ),
            None => (heap::alloc(len), len, false),
        };
        Region {
            ptr,
            len,
            capacity,
            mapped,
        }
    }

    /// The vectors this region can hold without reallocating.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Sets the length to `len` vectors, at most the capacity; the vectors
    /// past the old length hold whatever was there.
    pub fn set_len(&mut self, len: usize) {
        assert!(len <= self.capacity, "region of {} vectors", self.capacity);
        self.len = len;
    }

    pub fn as_slice(&self) -> &[f32] {
        // SAFETY: `len` initialised-or-plain vectors of LANES f32 each, no
        // padding (Vector is repr(C), 64 bytes); f32 has no invalid bits.
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr().cast(), self.len * LANES) }
    }

    pub fn as_mut_slice(&mut self) -> &mut [f32] {
        // SAFETY: as in `as_slice`, and `&mut self` is the only access.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.as_ptr().cast(), self.len * LANES) }
    }

    fn as_mut_vectors(&mut self) -> &mut [Vector] {
        // SAFETY: as in `as_mut_slice`.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.as_ptr(), self.len) }
    }
}

impl Drop for Region {
    fn drop(&mut self) {
        if self.capacity == 0 {
            return;
        }
        let bytes = self.capacity * size_of::<Vector>();
        // SAFETY: allocated by `uninit` with exactly this capacity.
        unsafe {
            if self.mapped {
                map::unmap(self.ptr, bytes);
            } else {
                heap::free(self.ptr, self.capacity);
            }
        }
    }
}

impl Clone for Region {
    fn clone(&self) -> Self {
        let mut r = Region::uninit(self.len);
        r.as_mut_slice().copy_from_slice(self.as_slice());
        r
    }
}

impl PartialEq for Region {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl std::fmt::Debug for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Region({} vectors)", self.len)
    }
}

impl Default for Region {
    fn default() -> Self {
        Self::empty()
    }
}

/// Small regions: the global allocator, 64-byte aligned.
mod heap {
    use super::Vector;
    use std::alloc::Layout;
    use std::ptr::NonNull;

    fn layout(len: usize) -> Layout {
        Layout::array::<Vector>(len).expect("region size overflows")
    }

    pub(super) fn alloc(len: usize) -> NonNull<Vector> {
        let layout = layout(len);
        // SAFETY: layout is non-zero (len > 0, checked by the caller).
        let p = unsafe { std::alloc::alloc(layout) };
        NonNull::new(p.cast()).unwrap_or_else(|| std::alloc::handle_alloc_error(layout))
    }

    /// # Safety
    /// `p` from `alloc(len)`.
    pub(super) unsafe fn free(p: NonNull<Vector>, len: usize) {
        std::alloc::dealloc(p.as_ptr().cast(), layout(len));
    }
}

/// Large regions: their own anonymous mapping, 2 MiB aligned, advised to
/// transparent huge pages (Linux; elsewhere the heap).
#[cfg(target_os = "linux")]
mod map {
    use super::{Vector, HUGE_PAGE};
    use std::ptr::NonNull;

    /// A mapping of `bytes` rounded up to whole huge pages, on a huge page
    /// boundary; `None` when the kernel refuses it.
    pub(super) fn huge(bytes: usize) -> Option<NonNull<Vector>> {
        let size = bytes.next_multiple_of(HUGE_PAGE);
        let span = size + HUGE_PAGE;
        // SAFETY: a fresh private anonymous mapping; the slack before and
        // after the aligned range is unmapped, never used.
        unsafe {
            let prot = libc::PROT_READ | libc::PROT_WRITE;
            let flags = libc::MAP_PRIVATE | libc::MAP_ANONYMOUS;
            let raw = libc::mmap(std::ptr::null_mut(), span, prot, flags, -1, 0);
            if raw == libc::MAP_FAILED {
                return None;
            }
            let start = (raw as usize).next_multiple_of(HUGE_PAGE);
            let head = start - raw as usize;
            if head > 0 {
                libc::munmap(raw, head);
            }
            let tail = span - head - size;
            if tail > 0 {
                libc::munmap((start + size) as *mut libc::c_void, tail);
            }
            // advice only: without transparent huge pages the mapping
            // still works on 4 KiB pages
            libc::madvise(start as *mut libc::c_void, size, libc::MADV_HUGEPAGE);
            NonNull::new(start as *mut Vector)
        }
    }

    /// # Safety
    /// `p` and `bytes` (the whole capacity) from `huge`.
    pub(super) unsafe fn unmap(p: NonNull<Vector>, bytes: usize) {
        libc::munmap(p.as_ptr().cast(), bytes.next_multiple_of(HUGE_PAGE));
    }
}

#[cfg(not(target_os = "linux"))]
mod map {
    use super::Vector;
    use std::ptr::NonNull;

    pub(super) fn huge(_bytes: usize) -> Option<NonNull<Vector>> {
        None
    }

    pub(super) unsafe fn unmap(_p: NonNull<Vector>, _bytes: usize) {
        unreachable!("no mapped regions off Linux")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_and_large_regions_start_zeroed_on_their_alignment() {
        for len in [
            1,
            100,
            HUGE_FROM / 64 - 1,
            HUGE_FROM / 64,
            3 * HUGE_PAGE / 64 + 5,
        ] {
            let r = Region::zeros(len);
            assert_eq!(r.as_slice().len(), len * LANES);
            assert!(r.as_slice().iter().all(|&v| v == 0.0), "{len}");
            let at = r.as_slice().as_ptr() as usize;
            assert_eq!(at % 64, 0, "{len}");
            if r.mapped {
                assert_eq!(at % HUGE_PAGE, 0, "{len}");
                assert!(r.capacity() >= len);
            }
        }
    }

    #[test]
    fn a_region_is_writable_to_its_capacity_and_clones_its_values() {
        let mut r = Region::uninit(HUGE_FROM / 64 + 1);
        let cap = r.capacity();
        r.set_len(cap);
        for (i, v) in r.as_mut_slice().iter_mut().enumerate() {
            *v = i as f32;
        }
        let c = r.clone();
        assert_eq!(c, r);
        assert_eq!(c.as_slice()[cap * LANES - 1], (cap * LANES - 1) as f32);
        assert_eq!(Region::empty().as_slice(), &[] as &[f32]);
    }
}
