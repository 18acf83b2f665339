#!/usr/bin/env bash
# The real YCB-Video fixture as a benchmark: for each of its ten objects, the one command a user
# runs for a mesh of their own (`ipdf pipeline --mesh`: randomised renders of the fixture's scan
# with a Kinect's depth, pseudo labels, a rotation and a translation model; nothing real in
# training), scored on the fixture's real frames per instance (rotation error, Acc@15°/30°, LLH,
# translation error, ADD(-S); the translation fitted to the frame's depth, with its ADD(-S); and
# the pose refined with the depth from the rotation model's hypotheses, with its VSD and ADD(-S)).
#
#   scripts/real-frame-benchmark.sh [OUT] [OBJ_ID ...]
#
# OUT (default runs/real-frames) ends with `real_frames.md` (one table, every instance) and
# `real_frames.json`; each object's run stays in OUT/obj_N, and a rerun resumes each where it
# stopped. PRESET (quick) chooses the preset; FRAMES, VAL_FRAMES, EPOCHS and STEPS override its
# training frames, validation frames, epochs (translation: EPOCHS too) and steps per epoch;
# PIPELINE_ARGS are added to each run (e.g. "--randomize none": plain renders); SEED (0) is each
# run's seed (renders, labels and training all draw from it); IPDF names the binary
# (target/release/ipdf).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/real-frames}
shift || true
FIXTURE=examples/pseudo-label/tests/data/ycbv_real
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
    OBJECTS=(1 2 3 5 7 8 9 10 14 21)
fi
mkdir -p "$OUT"
# The frames' camera: YCB-Video's cam_K, 640 × 480, 0.1 mm depth units.
python3 - "$FIXTURE" "$OUT/camera.json" <<'EOF2'
import json, sys
k = json.load(open(f"{sys.argv[1]}/test/000000/scene_camera.json"))["1"]["cam_K"]
json.dump({"fx": k[0], "fy": k[4], "cx": k[2], "cy": k[5], "width": 640, "height": 480,
           "depth_scale": 0.1}, open(sys.argv[2], "w"), indent=2)
