//! The process's allocator: the system allocator, with large blocks (images,
//! maps, the scale stack's levels) backed by transparent huge pages where the
//! kernel gives them on request.
//!
//! A 1024² filter touches some 40 MB of fresh memory; at 4 KiB a page that is
//! ten thousand page faults, each taking the kernel's locks and cgroup
//! accounting, a fifth of a `--tol 0.3` scale-map run's time (`perf`). With
//! `/sys/kernel/mm/transparent_hugepage/enabled` at `madvise` (Debian's
//! default) a block only gets 2 MiB pages if asked for them, so every block of
//! at least [`HUGE_FROM`] bytes starts on a 2 MiB boundary and is advised
//! `MADV_HUGEPAGE` as soon as it is allocated, before this allocator or its
//! owner writes to it (a zeroed block is zeroed after the advice; a block the
//! system allocator reuses keeps the pages it has). At `always` the advice
//! changes nothing, at `never` the kernel ignores it; other systems use the
//! system allocator unchanged. Reallocating a large block allocates, copies and
//! frees (the system's `realloc` could move pages instead).
#![allow(
    unsafe_code,
    reason = "a GlobalAlloc wrapper and the madvise call; see the module documentation"
)]

use std::alloc::{GlobalAlloc, Layout, System};

/// The system allocator; blocks of at least [`HUGE_FROM`] bytes aligned to
/// a huge page and advised huge pages.
pub struct HugePages;

/// The size of a transparent huge page on x86-64 and aarch64 (4 KiB base
/// pages).
const HUGE_PAGE: usize = 2 << 20;

/// Blocks from this size on start on a huge page boundary and are advised
/// whole (all but a last partial huge page, which keeps small pages).
pub const HUGE_FROM: usize = 2 * HUGE_PAGE;

/// The layout a block of `layout`'s size is allocated with: aligned to a
/// huge page when large. (Deallocation receives the allocation's size, so
/// it finds the same layout.)
fn system_layout(layout: Layout) -> Layout {
    if layout.size() >= HUGE_FROM && layout.align() < HUGE_PAGE {
        Layout::from_size_align(layout.size(), HUGE_PAGE).unwrap_or(layout)
    } else {
        layout
    }
}

// SAFETY: every block comes from `System` with `system_layout` of the
// caller's layout (its size, an alignment at least the caller's) and goes
// back to it with the same; `realloc` of a large block (before or after)
// allocates, copies the smaller size and frees, as `GlobalAlloc`'s default
// does; `alloc_zeroed` zeroes what it returns. `advise` only changes how the
// kernel backs pages of a block just returned.
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: `system_layout` keeps the caller's non-zero size.
        let p = unsafe { System.alloc(system_layout(layout)) };
        advise(p, layout.size());
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let system = system_layout(layout);
        if system == layout {
            // SAFETY: as in `alloc`.
            return unsafe { System.alloc_zeroed(layout) };
        }
        // A huge-page alignment: the system zeroes such blocks by writing
        // them, which would fault every page in small before the advice.
        // SAFETY: as in `alloc`; the zeroing covers exactly the block.
        unsafe {
            let p = System.alloc(system);
            if !p.is_null() {
                zero(p, layout.size());
            }
            advise(p, layout.size());
            p
        }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `alloc` with `system_layout(layout)`.
        unsafe { System.dealloc(ptr, system_layout(layout)) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if layout.size() < HUGE_FROM && new_size < HUGE_FROM {
            // SAFETY: a small block both before and after: the system's
            // own realloc, with the layout it was allocated with.
            return unsafe { System.realloc(ptr, layout, new_size) };
        }
        // SAFETY: the caller promises a valid non-zero `new_size` for
        // `layout.align()`; the copy stays within both blocks.
        unsafe {
            let new_layout = Layout::from_size_align_unchecked(new_size, layout.align());
            let new = self.alloc(new_layout);
            if !new.is_null() {
                std::ptr::copy_nonoverlapping(ptr, new, layout.size().min(new_size));
                self.dealloc(ptr, layout);
            }
            new
        }
    }
}

