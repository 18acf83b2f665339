"""Open3D baseline for the registration crate: FPFH + Fast Global Registration + point-to-plane
ICP (the pipeline of Open3D's "global registration" tutorial) on a folder of trials written by
our Rust program, timed per stage, with the success rate against the known ground truth.

Input folder (`trials_dir`):
- `model.ply`: the source cloud, model frame, meters (PLY ascii or binary_little_endian,
  `x y z` and maybe `nx ny nz`; the normals are dropped on loading, see below);
- `trials.json`: `{"voxel_size": v, "success": {"rotation_deg", "translation_m"},
  "trials": [{"target": "view_000.ply", "target_from_source": [16 floats, row-major 4x4]}]}`;
  each target is a noisy partial view of the model in the camera frame (meters).

Pipeline, v = voxel_size, for source (model) and target alike:
1. `voxel_down_sample(v)`;
2. `estimate_normals(KDTreeSearchParamHybrid(radius=2v, max_nn=30))`; the target's normals are
   then oriented towards the camera origin (`orient_normals_towards_camera_location([0,0,0])`);
   the model's are propagated with `orient_normals_consistent_tangent_plane(10)` and turned
   outward, as ipdf-rs orients them (`--model-normals arbitrary` leaves Open3D's per-point
   arbitrary signs, as the tutorial does). Any normals in model.ply are dropped before this
   step, because `estimate_normals` would otherwise flip the new normals to agree with them;
3. `compute_fpfh_feature(KDTreeSearchParamHybrid(radius=5v, max_nn=100))`;
then per trial:
4. `registration_fgr_based_on_feature_matching(model_down, target_down, model_fpfh,
   target_fpfh, FastGlobalRegistrationOption(maximum_correspondence_distance=0.5v))`;
   with `--global ransac` instead `registration_ransac_based_on_feature_matching(model_down,
   target_down, model_fpfh, target_fpfh, mutual_filter, 1.5v,
   TransformationEstimationPointToPoint(False), 3, [CorrespondenceCheckerBasedOnEdgeLength(0.9),
   CorrespondenceCheckerBasedOnDistance(1.5v)], RANSACConvergenceCriteria(100000, 0.999))`,
   the settings of Open3D's tutorial, `mutual_filter` False unless `--mutual` (the tutorial's);
5. `registration_icp(model_down, target_down, 1.5v, init=<step 4's>.transformation,
   TransformationEstimationPointToPlane(), ICPConvergenceCriteria(max_iteration=30))`.

Open3D 0.20 notes:
- `FastGlobalRegistrationOption` has no `seed` argument. FGR's only randomness (the tuple
  test's sampling), like RANSAC's, draws from Open3D's global generator, so
  `o3d.utility.random.seed(S + i)` is called right before trial i's step 4 (S = `--seed`,
  default 0): runs and repeats are repeatable.
- With the option's default `use_absolute_scale=False` (kept, as in the tutorial), FGR works on
  clouds centred and scaled to unit radius, and `maximum_correspondence_distance` is only the
  floor of its graduated non-convexity parameter in those normalised units; it is used in
  meters only for the fitness/RMSE that FGR's own result reports.

Timing (`time.perf_counter`, ms): `model_features` = steps 1-3 on the model, done once and
reused by all trials; per trial `target_features` = steps 1-3 on the target, `fgr` = step 4
(RANSAC's with `--global ransac`), `icp` = step 5, and `per_trial` = their sum. Loading the PLY
files is not timed. With `--repeat K` the whole trial loop (model preprocessing included) runs
K times and each trial keeps its per-stage minimum over the K runs; accuracy is taken from the
first run. Medians and means are over trials (`model_features`: the minimum over the K runs, so
median = mean).

Success of a trial: rotation error of the ICP result against the truth (angle of
R_est^T R_true, arccos((trace - 1) / 2), clipped) <= success.rotation_deg and translation error
|t_est - t_true| <= success.translation_m.

Run: `.venv-bench/bin/python benches/python/open3d_registration.py TRIALS_DIR [--threads N]
[--repeat K] [--limit N] [--seed S] [--global fgr|ransac [--mutual]]
[--json runs/bench/open3d_registration.json]`.
`--threads` (default: os.cpu_count()) sets OMP_NUM_THREADS before open3d is imported.
"""
import argparse
import json
import math
import os
import platform
import statistics
import sys
import tempfile
import time

