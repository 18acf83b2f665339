//! The process-wide allocator of the `ipdf` binary and the Implicit-PDF benchmarks: mimalloc,
//! replacing `malloc`/`free` for libtorch too, told never to hand freed pages back.
//!
//! A training step on CPU allocates and frees activations of hundreds of megabytes (batch 32 ×
//! 4,608 queries × 256 floats is 151 MB per head layer). glibc serves anything above 32 MB with
//! a fresh `mmap`, so every step the kernel zeroes every page again: a quarter of the step's time
//! (`perf`: `clear_page_erms`), in PyTorch as much as here. mimalloc with purging turned off
//! (`purge_delay` −1) reuses those pages instead; the price is that the process keeps its peak
//! memory until it exits. jemalloc with `dirty_decay_ms:-1` gave the same step time (and the
//! same weights) with 22 times as many page faults, and its C build took 75 of the release
//! build's 626 CPU-seconds; mimalloc's takes 5 (see docs/performance.md).

/// Declares mimalloc, configured as this module describes, as the global allocator of the
/// binary that invokes it (once, at the crate root).
#[macro_export]
macro_rules! keep_freed_pages_allocator {
    () => {
        #[global_allocator]
        static ALLOCATOR: $crate::allocator::MiMalloc = $crate::allocator::MiMalloc;

        /// Run by the loader before `main` (an ELF constructor), before libtorch's first
        /// large allocation.
        #[allow(unsafe_code)]
        #[used]
        #[unsafe(link_section = ".init_array")]
        static KEEP_FREED_PAGES: extern "C" fn() = $crate::allocator::keep_freed_pages;
    };
}

pub use mimalloc::MiMalloc;

/// mimalloc's `mi_option_purge_delay` (`mimalloc.h`, v3).
const PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Tells mimalloc never to purge freed pages.
pub extern "C" fn keep_freed_pages() {
    // SAFETY: `mi_option_set` only stores an option value; mimalloc reads it when it purges.
    #[allow(unsafe_code)]
    unsafe {
        libmimalloc_sys::mi_option_set(PURGE_DELAY, -1);
    }
}
