//! The process-wide allocator of the `ipdf` binary and the Implicit-PDF benchmarks: jemalloc,
//! replacing `malloc`/`free` for libtorch too, told never to hand freed pages back.
//!
//! A training step on CPU allocates and frees activations of hundreds of megabytes (batch 32 ×
//! 4,608 queries × 256 floats is 151 MB per head layer). glibc serves anything above 32 MB with
//! a fresh `mmap`, so every step the kernel zeroes every page again: a quarter of the step's time
//! (`perf`: `clear_page_erms`), in PyTorch as much as here. jemalloc with its purging turned off
//! (`dirty_decay_ms:-1,muzzy_decay_ms:-1`) reuses those pages instead; the price is that the
//! process keeps its peak memory until it exits.

/// Declares jemalloc, configured as this module describes, as the global allocator of the
/// binary that invokes it (once, at the crate root).
#[macro_export]
macro_rules! keep_freed_pages_allocator {
    () => {
        #[global_allocator]
        static ALLOCATOR: $crate::allocator::Jemalloc = $crate::allocator::Jemalloc;

        /// jemalloc's start-up options, read from this symbol before the first allocation.
        #[allow(unsafe_code, non_upper_case_globals)]
        #[unsafe(no_mangle)]
        static malloc_conf: Option<&'static u8> = Some(&$crate::allocator::KEEP_FREED_PAGES[0]);
    };
}

pub use tikv_jemallocator::Jemalloc;

/// jemalloc options: never purge dirty or muzzy pages (NUL-terminated for C).
pub const KEEP_FREED_PAGES: &[u8] = b"dirty_decay_ms:-1,muzzy_decay_ms:-1\0";