STAGES = ("target_features", "fgr", "icp")


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("trials_dir", help="folder with model.ply, trials.json and the targets")
    parser.add_argument("--threads", type=int, default=os.cpu_count(),
                        help="OMP_NUM_THREADS for Open3D (default: os.cpu_count())")
    parser.add_argument("--repeat", type=int, default=1,
                        help="run the trial loop K times, keep each stage's minimum per trial")
    parser.add_argument("--limit", type=int, default=None, help="use only the first N trials")
    parser.add_argument("--seed", type=int, default=0,
                        help="Open3D global seed for trial i's FGR is SEED + i")
    parser.add_argument("--model-normals", choices=["consistent", "arbitrary"], default="consistent",
                        help="orient the model's normals consistently and outward (as ipdf-rs "
                             "does), or leave Open3D's arbitrary signs (as the tutorial does)")
    parser.add_argument("--global", dest="global_stage", choices=["fgr", "ransac"],
                        default="fgr",
                        help="step 4's global registration: Fast Global Registration, or RANSAC "
                             "on feature matches (Open3D's tutorial settings)")
    parser.add_argument("--mutual", action="store_true",
                        help="with --global ransac: keep mutual nearest feature matches only "
                             "(the tutorial's mutual_filter=True)")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args()
    if args.threads < 1 or args.repeat < 1 or (args.limit is not None and args.limit < 0):
        parser.error("--threads and --repeat must be >= 1, --limit >= 0")
    if args.mutual and args.global_stage != "ransac":
        parser.error("--mutual applies to --global ransac only")
    return args


