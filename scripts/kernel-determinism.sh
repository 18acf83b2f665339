#!/usr/bin/env bash
# Which libtorch CPU kernel settings give the same trained weights: trains the quick preset's
# Single can model for 20 steps of 8 (48-pixel crops, --threads 1) under each setting and prints
# the SHA-256 of its weights. Run it on two machines and compare the columns
# (docs/method.md, "Determinism"). A CUDA build of libtorch trains on the GPU: hide it with
# CUDA_VISIBLE_DEVICES= to measure the CPU.
#
#   scripts/kernel-determinism.sh [IPDF] [WORKDIR]     defaults: target/release/ipdf, a temp folder
set -euo pipefail
ipdf=${1:-target/release/ipdf}
work=${2:-$(mktemp -d)}
"$ipdf" synth --out "$work/data" --objects can --frames 40 --seed 3 --json > /dev/null
train() { # name, then the environment's assignments
    local name=$1
    shift
    env "$@" "$ipdf" train --dataset "$work/data" --object can --labels single \
        --encoder small-cnn --input-size 48 --head 64,64 --epochs 1 --steps-per-epoch 20 \
        --batch-size 8 --threads 1 --out "$work/t_$name" --json > /dev/null
    printf '%-24s %s\n' "$name" "$(sha256sum "$work"/t_"$name"/model-*.safetensors | cut -c1-16)"
}
train pinned
train pinned_again
train mkl_compatible MKL_CBWR=COMPATIBLE
train mkl_sse4_2 MKL_CBWR=SSE4_2
train mkl_avx2 MKL_CBWR=AVX2
train onednn_sse41 ONEDNN_MAX_CPU_ISA=SSE41
train aten_default ATEN_CPU_CAPABILITY=default
train all_generic ATEN_CPU_CAPABILITY=default ONEDNN_MAX_CPU_ISA=SSE41 MKL_CBWR=COMPATIBLE
