//! Embeds libtorch's library folder as the run-time search path (RUNPATH) of every binary, test
//! and benchmark of the package, so that `target/*/ipdf` and `cargo test` find `libtorch_cpu.so`
//! without `LD_LIBRARY_PATH`. An `LD_LIBRARY_PATH` set at run time still wins over RUNPATH (used
//! to run a binary built here against another machine's CUDA libtorch).
//!
//! `torch-sys` (links = "tch") reports the folder it linked against as `DEP_TCH_LIBTORCH_LIB`; a
//! package gets that variable only when it depends on `torch-sys` directly. `examples` and
//! `benches` reuse this file as their build script.
fn main() {
    println!("cargo:rerun-if-env-changed=DEP_TCH_LIBTORCH_LIB");
    if let Ok(lib) = std::env::var("DEP_TCH_LIBTORCH_LIB") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{lib}");
    }
}