EOF2
for id in "${OBJECTS[@]}"; do
    run="$OUT/obj_$id"
    mesh=$(printf "%s/models/obj_%06d.ply" "$FIXTURE" "$id")
    "$IPDF" --seed "${SEED:-0}" pipeline --mesh "$mesh" --camera "$OUT/camera.json" --out "$run" \
        "${OVERRIDES[@]}" --real "$FIXTURE" --obj-id "$id" --json >/dev/null
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
visible = lambda r: "—" if r["visib_fract"] is None else f"{r['visib_fract']:.0%}"
lines = ["| scene | image | obj | visible | rotation error (°) | VSD | LLH | translation error (mm) | ADD(-S) (mm) | under 10% of the diameter | fitted to depth: translation error (mm) | its ADD(-S) (mm) | under 10% | refined with depth: rotation error (°) | its VSD | translation error (mm) | ADD(-S) (mm) | under 10% |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
under = lambda add, r: "—" if add is None else "yes" if add < 0.1 * r["diameter_mm"] else "no"
one = lambda v, digits=1: "—" if v is None else f"{v:.{digits}f}"
for r in rows:
    lines.append(f"| {r['scene_id']} | {r['im_id']} | {r['obj_id']} | {visible(r)} | {r['rotation_error_deg']:.1f} | {r['vsd']:.2f} | {r['llh']:.2f} | {r['translation_error_mm']:.1f} | {r['add_mm']:.1f} ({r['add_metric']}) | {under(r['add_mm'], r)} | "
                 f"{one(r.get('fitted_translation_error_mm'))} | {one(r.get('fitted_add_mm'))} | {under(r.get('fitted_add_mm'), r)} | "
                 f"{one(r.get('refined_rotation_error_deg'))} | {one(r.get('refined_vsd'), 2)} | {one(r.get('refined_translation_error_mm'))} | "
                 f"{one(r.get('refined_add_mm'))} | {under(r.get('refined_add_mm'), r)} |")
n = len(rows)
errors = sorted(r["rotation_error_deg"] for r in rows)
translations = sorted(r["translation_error_mm"] for r in rows)
# An instance without a fitted translation (no depth, or too few readings in its mask) is left
# out of the fitted medians and counts as wrong in their ADD(-S).
fitted = sorted(r["fitted_translation_error_mm"] for r in rows if r.get("fitted_translation_error_mm") is not None)
# An instance without a refined pose (its depth could not be registered) counts as wrong.
refined_true = lambda r: (r.get("refined_rotation_error_deg") is not None and r["refined_rotation_error_deg"] < 15) or (
    r.get("refined_vsd") is not None and r["refined_vsd"] < 0.3)
refined = sorted(r["refined_translation_error_mm"] for r in rows if r.get("refined_translation_error_mm") is not None)
uniform = -math.log(math.pi ** 2)
summary = {
    "instances": n,
    "acc_15": sum(e < 15 for e in errors) / n,
    "acc_30": sum(e < 30 for e in errors) / n,
    # A true pose: within 15° of the truth's symmetries, or under 0.3 in VSD to the truth.
    "acc_15_or_vsd": sum(r["rotation_error_deg"] < 15 or r["vsd"] < 0.3 for r in rows) / n,
    "median_rotation_error_deg": errors[n // 2],
    "above_uniform": sum(r["llh"] > uniform for r in rows) / n,
    "median_translation_error_mm": translations[n // 2],
    "add_accuracy": sum(r["add_mm"] < 0.1 * r["diameter_mm"] for r in rows) / n,
    "translation_over_50mm": sum(t > 50 for t in translations),
    # The most likely pose's translation fitted to the frame's depth in the visible mask.
    "fitted_instances": len(fitted),
    "median_fitted_translation_error_mm": fitted[len(fitted) // 2] if fitted else None,
    "fitted_translation_over_50mm": sum(t > 50 for t in fitted),
    "fitted_add_accuracy": sum(r.get("fitted_add_mm") is not None and r["fitted_add_mm"] < 0.1 * r["diameter_mm"]
                               for r in rows) / n,
    # The pose refined with the depth from the rotation model's hypotheses (`ipdf eval
    # --depth-hypotheses`).
    "refined_acc_15_or_vsd": sum(map(refined_true, rows)) / n,
    "refined_instances": len(refined),
    "median_refined_translation_error_mm": refined[len(refined) // 2] if refined else None,
    "refined_add_accuracy": sum(r.get("refined_add_mm") is not None and r["refined_add_mm"] < 0.1 * r["diameter_mm"]
                                for r in rows) / n,
}
lines.append("")
lines.append(f"{n} instances: Acc@15° {summary['acc_15']:.0%}, Acc@30° {summary['acc_30']:.0%}, a true pose (under 15° or VSD "
             f"under 0.3) {summary['acc_15_or_vsd']:.0%}, median rotation error "
             f"{summary['median_rotation_error_deg']:.1f}°, truth denser than uniform for {summary['above_uniform']:.0%}, "
             f"median translation error {summary['median_translation_error_mm']:.1f} mm, ADD(-S) under 10% of the diameter "
             f"{summary['add_accuracy']:.0%}; fitted to depth: median translation error "
             f"{one(summary['median_fitted_translation_error_mm'])} mm ({summary['fitted_instances']} fitted), {summary['fitted_translation_over_50mm']} over 50 mm "
             f"(the model's: {summary['translation_over_50mm']}), ADD(-S) under 10% of the diameter {summary['fitted_add_accuracy']:.0%}; "
             f"refined with depth from the rotation model's hypotheses: a true pose {summary['refined_acc_15_or_vsd']:.0%}, "
             f"median translation error {one(summary['median_refined_translation_error_mm'])} mm, ADD(-S) under 10% of the diameter "
             f"{summary['refined_add_accuracy']:.0%}.")
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