/// Advises huge pages for the whole 2 MiB pages inside the `len` bytes at
/// `p` (nothing for a null pointer or a small block).
#[cfg(target_os = "linux")]
fn advise(p: *mut u8, len: usize) {
    if p.is_null() || len < HUGE_FROM {
        return;
    }
    let start = (p as usize).next_multiple_of(HUGE_PAGE);
    let end = (p as usize + len) / HUGE_PAGE * HUGE_PAGE;
    if end > start {
        // SAFETY: `[start, end)` lies inside the block just allocated (whose
        // owner has not touched it yet); `madvise` with `MADV_HUGEPAGE`
        // changes no contents and no permissions, only how later faults are
        // served. Its failure (a kernel without THP) leaves the block as is.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_: *mut u8, _: usize) {}

/// Zeroes the `len` bytes at `p` (a block just allocated, not null) without
/// touching the whole pages inside it: those go back to the kernel
/// (`MADV_DONTNEED`: a private anonymous page, which is what the system
/// allocator's heap and maps are, reads as zeros from then on and gets a
/// page only when written), the partial pages at the ends are written. A
/// zeroed block its owner writes only in part (a scale stack's level built
/// where a scale map reads it) then costs pages only for that part. Where
/// the kernel refuses, every byte is written. The pages are the system's
/// (`sysconf`; 16 or 64 KiB on some aarch64 kernels), and the block must
/// come from an allocator of private memory (the system's does: a
/// replacement preloaded over shared memory would lose its contents to
/// other mappings of it).
#[cfg(target_os = "linux")]
unsafe fn zero(p: *mut u8, len: usize) {
    // SAFETY: `sysconf` reads a constant of the system.
    let page = match unsafe { libc::sysconf(libc::_SC_PAGESIZE) } {
        n if n > 0 => n as usize,
        _ => usize::MAX,
    };
    let start = (p as usize)
        .checked_next_multiple_of(page)
        .unwrap_or(usize::MAX);
    let end = (p as usize + len) / page * page;
    // SAFETY: `[p, p + len)` is the block just allocated; `[start, end)`
    // lies inside it, and `MADV_DONTNEED` on private anonymous memory only
    // replaces its pages with zero-fill-on-demand ones.
    unsafe {
        if end > start
            && libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_DONTNEED) == 0
        {
            std::ptr::write_bytes(p, 0, start - p as usize);
            std::ptr::write_bytes(end as *mut u8, 0, p as usize + len - end);
        } else {
            std::ptr::write_bytes(p, 0, len);
        }
    }
}

#[cfg(not(target_os = "linux"))]
unsafe fn zero(p: *mut u8, len: usize) {
    // SAFETY: `[p, p + len)` is the block just allocated.
    unsafe { std::ptr::write_bytes(p, 0, len) }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::HUGE_FROM;

    /// The kernel's transparent huge page mode (`always`, `madvise` or
    /// `never`), if it has the setting.
    fn thp_mode() -> Option<String> {
        let s = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled").ok()?;
        let start = s.find('[')? + 1;
        let end = s[start..].find(']')? + start;
        Some(s[start..end].to_string())
    }

    /// `AnonHugePages` of this process, in kB.
    fn anon_huge_kb() -> u64 {
        let s = std::fs::read_to_string("/proc/self/smaps_rollup").unwrap_or_default();
        s.lines()
            .find_map(|l| l.strip_prefix("AnonHugePages:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .unwrap_or(0)
    }

    /// A large block, written through, is backed by huge pages where the
    /// kernel hands them out on request (the test binary uses the binary's
    /// allocator); elsewhere it says it checked nothing.
    #[test]
    fn large_blocks_get_huge_pages() {
        let mode = thp_mode();
        if mode.as_deref() != Some("madvise") {
            // counted as skipped, not passed (tests/support/skip.rs)
            crate::test_skip::skip(&format!(
                "transparent huge pages are {mode:?}, not on request: nothing to check"
            ));
            return;
        }
        let before = anon_huge_kb();
        let mut block = vec![0u8; 4 * HUGE_FROM];
        for (i, b) in block.iter_mut().enumerate().step_by(4096) {
            *b = i as u8;
        }
        let after = anon_huge_kb();
        assert!(
            block
                .iter()
                .step_by(4096)
                .enumerate()
                .all(|(k, &b)| b == (k * 4096) as u8)
        );
        assert!(
            after >= before + 4 * 2048,
            "huge pages {before} kB -> {after} kB after a {} MiB block",
            block.len() >> 20
        );
    }

    /// `zero` clears exactly the bytes it is given, whole pages and partial
    /// ones, of a block that was written (the kernel's pages handed back
    /// read as zeros), and they can be written again; a large zeroed block
    /// reads as zeros.
    #[test]
    fn zero_clears_exactly_its_bytes() {
        for (skip, len) in [
            (0, 3 * HUGE_FROM),
            (100, 2 * HUGE_FROM + 12_345),
            (4096, 70_000),
            (7, 9),
        ] {
            let mut block = vec![0xA5u8; skip + len + 333];
            // SAFETY: `[skip, skip + len)` lies inside `block`, private
            // memory of this process.
            unsafe { super::zero(block.as_mut_ptr().add(skip), len) };
            assert!(
                block[..skip].iter().all(|&b| b == 0xA5),
                "{skip} {len}: before"
            );
            assert!(
                block[skip..skip + len].iter().all(|&b| b == 0),
                "{skip} {len}: inside"
            );
            assert!(
                block[skip + len..].iter().all(|&b| b == 0xA5),
                "{skip} {len}: after"
            );
            block[skip + len / 2] = 3;
            assert_eq!(block[skip + len / 2], 3);
        }
        let zeroed = vec![0u32; HUGE_FROM];
        assert!(zeroed.iter().all(|&v| v == 0));
    }

    /// Blocks grown and shrunk across the threshold keep their contents
    /// (the allocate-copy-free path) and large blocks start on a huge page.
    #[test]
    fn realloc_across_the_threshold_keeps_contents() {
        let mut v: Vec<u32> = (0..1000).collect();
        v.reserve_exact(HUGE_FROM); // small -> large
        assert_eq!(v.as_ptr() as usize % super::HUGE_PAGE, 0);
        v.extend(1000..(HUGE_FROM as u32 / 2));
        assert!(v.iter().enumerate().all(|(i, &x)| x as usize == i));
        v.truncate(10);
        v.shrink_to_fit(); // large -> small
        assert_eq!(v, (0..10).collect::<Vec<u32>>());
        let mut big = vec![7u8; HUGE_FROM + 5];
        big.reserve(HUGE_FROM); // large -> large
        assert!(big.len() == HUGE_FROM + 5 && big.iter().all(|&b| b == 7));
    }
}
