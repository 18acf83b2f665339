#!/usr/bin/env bash
# The real YCB-Video fixture as a benchmark: for each of its ten objects, the models the
# pipeline trains today (quick preset: renders of the fixture's scan with a Kinect's depth,
# pseudo labels, a rotation and a translation model), scored on the fixture's real frames per
# instance (`ipdf eval`: rotation error, Acc@15°/30°, LLH, translation error, ADD(-S)).
#
#   scripts/real-frame-benchmark.sh [OUT] [OBJ_ID ...]
#
# OUT (default runs/real-frames) ends with `real_frames.md` (one table, every instance) and
# `real_frames.json`; each object's run stays in OUT/obj_N, and an object whose `eval.json` is
# there is not run again (a rerun resumes). FRAMES (800 training renders),
# VAL_FRAMES (50), EPOCHS (32; translation EPOCHS/2), STEPS (50 per epoch) and LEVEL (4, the
# scoring grid) scale it; SYNTH_ARGS are added to both `ipdf synth` calls (e.g. "--variant
# texture --randomize": the scans' own textures, randomised looks) and TRAIN_ARGS to both
# `ipdf train` calls; IPDF names the binary (target/release/ipdf).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/real-frames}
shift || true
FIXTURE=examples/pseudo-label/tests/data/ycbv_real
IPDF=${IPDF:-target/release/ipdf}
FRAMES=${FRAMES:-800}
EPOCHS=${EPOCHS:-32}
STEPS=${STEPS:-50}
VAL_FRAMES=${VAL_FRAMES:-50}
LEVEL=${LEVEL:-4}
read -r -a SYNTH_EXTRA <<< "${SYNTH_ARGS:-}"
read -r -a TRAIN_EXTRA <<< "${TRAIN_ARGS:-}"
OBJECTS=("$@")
if [ ${#OBJECTS[@]} -eq 0 ]; then
    OBJECTS=(1 2 3 5 7 8 9 10 14 21)
fi
mkdir -p "$OUT"
# The frames' camera: YCB-Video's cam_K, 640 × 480, 0.1 mm depth units.
python3 - "$FIXTURE" "$OUT/camera.json" <<'EOF'
import json, sys
k = json.load(open(f"{sys.argv[1]}/test/000000/scene_camera.json"))["1"]["cam_K"]
json.dump({"fx": k[0], "fy": k[4], "cx": k[2], "cy": k[5], "width": 640, "height": 480,
           "depth_scale": 0.1}, open(sys.argv[2], "w"), indent=2)
EOF
NETWORK=(--encoder small-cnn --input-size 48 --head 64,64 --steps-per-epoch "$STEPS" --batch-size 16
    "${TRAIN_EXTRA[@]}")
for id in "${OBJECTS[@]}"; do
    run="$OUT/obj_$id"
    if [ -f "$run/eval.json" ]; then
        continue
    fi
    mesh=$(printf "%s/models/obj_%06d.ply" "$FIXTURE" "$id")
    scene=(--mesh "$mesh" --camera "$OUT/camera.json" --distance 0.45 1.2 --off-centre 1
        --roll 30 --occluders 2 --distractors 2 --sensor kinect --json "${SYNTH_EXTRA[@]}")
    "$IPDF" synth --out "$run/data" --frames "$FRAMES" --frames-per-scene "$FRAMES" "${scene[@]}" >/dev/null
    "$IPDF" synth --out "$run/data" --split val --frames "$VAL_FRAMES" --frames-per-scene "$VAL_FRAMES" --seed 1 "${scene[@]}" >/dev/null
    "$IPDF" label --dataset "$run/data" --split train --sensor kinect --json >/dev/null
    "$IPDF" train --dataset "$run/data" --labels pseudo --target rotation --out "$run/model" \
        "${NETWORK[@]}" --epochs "$EPOCHS" --learning-rate 4e-3 --query-level 1 --json >/dev/null
    "$IPDF" train --dataset "$run/data" --labels pseudo --target translation \
        --out "$run/model/translation" "${NETWORK[@]}" --epochs $((EPOCHS / 2)) \
        --learning-rate 2e-3 --translation-queries 512 --json >/dev/null
    "$IPDF" eval --checkpoint "$run/model" --dataset "$FIXTURE" --split test --obj-id "$id" \
        --level "$LEVEL" --out "$run/eval.json" --json >/dev/null
    echo "obj $id: $(python3 -c "import json,sys; a=json.load(open(sys.argv[1]))['accuracy']; print(f\"Acc@15 {a['acc_15']:.2f}, median rotation error {a['median_rotation_error_deg']:.1f}°, median translation error {a['median_translation_error_mm']:.1f} mm\")" "$run/eval.json")"
done
# One table of every instance, the object id beside it.
python3 - "$OUT" "${OBJECTS[@]}" <<'EOF'
import json, math, sys
out, ids = sys.argv[1], sys.argv[2:]
rows = []
for i in ids:
    result = json.load(open(f"{out}/obj_{i}/eval.json"))
    for r in result["instances"]:
        rows.append(dict(r, obj_id=int(i), add_metric=result["accuracy"]["add_metric"],
                         diameter_mm=result["pose"]["diameter_mm"]))
rows.sort(key=lambda r: (r["scene_id"], r["im_id"], r["instance"]))
visible = lambda r: "—" if r["visib_fract"] is None else f"{r['visib_fract']:.0%}"
lines = ["| scene | image | obj | visible | rotation error (°) | LLH | translation error (mm) | ADD(-S) (mm) | under 10% of the diameter |",
         "|---|---|---|---|---|---|---|---|---|"]
for r in rows:
    ok = "yes" if r["add_mm"] < 0.1 * r["diameter_mm"] else "no"
    lines.append(f"| {r['scene_id']} | {r['im_id']} | {r['obj_id']} | {visible(r)} | {r['rotation_error_deg']:.1f} | {r['llh']:.2f} | {r['translation_error_mm']:.1f} | {r['add_mm']:.1f} ({r['add_metric']}) | {ok} |")
n = len(rows)
errors = sorted(r["rotation_error_deg"] for r in rows)
translations = sorted(r["translation_error_mm"] for r in rows)
uniform = -math.log(math.pi ** 2)
summary = {
    "instances": n,
    "acc_15": sum(e < 15 for e in errors) / n,
    "acc_30": sum(e < 30 for e in errors) / n,
    "median_rotation_error_deg": errors[n // 2],
    "above_uniform": sum(r["llh"] > uniform for r in rows) / n,
    "median_translation_error_mm": translations[n // 2],
    "add_accuracy": sum(r["add_mm"] < 0.1 * r["diameter_mm"] for r in rows) / n,
}
lines.append("")
lines.append(f"{n} instances: Acc@15° {summary['acc_15']:.0%}, Acc@30° {summary['acc_30']:.0%}, median rotation error "
             f"{summary['median_rotation_error_deg']:.1f}°, truth denser than uniform for {summary['above_uniform']:.0%}, "
             f"median translation error {summary['median_translation_error_mm']:.1f} mm, ADD(-S) under 10% of the diameter "
             f"{summary['add_accuracy']:.0%}.")
# Per object: the rotation model's LLH on its validation renders (the last epoch of its
# train_log.csv) beside its real instances' scores.
objects = []
for i in ids:
    log = open(f"{out}/obj_{i}/model/train_log.csv").read().split()
    header, last = log[0].split(","), log[-1].split(",")
    accuracy = json.load(open(f"{out}/obj_{i}/eval.json"))["accuracy"]
    objects.append(dict(obj_id=int(i), renders_validation_llh=float(last[header.index("validation_llh")]),
                        **{k: accuracy[k] for k in ("instances", "acc_15", "median_rotation_error_deg",
                                                    "median_translation_error_mm")}))
lines += ["", "| obj | LLH on its validation renders | real instances | Acc@15° | median rotation error (°) | median translation error (mm) |",
          "|---|---|---|---|---|---|"]
for o in objects:
    lines.append(f"| {o['obj_id']} | {o['renders_validation_llh']:.2f} | {o['instances']} | {o['acc_15']:.0%} | "
                 f"{o['median_rotation_error_deg']:.1f} | {o['median_translation_error_mm']:.1f} |")
open(f"{out}/real_frames.md", "w").write("\n".join(lines) + "\n")
json.dump({"instances": rows, "summary": summary, "objects": objects}, open(f"{out}/real_frames.json", "w"), indent=2)
print("\n".join(lines))
EOF
