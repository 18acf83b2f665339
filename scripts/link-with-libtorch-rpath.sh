#!/bin/sh
# The linker of the workspace's binaries, tests and benchmarks on Linux (.cargo/config.toml): the
# C compiler rustc uses by default, plus libtorch's library folder as the run-time search path
# (RUNPATH) of what it links, so that `target/*/ipdf`, `cargo test` and `cargo bench` find
# libtorch_cpu.so without LD_LIBRARY_PATH. LIBTORCH comes from .cargo/config.toml (`.libtorch`,
# made by scripts/setup-libtorch.sh) or from your environment. An LD_LIBRARY_PATH set at run
# time still wins over RUNPATH (docs/gpu.md runs a binary built here against a CUDA libtorch).
if [ -n "${LIBTORCH:-}" ]; then
    exec cc "$@" "-Wl,-rpath,$LIBTORCH/lib"
fi
exec cc "$@"
