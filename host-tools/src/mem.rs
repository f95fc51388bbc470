//! Heap in use by the process, for the script sandbox's memory budget.
//!
//! Rhai's own data-size limits re-measure a whole value (recursively) after every call that
//! may change it, so appending to a path of points (`p.push(point(..))`, FullControl's most
//! basic habit) cost O(n) per append and O(n²) per path: 0.46 / 1.74 / 5.75 s for 10k / 20k
//! / 40k points, 90 % of it in `rhai::eval::data_check::calc_array_sizes` (`perf record`).
//! The sandbox therefore turns those limits off and bounds the script's memory as a whole:
//! the `host-tools` binary installs [`Counting`] as its allocator, and the script runner
//! stops a script between two operations once the heap in use exceeds its budget
//! (`design::script::Limits::max_memory_bytes`). Without [`Counting`] installed (the library
//! used from other programs) [`in_use`] reads 0 and only the operation limit applies.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

static IN_USE: AtomicUsize = AtomicUsize::new(0);

/// The system allocator, counting the bytes in use.
pub struct Counting;

// SAFETY: every call is forwarded to `System` with the same arguments; the counter is only
// bookkeeping and never changes what is allocated.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract is `System`'s.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            IN_USE.fetch_add(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            IN_USE.fetch_add(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by this allocator (so by `System`) with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        IN_USE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as `dealloc`, and `new_size` is the caller's.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            IN_USE.fetch_add(new_size, Ordering::Relaxed);
            IN_USE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }
}

/// Bytes allocated through [`Counting`] and not yet freed (0 when it is not installed).
pub fn in_use() -> usize {
    IN_USE.load(Ordering::Relaxed)
}

/// Lets the C allocator keep freed memory for the next allocation instead of returning it
/// to the kernel at once (glibc on Linux; elsewhere nothing): large blocks come from the heap
/// rather than their own mappings (up to 32 MiB, glibc's maximum), and up to 128 MiB of free
/// heap stays mapped. A compile allocates and frees its model, checks and G-code buffers a
/// few times over; with glibc's defaults every large buffer was a fresh mapping whose pages
/// the kernel zeroed on first touch: the 45k-point helix spent 0.014 s of its 0.066 s in the
/// kernel (farm-bench median of 9, `MALLOC_MMAP_THRESHOLD_`/`MALLOC_TRIM_THRESHOLD_` set:
/// 0.008 of 0.056 s). Call once, before allocating much (the binary's `main`).
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // glibc's `mallopt` parameters (malloc.h).
        const M_TRIM_THRESHOLD: i32 = -1;
        const M_TOP_PAD: i32 = -2;
        const M_MMAP_THRESHOLD: i32 = -3;
        extern "C" {
            fn mallopt(param: i32, value: i32) -> i32;
        }
        // SAFETY: `mallopt` only sets allocator tunables; it is safe to call at any time
        // from one thread (here before any other thread exists), and a value it refuses
        // leaves the setting as it was (return value 0).
        unsafe {
            mallopt(M_MMAP_THRESHOLD, 32 << 20);
            mallopt(M_TRIM_THRESHOLD, 128 << 20);
            mallopt(M_TOP_PAD, 16 << 20);
        }
    }
}
