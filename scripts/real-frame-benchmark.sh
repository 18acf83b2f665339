#!/usr/bin/env bash
# A real BOP dataset as a benchmark (by default the real YCB-Video fixture): for each object, the
# one command a user runs for a mesh of their own (`ipdf pipeline --mesh`: randomised renders of
# the dataset's mesh with a Kinect's depth, pseudo labels, a rotation and a translation model;
# nothing real in training), scored on the dataset's real frames per instance (rotation error,
# Acc@15°/30°, LLH, translation error, ADD(-S); where the frames have depth and visible masks,
# the VSD, the translation fitted to the frame's depth, with its ADD(-S), and the pose refined
# with the depth from the rotation model's hypotheses, with its VSD and ADD(-S)).
#
#   scripts/real-frame-benchmark.sh [OUT] [OBJ_ID ...]
#
# OUT (default runs/real-frames) ends with `real_frames.md` (one table, every instance) and
# `real_frames.json`; each object's run stays in OUT/obj_N, and a rerun resumes each where it
# stopped. DATASET names the real BOP dataset (examples/pseudo-label/tests/data/ycbv_real), SPLIT
# its split scored (test); the meshes are its `models/obj_NNNNNN.ply` (millimetres), every one of
# them unless OBJ_IDs are given; the renders' camera is the dataset's `camera.json` where it has
# one, else its first frame's `cam_K` and `depth_scale` and its colour image's size. PRESET
# (quick) chooses the preset; FRAMES, VAL_FRAMES, EPOCHS and STEPS override its training frames,
# validation frames, epochs (translation: EPOCHS too) and steps per epoch; PIPELINE_ARGS are
# added to each run (e.g. "--randomize none": plain renders, "--sensor realsense": another depth
# camera); SEED (0) is each run's seed (renders, labels and training all draw from it); IPDF
# names the binary (target/release/ipdf).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/real-frames}
shift || true
DATASET=${DATASET:-examples/pseudo-label/tests/data/ycbv_real}
SPLIT=${SPLIT:-test}
IPDF=${IPDF:-target/release/ipdf}
OVERRIDES=(--preset "${PRESET:-quick}")
[ -n "${FRAMES:-}" ] && OVERRIDES+=(--frames "$FRAMES")
[ -n "${VAL_FRAMES:-}" ] && OVERRIDES+=(--val-frames "$VAL_FRAMES")
[ -n "${EPOCHS:-}" ] && OVERRIDES+=(--epochs "$EPOCHS")
[ -n "${STEPS:-}" ] && OVERRIDES+=(--steps-per-epoch "$STEPS")
read -r -a EXTRA <<< "${PIPELINE_ARGS:-}"
OVERRIDES+=("${EXTRA[@]}")
OBJECTS=("$@")
if [ ${#OBJECTS[@]} -eq 0 ]; then
    shopt -s nullglob
    for mesh in "$DATASET"/models/obj_[0-9][0-9][0-9][0-9][0-9][0-9].ply; do
        id=${mesh##*/obj_}
        OBJECTS+=($((10#${id%.ply})))
    done
    shopt -u nullglob
    if [ ${#OBJECTS[@]} -eq 0 ]; then
        echo "real-frame-benchmark: $DATASET/models holds no obj_NNNNNN.ply mesh; set DATASET to a BOP dataset" >&2
        exit 1
    fi
fi
mkdir -p "$OUT"
# The frames' camera: the dataset's camera.json, else its first frame's.
python3 - "$DATASET" "$SPLIT" "$OUT/camera.json" <<'EOF2'
import glob, json, os, struct, sys
root, split, out = sys.argv[1:4]
if os.path.exists(f"{root}/camera.json"):
    json.dump(json.load(open(f"{root}/camera.json")), open(out, "w"), indent=2)
    sys.exit()
scenes = sorted(glob.glob(f"{root}/{split}/*/scene_camera.json"))
if not scenes:
    sys.exit(f"real-frame-benchmark: no camera.json in {root} and no {split}/*/scene_camera.json: "
             "set DATASET to a BOP dataset and SPLIT to its split")
im_id, first = min(json.load(open(scenes[0])).items(), key=lambda kv: int(kv[0]))
k = first["cam_K"]
frame = f"{os.path.dirname(scenes[0])}/{{rgb,gray}}/{int(im_id):06d}.*"
images = [p for folder in ("rgb", "gray") for p in glob.glob(frame.replace("{rgb,gray}", folder))]
if not images:
    sys.exit(f"real-frame-benchmark: no image {frame} for the camera's size")
data = open(images[0], "rb").read()
try:
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        width, height = struct.unpack(">II", data[16:24])
    else:  # JPEG: the first start-of-frame marker holds the size
        at = 2
        while data[at + 1] not in (0xC0, 0xC1, 0xC2, 0xC3):
            at += 2 + struct.unpack(">H", data[at + 2:at + 4])[0]
        height, width = struct.unpack(">HH", data[at + 5:at + 9])
except (IndexError, struct.error):
    sys.exit(f"real-frame-benchmark: {images[0]}: neither a PNG nor a JPEG whose size can be read")
json.dump({"fx": k[0], "fy": k[4], "cx": k[2], "cy": k[5], "width": width, "height": height,
           "depth_scale": first.get("depth_scale", 1.0)}, open(out, "w"), indent=2)
EOF2
for id in "${OBJECTS[@]}"; do
    run="$OUT/obj_$id"
    mesh=$(printf "%s/models/obj_%06d.ply" "$DATASET" "$id")
    "$IPDF" --seed "${SEED:-0}" pipeline --mesh "$mesh" --camera "$OUT/camera.json" --out "$run" \
        "${OVERRIDES[@]}" --real "$DATASET" --real-split "$SPLIT" --obj-id "$id" --json >/dev/null
    echo "obj $id: $(python3 -c "import json,sys; r=json.load(open(sys.argv[1])); a=r['real']['accuracy']; print(f\"Acc@15 {a['acc_15']:.2f}, median rotation error {a['median_rotation_error_deg']:.1f}°, median translation error {a['median_translation_error_mm']:.1f} mm, {sum(r['timing_s'].values()) / 60:.1f} min\")" "$run/report.json")"
done
# One table of every instance, the object id beside it.
python3 - "$OUT" "${OBJECTS[@]}" <<'EOF'
import json, math, sys
out, ids = sys.argv[1], sys.argv[2:]
rows = []
for i in ids:
    result = json.load(open(f"{out}/obj_{i}/report.json"))["real"]
    for r in result["instances"]:
        rows.append(dict(r, obj_id=int(i), add_metric=result["accuracy"]["add_metric"],
                         diameter_mm=result["pose"]["diameter_mm"]))
rows.sort(key=lambda r: (r["scene_id"], r["im_id"], r["instance"]))
visible = lambda r: "—" if r.get("visib_fract") is None else f"{r['visib_fract']:.0%}"
lines = ["| scene | image | obj | visible | rotation error (°) | VSD | LLH | translation error (mm) | ADD(-S) (mm) | under 10% of the diameter | fitted to depth: translation error (mm) | its ADD(-S) (mm) | under 10% | refined with depth: rotation error (°) | its VSD | translation error (mm) | ADD(-S) (mm) | under 10% |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
# ADD(-S) under 10% of the object's diameter: a correct pose.
within = lambda add, r: add is not None and add < 0.1 * r["diameter_mm"]
under = lambda add, r: "—" if add is None else "yes" if within(add, r) else "no"
one = lambda v, digits=1: "—" if v is None else f"{v:.{digits}f}"
for r in rows:
    lines.append(f"| {r['scene_id']} | {r['im_id']} | {r['obj_id']} | {visible(r)} | {r['rotation_error_deg']:.1f} | {one(r.get('vsd'), 2)} | {r['llh']:.2f} | {r['translation_error_mm']:.1f} | {r['add_mm']:.1f} ({r['add_metric']}) | {under(r['add_mm'], r)} | "
                 f"{one(r.get('fitted_translation_error_mm'))} | {one(r.get('fitted_add_mm'))} | {under(r.get('fitted_add_mm'), r)} | "
                 f"{one(r.get('refined_rotation_error_deg'))} | {one(r.get('refined_vsd'), 2)} | {one(r.get('refined_translation_error_mm'))} | "
                 f"{one(r.get('refined_add_mm'))} | {under(r.get('refined_add_mm'), r)} |")
n = len(rows)
errors = sorted(r["rotation_error_deg"] for r in rows)
translations = sorted(r["translation_error_mm"] for r in rows)
# Frames with depth and visible masks give a VSD to every instance; RGB-only frames (or boxes
# without masks) give none, and neither a translation fitted to depth nor a pose refined with it.
depth = any(r.get("vsd") is not None for r in rows)
# An instance without a fitted translation (no depth, or too few readings in its mask) is left
# out of the fitted medians and counts as wrong in their ADD(-S).
fitted = sorted(r["fitted_translation_error_mm"] for r in rows if r.get("fitted_translation_error_mm") is not None)
# An instance without a refined pose (its depth could not be registered) counts as wrong.
refined_true = lambda r: (r.get("refined_rotation_error_deg") is not None and r["refined_rotation_error_deg"] < 15) or (
    r.get("refined_vsd") is not None and r["refined_vsd"] < 0.3)
refined = sorted(r["refined_translation_error_mm"] for r in rows if r.get("refined_translation_error_mm") is not None)
under_tenth = lambda key: sum(within(r.get(key), r) for r in rows) / n
uniform = -math.log(math.pi ** 2)
summary = {
    "instances": n,
    "acc_15": sum(e < 15 for e in errors) / n,
    "acc_30": sum(e < 30 for e in errors) / n,
    # A true pose: within 15° of the truth's symmetries, or under 0.3 in VSD to the truth.
    "acc_15_or_vsd": sum(r["rotation_error_deg"] < 15 or r["vsd"] < 0.3 for r in rows) / n if depth else None,
    "median_rotation_error_deg": errors[n // 2],
    "above_uniform": sum(r["llh"] > uniform for r in rows) / n,
    "median_translation_error_mm": translations[n // 2],
    "add_accuracy": under_tenth("add_mm"),
    "translation_over_50mm": sum(t > 50 for t in translations),
    # The most likely pose's translation fitted to the frame's depth in the visible mask.
    "fitted_instances": len(fitted),
    "median_fitted_translation_error_mm": fitted[len(fitted) // 2] if fitted else None,
    "fitted_translation_over_50mm": sum(t > 50 for t in fitted),
    "fitted_add_accuracy": under_tenth("fitted_add_mm") if depth else None,
    # The pose refined with the depth from the rotation model's hypotheses (`ipdf eval
    # --depth-hypotheses`).
    "refined_acc_15_or_vsd": sum(map(refined_true, rows)) / n if depth else None,
    "refined_instances": len(refined),
    "median_refined_translation_error_mm": refined[len(refined) // 2] if refined else None,
    "refined_add_accuracy": under_tenth("refined_add_mm") if depth else None,
}
alone = [f"Acc@15° {summary['acc_15']:.0%}", f"Acc@30° {summary['acc_30']:.0%}"]
if depth:
    alone.append(f"a true pose (under 15° or VSD under 0.3) {summary['acc_15_or_vsd']:.0%}")
alone += [f"median rotation error {summary['median_rotation_error_deg']:.1f}°",
          f"truth denser than uniform for {summary['above_uniform']:.0%}",
          f"median translation error {summary['median_translation_error_mm']:.1f} mm",
          f"ADD(-S) under 10% of the diameter {summary['add_accuracy']:.0%}"]
if depth:
    with_depth = [f"fitted to depth: median translation error {one(summary['median_fitted_translation_error_mm'])} mm "
                  f"({summary['fitted_instances']} fitted), {summary['fitted_translation_over_50mm']} over 50 mm (the model's: "
                  f"{summary['translation_over_50mm']}), ADD(-S) under 10% of the diameter {summary['fitted_add_accuracy']:.0%}",
                  f"refined with depth from the rotation model's hypotheses: a true pose {summary['refined_acc_15_or_vsd']:.0%}, "
                  f"median translation error {one(summary['median_refined_translation_error_mm'])} mm, ADD(-S) under 10% of the "
                  f"diameter {summary['refined_add_accuracy']:.0%}"]
else:
    with_depth = ["no depth under the visible masks: no VSD, no translation fitted to depth, no pose refined with it"]
lines.append("")
lines.append(f"{n} instances: " + "; ".join([", ".join(alone)] + with_depth) + ".")
# Per object: the models' scores on their validation renders beside their real instances'
# scores, and the run's minutes (of the invocation that finished it).
objects = []
for i in ids:
    report = json.load(open(f"{out}/obj_{i}/report.json"))
    accuracy = report["real"]["accuracy"]
    objects.append(dict(obj_id=int(i), renders_validation_llh=report["renders"]["llh"],
                        renders_maad_deg=report["renders"]["maad_deg"],
                        renders_acc_15=report["renders"]["accuracy"]["acc_15"],
                        minutes=sum(report["timing_s"].values()) / 60,
                        **{k: accuracy.get(k) for k in ("instances", "acc_15", "median_rotation_error_deg",
                                                        "median_translation_error_mm",
                                                        "median_fitted_translation_error_mm")}))
lines += ["", "| obj | validation renders: LLH | MAAD (°) | Acc@15° | real instances | Acc@15° | median rotation error (°) | median translation error (mm) | fitted to depth (mm) | minutes |",
          "|---|---|---|---|---|---|---|---|---|---|"]
for o in objects:
    lines.append(f"| {o['obj_id']} | {o['renders_validation_llh']:.2f} | {o['renders_maad_deg']:.1f} | {o['renders_acc_15']:.0%} | {o['instances']} | {o['acc_15']:.0%} | "
                 f"{o['median_rotation_error_deg']:.1f} | {o['median_translation_error_mm']:.1f} | {one(o['median_fitted_translation_error_mm'])} | {o['minutes']:.1f} |")
open(f"{out}/real_frames.md", "w").write("\n".join(lines) + "\n")
json.dump({"instances": rows, "summary": summary, "objects": objects}, open(f"{out}/real_frames.json", "w"), indent=2)
print("\n".join(lines))
EOF
