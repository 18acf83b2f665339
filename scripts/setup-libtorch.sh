#!/usr/bin/env bash
# Provision a CPU-only libtorch 2.11.0 (what `tch = "=0.24.0"` links against) from PyPI wheels.
#
#   scripts/setup-libtorch.sh [DEST]      default DEST: .libtorch (git-ignored)
#
# Idempotent: does nothing when DEST already holds a complete libtorch. When LIBTORCH is set in
# the environment it is respected and nothing is downloaded. The torch wheel is the CUDA build;
# we keep its CPU libraries and headers, leave out libtorch_cuda*.so (so `tch` builds CPU-only)
# and add the two CUDA runtime libraries libtorch_cpu.so still links against.
set -euo pipefail

TORCH_VERSION=2.11.0
CUDART_SPEC='nvidia-cuda-runtime==13.0.96.*'
CUPTI_SPEC='nvidia-cuda-cupti==13.0.85.*'

root=$(cd "$(dirname "$0")/.." && pwd)
dest=${1:-$root/.libtorch}

if [ -n "${LIBTORCH:-}" ]; then
    if [ -f "$LIBTORCH/lib/libtorch_cpu.so" ]; then
        echo "libtorch: using LIBTORCH=$LIBTORCH"
        exit 0
    fi
    echo "libtorch: LIBTORCH=$LIBTORCH has no lib/libtorch_cpu.so" >&2
    exit 1
fi

stamp="$dest/.complete-$TORCH_VERSION"
if [ -f "$stamp" ]; then
    echo "libtorch: $dest is ready"
    exit 0
fi

python=${PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "libtorch: downloading torch $TORCH_VERSION and the CUDA runtime wheels (about 0.55 GB, once)"
cache="$work/wheels"
mkdir -p "$cache"
for spec in "torch==$TORCH_VERSION" "$CUDART_SPEC" "$CUPTI_SPEC"; do
    "$python" -m pip download --quiet --no-deps --only-binary=:all: \
        --dest "$cache" "$spec"
done

torch_wheel=$(ls "$cache"/torch-"$TORCH_VERSION"-*.whl | head -n 1)
cudart_wheel=$(ls "$cache"/nvidia_cuda_runtime-13.0.96*.whl | head -n 1)
cupti_wheel=$(ls "$cache"/nvidia_cuda_cupti-13.0.85*.whl | head -n 1)

echo "libtorch: extracting into $dest"
"$python" - "$torch_wheel" "$cudart_wheel" "$cupti_wheel" "$work/out" <<'PY'
import os, shutil, sys, zipfile

torch_wheel, cudart_wheel, cupti_wheel, out = sys.argv[1:]
os.makedirs(os.path.join(out, "lib"))

def extract(zf, member, target):
    os.makedirs(os.path.dirname(target), exist_ok=True)
    with zf.open(member) as src, open(target, "wb") as dst:
        shutil.copyfileobj(src, dst, 1 << 20)

with zipfile.ZipFile(torch_wheel) as zf:
    for info in zf.infolist():
        name = info.filename
        if info.is_dir():
            continue
        if name.startswith("torch/include/"):
            extract(zf, name, os.path.join(out, name[len("torch/"):]))
        elif name.startswith("torch/lib/"):
            base = os.path.basename(name)
            if base.startswith("libtorch_cuda"):
                continue  # CPU-only build: tch links CUDA when these are present
            extract(zf, name, os.path.join(out, "lib", base))

for wheel, lib in ((cudart_wheel, "libcudart.so.13"), (cupti_wheel, "libcupti.so.13")):
    with zipfile.ZipFile(wheel) as zf:
        member = next(n for n in zf.namelist() if n.endswith("/lib/" + lib))
        extract(zf, member, os.path.join(out, "lib", lib))

with open(os.path.join(out, "build-version"), "w") as f:
    f.write("2.11.0+cpu\n")
PY

rm -rf "$dest"
mkdir -p "$(dirname "$dest")"
mv "$work/out" "$dest"
touch "$stamp"
echo "libtorch: ready in $dest"
