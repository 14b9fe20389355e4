//! The process's allocator: the system's, asking the kernel to back large blocks with 2 MiB pages
//! (Linux's transparent huge pages, `madvise(MADV_HUGEPAGE)`).
//!
//! A big mesh's analysis writes a few hundred MB of fresh arrays, and with 4 KiB pages the kernel
//! takes one page fault for each 4 KiB of them: on an 871k-face mesh about 50,000 faults, a
//! quarter of the scan's time. Blocks of [`LARGE`] bytes or more are advised to use huge pages
//! (the 2 MiB-aligned part of the block; the ends stay small pages), so they fault 512 times less
//! often. Machines whose kernel has transparent huge pages off ignore the advice; so do other
//! systems, where this is the system allocator unchanged. Small blocks are untouched. The advice
//! changes only how memory is backed, never what a program reads from it.
//!
//! [`keep_freed_memory`] is the other half: freed blocks stay with the process for the next
//! allocation instead of going back to the kernel, which would have to fault and zero them again.
//!
//! [`prefetch`] is for loops whose loads land all over a large array (a vertex's position read
//! from a face, a face's row read in another order): fetched a few steps ahead, their cache misses
//! overlap instead of stalling the loop one by one.

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks from this size up are advised to use huge pages (two huge pages: a smaller block has
/// at most one aligned huge page inside it, often none).
pub const LARGE: usize = 4 << 20;

/// The size and alignment of a huge page.
const HUGE_PAGE: usize = 2 << 20;

/// The system allocator, advising large blocks to use huge pages.
pub struct HugePages;

impl HugePages {
    /// Advises the 2 MiB-aligned pages inside `[p, p + size)` to be huge.
    #[inline]
    fn advise(p: *mut u8, size: usize) {
        #[cfg(target_os = "linux")]
        if !p.is_null() && size >= LARGE {
            let start = (p as usize).next_multiple_of(HUGE_PAGE);
            let end = (p as usize + size) & !(HUGE_PAGE - 1);
            if end > start {
                // SAFETY: the range lies inside a block the allocator just handed out, and the
                // advice does not change its contents; a failure (no THP) is harmless.
                unsafe {
                    libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
                }
            }
        }
        #[cfg(not(target_os = "linux"))]
        let _ = (p, size);
    }
}

// SAFETY: every call is the system allocator's; the advice only changes page backing.
unsafe impl GlobalAlloc for HugePages {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        Self::advise(p, layout.size());
        p
    }

    /// A large zeroed block below glibc's 32 MiB mapping threshold is taken unzeroed, advised,
    /// then zeroed here. glibc's `calloc` zeroes such a block itself when it is recycled or starts
    /// a new thread heap, and that first touch, before the advice, faulted a fresh block in 4 KiB
    /// pages (on the 871k-face torus, 5,900 of the scan's 10,500 faults were in that zeroing).
    /// Blocks glibc maps on their own come zeroed from the kernel, untouched, and are left to it.
    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let size = layout.size();
        let ours = (LARGE..KEPT_BLOCK).contains(&size);
        let p = unsafe {
            if ours {
                System.alloc(layout)
            } else {
                System.alloc_zeroed(layout)
            }
        };
        Self::advise(p, size);
        if ours && !p.is_null() {
            // SAFETY: `p` is a fresh block of `size` bytes.
            unsafe { std::ptr::write_bytes(p, 0, size) };
        }
        p
    }

    #[inline]
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        unsafe { System.dealloc(p, layout) }
    }

    #[inline]
    unsafe fn realloc(&self, p: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, layout, new_size) };
        Self::advise(q, new_size);
        q
    }
}

/// The largest block the system allocator keeps in its heaps rather than mapping on its own
/// (glibc's ceiling for `M_MMAP_THRESHOLD` on 64-bit systems: half of a thread heap's 64 MiB).
/// Where [`keep_freed_memory`] does nothing, [`LARGE`]: `alloc_zeroed` then leaves every block
/// to the system allocator.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const KEPT_BLOCK: usize = 32 << 20;
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
const KEPT_BLOCK: usize = LARGE;

