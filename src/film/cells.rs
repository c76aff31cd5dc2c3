//! The film's cell array, zeroed by the OS. A film is 64 bytes a pixel (16 MB at 640 x 400), and
//! its first touch costs one page fault per 4 KiB page: on this project's VM 5.6 ms for 640 x 400,
//! a tenth of a 4-spp render. On Linux, films of 2 MiB and more are therefore mapped anonymously with
//! the range asked to be backed by transparent huge pages (`MADV_HUGEPAGE`, which takes effect where the
//! kernel's THP mode is `always` or `madvise`): 2 MiB per fault, 0.8 ms for the same film; films over
//! [`HUGE_MAX`] are mapped with ordinary pages. Elsewhere, or when the mapping fails, a plain zeroed `Vec`.

use bytemuck::Pod;
use std::ops::{Deref, DerefMut};

/// Huge-page size and the alignment of the range advised.
const HUGE: usize = 2 << 20;

/// The largest film asked for huge pages: 64 MiB (1 M pixels, 1280 x 800). Where free huge pages are
/// scarce the kernel compacts memory for each one at the fault (THP's `defrag = madvise`, the default):
/// measured in session 50 on the Zen 4 VM, a 4K film (530 MB) took 1.16-1.34 s to first touch with the
/// advice and 0.25-0.29 s without (4K renders at 4 spp, 3 rounds each: 3.65-3.70 s against 2.54-3.56 s in
/// all), while films up to 1280 x 720 took 2-41 ms either way.
const HUGE_MAX: usize = 64 << 20;

/// `len` zeroed `T`s (see the module doc).
pub(super) struct Cells<T: Pod> {
    store: Store<T>,
    len: usize,
}

enum Store<T> {
    Vec(Vec<T>),
    /// The mapping and the byte offset of the cells in it (the first 2 MiB boundary).
    #[cfg(target_os = "linux")]
    Map(memmap2::MmapMut, usize),
}

impl<T: Pod> Cells<T> {
    pub(super) fn zeroed(len: usize) -> Self {
        let bytes = len * std::mem::size_of::<T>();
        #[cfg(target_os = "linux")]
        if bytes >= HUGE {
            if let Some(store) = Self::map(bytes) {
                return Cells { store, len };
            }
        }
        let _ = bytes;
        Cells { store: Store::Vec(vec![T::zeroed(); len]), len }
    }

    /// [`Cells::zeroed`], or `None` where the memory cannot be had (where `zeroed` aborts the process).
    pub(super) fn try_zeroed(len: usize) -> Option<Self> {
        let bytes = len.checked_mul(std::mem::size_of::<T>())?;
        #[cfg(target_os = "linux")]
        if bytes >= HUGE {
            if let Some(store) = Self::map(bytes) {
                return Some(Cells { store, len });
            }
        }
        let _ = bytes;
        let mut v = Vec::new();
        v.try_reserve_exact(len).ok()?;
        v.resize(len, T::zeroed());
        Some(Cells { store: Store::Vec(v), len })
    }

    #[cfg(target_os = "linux")]
    fn map(bytes: usize) -> Option<Store<T>> {
        // Room to start at a 2 MiB boundary and to advise whole huge pages.
        let rounded = bytes.checked_next_multiple_of(HUGE)?;
        let map = memmap2::MmapMut::map_anon(rounded.checked_add(HUGE)?).ok()?;
        let offset = (map.as_ptr() as usize).next_multiple_of(HUGE) - map.as_ptr() as usize;
        // Only advice: without THP the pages are ordinary ones, as a Vec's. Not past `HUGE_MAX` (see
        // there).
        if rounded <= HUGE_MAX {
            let _ = map.advise_range(memmap2::Advice::HugePage, offset, rounded);
        }
        offset.is_multiple_of(std::mem::align_of::<T>()).then_some(Store::Map(map, offset))
    }
}

impl<T: Pod> Deref for Cells<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        match &self.store {
            Store::Vec(v) => v,
            #[cfg(target_os = "linux")]
            Store::Map(m, off) => bytemuck::cast_slice(&m[*off..*off + self.len * std::mem::size_of::<T>()]),
        }
    }
}

impl<T: Pod> DerefMut for Cells<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        let len = self.len;
        match &mut self.store {
            Store::Vec(v) => v,
            #[cfg(target_os = "linux")]
            Store::Map(m, off) => bytemuck::cast_slice_mut(&mut m[*off..*off + len * std::mem::size_of::<T>()]),
        }
    }
}

impl<T: Pod> Clone for Cells<T> {
    fn clone(&self) -> Self {
        let mut c = Cells::zeroed(self.len);
        c.copy_from_slice(self);
        c
    }
}

impl<T: Pod + std::fmt::Debug> std::fmt::Debug for Cells<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Cells({} x {} bytes)", self.len, std::mem::size_of::<T>())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small and large buffers come zeroed, hold what is written, and clone exactly.
    #[test]
    fn zeroed_writable_and_cloned() {
        for len in [0usize, 1, 1000, (HUGE / 8) * 3 + 5] {
            let mut c = Cells::<u64>::zeroed(len);
            assert_eq!(c.len(), len);
            assert!(c.iter().all(|&x| x == 0));
            for (i, x) in c.iter_mut().enumerate() {
                *x = i as u64 * 7;
            }
            let d = c.clone();
            assert!(d.iter().enumerate().all(|(i, &x)| x == i as u64 * 7));
        }
    }
}
