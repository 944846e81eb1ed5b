//! Weights packed once per layer for the AVX-512 1x1 kernels (`narrow`,
//! `wide`): blocks of `width` output channels, each input channel's
//! `width` weights side by side, the last block padded with zeros.

use std::sync::OnceLock;

/// Weights packed for a kernel, with the shape they were packed from.
#[derive(Debug)]
pub struct Packed {
    data: Vec<f32>,
    pub(super) cout: usize,
    pub(super) cin: usize,
    width: usize,
}

impl Packed {
    /// Packs row-major `weight` (cout x cin) in blocks of `width` outputs.
    fn new(weight: &[f32], cout: usize, cin: usize, width: usize) -> Self {
        let blocks = cout.div_ceil(width);
        let mut data = vec![0f32; blocks * cin * width];
        for (o, row) in weight.chunks_exact(cin).take(cout).enumerate() {
            let block = &mut data[(o / width) * cin * width..];
            for (c, &w) in row.iter().enumerate() {
                block[c * width + o % width] = w;
            }
        }
        Packed {
            data,
            cout,
            cin,
            width,
        }
    }

    /// Block `b`: `cin` groups of `width` weights.
    pub(super) fn block(&self, b: usize) -> &[f32] {
        let len = self.cin * self.width;
        &self.data[b * len..(b + 1) * len]
    }
}

/// One kernel's packing of a layer's weights, built on first use (none
/// without AVX-512).
#[derive(Debug, Default)]
pub(super) struct PackCache(OnceLock<Option<Packed>>);

impl PackCache {
    pub(super) fn is_packed(&self) -> bool {
        self.0.get().is_some_and(|p| p.is_some())
    }

    /// The packed form of `weight` (cout x cin) in blocks of `width`, or
    /// `None` when this CPU has no AVX-512 or the cache was packed for
    /// another shape (the caller then uses `gemm`). Packs on the first
    /// call; later calls must pass the same weight.
    pub(super) fn packed(
        &self,
        weight: &[f32],
        cout: usize,
        cin: usize,
        width: usize,
    ) -> Option<&Packed> {
        let packed = self
            .0
            .get_or_init(|| available().then(|| Packed::new(weight, cout, cin, width)))
            .as_ref()?;
        (packed.cout == cout && packed.cin == cin).then_some(packed)
    }
}

/// Whether this CPU runs the packed kernels.
pub(super) fn available() -> bool {
    crate::ops::cpu::has_avx512()
}