/// Asks the system allocator to keep memory the process frees, for its next allocations: blocks
/// up to 32 MiB come from its heaps instead of a mapping each (unmapped when freed), and
/// the heaps are never trimmed. Call it once, at the start.
///
/// A fresh page costs a fault and the kernel's zeroing, which on the project's virtual machine is
/// slow (44% of `perf`'s samples of a scan of a 1M-face PLY without the search). A scan frees and
/// allocates arrays of the same sizes file after file and stage after stage: with glibc's defaults
/// they went back to the kernel and were faulted in again (a scan of 217 corpus files: 18,100-18,600
/// page faults with the defaults, 8,700-8,900 keeping them; peak memory the same). The process
/// simply does not give memory back before it exits, as a batch tool need not. Blocks above
/// 32 MiB are still mapped and unmapped one by one (keeping a few of them was tried: a
/// scan of a 5M-face mesh then held 30% more memory and faulted no less).
/// Elsewhere than glibc this does nothing.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only changes glibc's thresholds; it is called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, KEPT_BLOCK as libc::c_int);
        libc::mallopt(libc::M_TRIM_THRESHOLD, libc::c_int::MAX);
    }
}

/// Asks the processor to bring `x` into its caches; a hint that changes no value (and does
/// nothing where it is not available).
#[inline(always)]
pub fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of x86-64; a prefetch reads nothing into the program and cannot fault
    // (here the address is a live reference's besides).
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((x as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `VmFlags` of the mapping holding `address`, from `/proc/self/smaps`.
    #[cfg(target_os = "linux")]
    fn flags_at(address: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut inside = false;
        for line in smaps.lines() {
            let range = line
                .split_whitespace()
                .next()
                .and_then(|r| r.split_once('-'));
            if let Some((Ok(lo), Ok(hi))) =
                range.map(|(lo, hi)| (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16)))
            {
                inside = (lo..hi).contains(&address);
            } else if let Some(flags) = line.strip_prefix("VmFlags:").filter(|_| inside) {
                return Some(flags.to_owned());
            }
        }
        None
    }

    /// A large block is advised to use huge pages (`hg` in its mapping's flags), keeps what is
    /// written to it when it grows, and a zeroed one reads as zeros.
    #[test]
    fn large_blocks_are_advised_and_work_as_memory() {
        let size = 3 * LARGE;
        let layout = Layout::from_size_align(size, 8).unwrap();
        unsafe {
            let p = HugePages.alloc_zeroed(layout);
            assert!(!p.is_null());
            let block = std::slice::from_raw_parts_mut(p, size);
            assert!(block.iter().all(|&b| b == 0));
            block.iter_mut().enumerate().for_each(|(i, b)| *b = i as u8);
            #[cfg(target_os = "linux")]
            if std::path::Path::new("/sys/kernel/mm/transparent_hugepage").exists() {
                let inside = (p as usize).next_multiple_of(HUGE_PAGE);
                let flags = flags_at(inside).expect("the block's mapping in /proc/self/smaps");
                assert!(
                    flags.split_whitespace().any(|f| f == "hg"),
                    "flags: {flags}"
                );
            }
            let q = HugePages.realloc(p, layout, 2 * size);
            assert!(!q.is_null());
            let grown = std::slice::from_raw_parts(q, size);
            assert!(grown.iter().enumerate().all(|(i, &b)| b == i as u8));
            HugePages.dealloc(q, Layout::from_size_align(2 * size, 8).unwrap());
            let small = Layout::from_size_align(64, 8).unwrap();
            let s = HugePages.alloc(small);
            assert!(!s.is_null());
            HugePages.dealloc(s, small);
        }
    }
}
