#!/usr/bin/env bash
# Every example program of the workspace run once at a miniature scale (part of `make test`):
# each must exit 0 and print the line it exists to print. The examples are built as the
# programs a user runs (`cargo build --examples`, the test profile's settings); the data they
# read is made here with the `ipdf` binary of the same build.
#
#   scripts/run-examples.sh        CARGO: the cargo to run
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cargo="${CARGO:-cargo}"
cd "$root"
"$cargo" build --quiet --workspace --bins --examples
target="$("$cargo" metadata --format-version 1 --no-deps |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')"
examples="$target/debug/examples"
ipdf="$target/debug/ipdf"
work="$(mktemp -d "${TMPDIR:-/tmp}/ipdf-examples.XXXXXX")"
trap 'rm -rf "$work"' EXIT

passed=0
failed=0
# expect NAME PATTERN COMMAND…: runs COMMAND and checks that it exits 0 and prints a line
# matching the extended regular expression PATTERN.
expect() {
    local name=$1 pattern=$2 out
    shift 2
    if out="$("$@" 2>&1)" && grep -qE "$pattern" <<<"$out"; then
        passed=$((passed + 1))
        echo "example $name ... ok"
    else
        failed=$((failed + 1))
        echo "example $name ... FAILED (expected a line matching: $pattern)"
        tail -n 20 <<<"$out" | sed 's/^/    /'
    fi
}
quiet() { "$@" >/dev/null; }

# What the data-reading examples read: a box with a validation split and a single-label model
# of it, a mug's views, and the labelled renders of a coloured scan (YCB's gelatin box).
quiet "$ipdf" synth --out "$work/box" --objects box --frames 2 --json
quiet "$ipdf" synth --out "$work/box" --objects box --frames 2 --split val --seed 1 --json
quiet "$ipdf" train --dataset "$work/box" --object box --labels single \
    --out "$work/models/box/single" --encoder small-cnn --input-size 32 --head 16,16 \
    --epochs 1 --steps-per-epoch 1 --batch-size 2 --json
quiet "$ipdf" synth --out "$work/mugs" --objects mug --frames 2 --json
scan="examples/pseudo-label/tests/data/ycbv_real/models/obj_000007.ply"
quiet "$ipdf" synth --out "$work/scan" --mesh "$scan" --variant texture --frames 2 --json
quiet "$ipdf" label --dataset "$work/scan" --json

expect render_mesh 'pixels of can; wrote' "$examples/render_mesh" "$work/render"
expect label_image 'label: score .* from a symmetric pose' "$examples/label_image"
expect register_clouds 'from the true pose, fitness' "$examples/register_clouds"
expect train_steps '^checkpoint in ' "$examples/train_steps" "$work/cube"
expect evaluate_checkpoint 'images: LLH' "$examples/evaluate_checkpoint" "$work/cube"
expect registration_trials '^success: ' "$examples/registration_trials" --out "$work/trials" \
    --trials 2 --model-points 5000
expect refine_accuracy '\|ΔLLH\|' "$examples/refine_accuracy" "$work/models" 2 5000
expect mug_handle_views 'views$' "$examples/mug_handle_views" "$work/mugs" train
expect label_colours '^margin 0\.1: drops' "$examples/label_colours" "$work/scan" train 1

echo "examples: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