def rotation_error_deg(r_est, r_true):
    """Angle of R_est^T R_true in degrees, arccos((trace - 1) / 2) with the cosine clipped."""
    cos = (float((r_est.T @ r_true).trace()) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def main():
    args = parse_args()
    os.environ["OMP_NUM_THREADS"] = str(args.threads)
    import numpy as np
    import open3d as o3d

    reg = o3d.pipelines.registration
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)

    with open(os.path.join(args.trials_dir, "trials.json")) as f:
        spec = json.load(f)
    v = float(spec["voxel_size"])
    max_rot_deg = float(spec["success"]["rotation_deg"])
    max_trans_m = float(spec["success"]["translation_m"])
    trials = spec["trials"][: args.limit] if args.limit is not None else spec["trials"]
    if not trials:
        sys.exit("no trials")

    def load_points(name):
        path = os.path.join(args.trials_dir, name)
        cloud = o3d.io.read_point_cloud(path)
        if not cloud.has_points():
            sys.exit(f"{path}: no points read")
        # Points only: normals in the file must not steer estimate_normals' orientation.
        return o3d.geometry.PointCloud(cloud.points)

    model = load_points("model.ply")
    targets = [load_points(t["target"]) for t in trials]
    truths = [np.asarray(t["target_from_source"], dtype=np.float64).reshape(4, 4) for t in trials]

    normal_param = o3d.geometry.KDTreeSearchParamHybrid(radius=2.0 * v, max_nn=30)
    fpfh_param = o3d.geometry.KDTreeSearchParamHybrid(radius=5.0 * v, max_nn=100)
    fgr_option = reg.FastGlobalRegistrationOption(maximum_correspondence_distance=0.5 * v)
    ransac_checkers = [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
                       reg.CorrespondenceCheckerBasedOnDistance(1.5 * v)]
    ransac_criteria = reg.RANSACConvergenceCriteria(100000, 0.999)

    def global_alignment(model_down, target_down, model_fpfh, target_fpfh):
        if args.global_stage == "fgr":
            return reg.registration_fgr_based_on_feature_matching(
                model_down, target_down, model_fpfh, target_fpfh, fgr_option)
        return reg.registration_ransac_based_on_feature_matching(
            model_down, target_down, model_fpfh, target_fpfh, args.mutual, 1.5 * v,
            reg.TransformationEstimationPointToPoint(False), 3, ransac_checkers, ransac_criteria)
    icp_criteria = reg.ICPConvergenceCriteria(max_iteration=30)
    point_to_plane = reg.TransformationEstimationPointToPlane()

    def features(cloud, orientation):
        down = cloud.voxel_down_sample(v)
        down.estimate_normals(normal_param)
        if orientation == "camera":
            down.orient_normals_towards_camera_location(np.zeros(3))
        elif orientation == "consistent":
            # Propagated over the surface like ipdf-rs' model normals, then turned outward
            # (Open3D leaves the global sign open).
            down.orient_normals_consistent_tangent_plane(10)
            points, normals = np.asarray(down.points), np.asarray(down.normals)
            if np.mean(np.sum((points - points.mean(axis=0)) * normals, axis=1)) < 0:
                down.normals = o3d.utility.Vector3dVector(-normals)
        return down, reg.compute_fpfh_feature(down, fpfh_param)

    model_ms = float("inf")
    best = [{stage: float("inf") for stage in STAGES} for _ in trials]
    accuracy = [None] * len(trials)
    model_points_down = 0
    for rep in range(args.repeat):
        t0 = time.perf_counter()
        model_down, model_fpfh = features(model, args.model_normals)
        model_ms = min(model_ms, (time.perf_counter() - t0) * 1e3)
        model_points_down = len(model_down.points)
        for i, (target, truth) in enumerate(zip(targets, truths)):
            t0 = time.perf_counter()
            target_down, target_fpfh = features(target, "camera")
            t1 = time.perf_counter()
            o3d.utility.random.seed(args.seed + i)
            t2 = time.perf_counter()
            coarse = global_alignment(model_down, target_down, model_fpfh, target_fpfh)
            t3 = time.perf_counter()
            icp = reg.registration_icp(model_down, target_down, 1.5 * v, coarse.transformation,
                                       point_to_plane, icp_criteria)
            t4 = time.perf_counter()
            for stage, dt in zip(STAGES, (t1 - t0, t3 - t2, t4 - t3)):
                best[i][stage] = min(best[i][stage], dt * 1e3)
            if rep == 0:
                est = np.asarray(icp.transformation)
                rot_err = rotation_error_deg(est[:3, :3], truth[:3, :3])
                trans_err = float(np.linalg.norm(est[:3, 3] - truth[:3, 3]))
                accuracy[i] = {
                    "target": trials[i]["target"],
                    "target_points_down": len(target_down.points),
                    "rotation_error_deg": rot_err,
                    "translation_error_m": trans_err,
                    "fitness": float(icp.fitness),
                    "inlier_rmse": float(icp.inlier_rmse),
                    "success": bool(rot_err <= max_rot_deg and trans_err <= max_trans_m),
                }

    per_trial = []
    for acc, times in zip(accuracy, best):
        row = dict(acc)
        for stage in STAGES:
            row[f"{stage}_ms"] = times[stage]
        per_trial.append(row)
    series = {stage: [row[f"{stage}_ms"] for row in per_trial] for stage in STAGES}
    series["per_trial"] = [sum(row[f"{s}_ms"] for s in STAGES) for row in per_trial]
    median_ms = {"model_features": model_ms}
    mean_ms = {"model_features": model_ms}
    for key, values in series.items():
        median_ms[key] = statistics.median(values)
        mean_ms[key] = statistics.fmean(values)
    successes = sum(row["success"] for row in per_trial)
    success_rate = successes / len(per_trial)

    stage4 = "FGR" if args.global_stage == "fgr" else (
        "RANSAC (mutual matches)" if args.mutual else "RANSAC")
    print(f"Open3D {o3d.__version__} FPFH + {stage4} + point-to-plane ICP, threads {args.threads}, "
          f"voxel {v} m, {len(per_trial)} trials, repeat {args.repeat}, "
          f"model {len(model.points)} -> {model_points_down} points")
    print(f"{'stage':<18} {'median ms':>10} {'mean ms':>10}")
    for key in ("model_features", *STAGES, "per_trial"):
        print(f"{key:<18} {median_ms[key]:>10.3f} {mean_ms[key]:>10.3f}")
    rot = [row["rotation_error_deg"] for row in per_trial]
    trans = [row["translation_error_m"] for row in per_trial]
    print(f"success: {successes}/{len(per_trial)} = {success_rate:.3f} "
          f"(rotation <= {max_rot_deg} deg, translation <= {max_trans_m} m); median errors "
          f"{statistics.median(rot):.3f} deg, {statistics.median(trans) * 1e3:.3f} mm")
    failed = [row for row in per_trial if not row["success"]]
    for row in failed[:10]:
        print(f"  failed {row['target']}: {row['rotation_error_deg']:.2f} deg, "
              f"{row['translation_error_m'] * 1e3:.2f} mm, fitness {row['fitness']:.3f}")
    if len(failed) > 10:
        print(f"  ... and {len(failed) - 10} more")

    if args.json:
        report = {
            "open3d_version": o3d.__version__,
            "threads": args.threads,
            "model_normals": args.model_normals,
            "global": args.global_stage,
            "mutual": args.mutual,
            "voxel_size": v,
            "trials": len(per_trial),
            "success_rate": success_rate,
            "median_ms": median_ms,
            "mean_ms": mean_ms,
            "per_trial": per_trial,
            "repeat": args.repeat,
            "seed": args.seed,
            "model_points_down": model_points_down,
            "numpy": np.__version__,
            "python": platform.python_version(),
            "machine": platform.machine(),
            "cpus": os.cpu_count(),
        }
        path = os.path.abspath(args.json)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=".open3d_registration.",
                                   suffix=".json.tmp")
        try:
            with os.fdopen(fd, "w") as f:
                json.dump(report, f, indent=2)
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 -> an ordinary file's mode
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
