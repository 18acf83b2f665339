//! Making CUDA available to binaries built against a CPU libtorch.
//!
//! `tch` reports "CUDA not available" unless `libtorch_cuda.so` is loaded: the linker drops it
//! when nothing references it directly, and a binary built on a machine without it never links
//! it at all. Loading it at start-up runs its static initialisers, which register the CUDA
//! backend with libtorch; after that `tch::Cuda::is_available()` is true on a machine with a GPU.
use tch::Device;

/// Loads `libtorch_cuda.so` from the dynamic loader's search path (e.g. `LD_LIBRARY_PATH` set
/// to a CUDA build of torch 2.11's `lib` folder) and keeps it loaded for the life of the
/// process. Returns whether it was found. Harmless when already loaded or absent; call it
/// before the first [`Device::cuda_if_available`].
pub fn load_cuda_backend() -> bool {
    load_library("libtorch_cuda.so")
}

#[cfg(unix)]
#[allow(unsafe_code)]
fn load_library(name: &str) -> bool {
    use libloading::os::unix::{Library, RTLD_GLOBAL, RTLD_NOW};
    // SAFETY: loading a library runs its initialisers. libtorch_cuda's register the CUDA
    // backend with the libtorch this process already uses (same install, found through the
    // same search path); nothing is called through the handle, and the library is never
    // unloaded (`forget`), so no symbol outlives it.
    match unsafe { Library::open(Some(name), RTLD_NOW | RTLD_GLOBAL) } {
        Ok(library) => {
            std::mem::forget(library);
            true
        }
        Err(_) => false,
    }
}

#[cfg(not(unix))]
fn load_library(_name: &str) -> bool {
    false
}

/// The device new tensors and models should live on: after [`load_cuda_backend`], the first
/// CUDA device when one is visible, the CPU otherwise.
pub fn default_device() -> Device {
    load_cuda_backend();
    Device::cuda_if_available()
}
