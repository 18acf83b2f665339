"""Baseline for the `render/*` criterion benches (benches/benches/depth_render.rs): the same
workload ray cast with Embree through Open3D's `o3d.t.geometry.RaycastingScene`.

Workload, identical to the Rust bench:
- mesh: `primitives::sphere(0.1, s)` rebuilt in numpy (icosahedron subdivided `s` times, the
  same triangles in the same order and the same vertex order); s = 5 (20,480 triangles) for the
  renders, s = 6 (81,920) and s = 7 (327,680) for the BVH builds;
- camera: fx 1075.65, fy 1073.90, cx 320, cy 240, 640×480, OpenCV axes, rays through integer
  pixel centres with direction ((u-cx)/fx, (v-cy)/fy, 1), so that t_hit is the z-depth;
- pose: model→camera rotation Rz(0.1)·Ry(0.4)·Rx(0.2) (nalgebra
  `UnitQuaternion::from_euler_angles(0.2, 0.4, 0.1)`), translation (0, 0, 0.7).

As in the Rust renderer, the mesh (and its BVH) stays in the model frame and the camera rays
are taken into it: origin -Rᵀt, direction Rᵀd (an unnormalised direction, so Open3D's t_hit,
in units of the direction's length, is still the z-depth). The ray tensors are precomputed
outside the timed part; their numpy construction is timed separately for reference (the Rust
bench generates its rays inside the timed loop).

Timed cases (time.perf_counter, `--warmup` untimed runs then `--reps` timed ones; median and min):
- bvh_build/{82k,328k}_triangles: `RaycastingScene()` + `add_triangles` + casting one ray.
  Open3D builds the Embree BVH lazily (rtcCommitScene on the first query), so the single-ray
  cast is what builds it; the parts are reported separately too.
- depth/640x480_20k_triangles: `cast_rays` of the 307,200 rays on a built scene.
- depth/roi_100x100: the 10,000 rays of u in [270, 370), v in [190, 290).

Run: `make bench-python` (creates .venv-bench with open3d-cpu), or
`.venv-bench/bin/python benches/python/open3d_raycast.py [--reps 20] [--warmup 3]
[--nthreads 0] [--json runs/bench/open3d_raycast.json]`.
"""
import argparse
import json
import os
import platform
import statistics
import sys
import time

import numpy as np
import open3d as o3d

RADIUS = 0.1
FX, FY, CX, CY, WIDTH, HEIGHT = 1075.65, 1073.90, 320.0, 240.0, 640, 480
ROLL, PITCH, YAW = 0.2, 0.4, 0.1
TRANSLATION = np.array([0.0, 0.0, 0.7])
ROI = (270, 190, 370, 290)  # u0, v0, u1, v1 (half-open), as depth_render.rs's Window


def icosahedron_corners():
    phi = 0.5 * (1.0 + 5.0**0.5)
    corners = []
    for a, b in ((1.0, phi), (1.0, -phi), (-1.0, phi), (-1.0, -phi)):
        corners += [(0.0, a, b), (a, b, 0.0), (b, 0.0, a)]
    return np.array(corners)


def icosahedron_faces(points):
    """Vertex triples (a < b < c) whose pairwise distances equal the shortest edge, outward."""
    edge = np.linalg.norm(points[1:] - points[0], axis=1).min()
    dist = np.linalg.norm(points[:, None] - points[None], axis=2)
    is_edge = np.abs(dist - edge) < 1e-9
    n = len(points)
    faces = []
    for a in range(n):
        for b in range(a + 1, n):
            for c in range(b + 1, n):
                if is_edge[a, b] and is_edge[b, c] and is_edge[a, c]:
                    normal = np.cross(points[b] - points[a], points[c] - points[a])
                    outward = normal @ (points[a] + points[b] + points[c]) > 0.0
                    faces.append((a, b, c) if outward else (a, c, b))
    assert len(faces) == 20
    return np.array(faces, dtype=np.int64)


def sphere(radius, subdivisions):
    """`primitives::sphere`: (vertices N×3 float64, faces M×3 int64), M = 20·4^subdivisions.

    Midpoints are numbered in the order the Rust code creates them (per face: ab, bc, ca), so
    vertex and triangle order match it exactly."""
    vertices = icosahedron_corners()
    vertices /= np.linalg.norm(vertices, axis=1, keepdims=True)
    faces = icosahedron_faces(vertices)
    for _ in range(min(subdivisions, 8)):
        a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
        pairs = np.stack([np.stack([a, b], 1), np.stack([b, c], 1), np.stack([c, a], 1)], 1)
        pairs = np.sort(pairs.reshape(-1, 2), axis=1)  # (3M, 2), rows ab0, bc0, ca0, ab1, ...
        keys = pairs[:, 0] * len(vertices) + pairs[:, 1]
        _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
        rank = np.empty(len(first), dtype=np.int64)
        rank[np.argsort(first, kind="stable")] = np.arange(len(first))  # creation order
        mid_of_key = first[np.argsort(first, kind="stable")]
        new = vertices[pairs[mid_of_key, 0]] + vertices[pairs[mid_of_key, 1]]
        new /= np.linalg.norm(new, axis=1, keepdims=True)
        ids = (len(vertices) + rank[inverse]).reshape(-1, 3)
        ab, bc, ca = ids[:, 0], ids[:, 1], ids[:, 2]
        vertices = np.concatenate([vertices, new])
        faces = np.stack(
            [
                np.stack([a, ab, ca], 1),
                np.stack([ab, b, bc], 1),
                np.stack([ca, bc, c], 1),
                np.stack([ab, bc, ca], 1),
            ],
            1,
        ).reshape(-1, 3)
    return vertices * radius, faces


def euler_rotation(roll, pitch, yaw):
    """nalgebra's `Rotation3::from_euler_angles(roll, pitch, yaw)` = Rz(yaw)·Ry(pitch)·Rx(roll)."""
    cr, sr, cp, sp, cy, sy = (
        np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    )
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def model_frame_rays(rotation, translation, u0, v0, u1, v1):
    """((v1-v0)·(u1-u0), 6) float32 rays [origin, direction] in the model frame, row-major
    over pixels (v, u) with integer pixel centres; t along them is the camera z-depth."""
    v, u = np.meshgrid(np.arange(v0, v1, dtype=np.float64), np.arange(u0, u1, dtype=np.float64),
                       indexing="ij")
    directions = np.stack([(u - CX) / FX, (v - CY) / FY, np.ones_like(u)], -1).reshape(-1, 3)
    rays = np.empty((len(directions), 6), dtype=np.float32)
    rays[:, :3] = -rotation.T @ translation  # camera centre in the model frame
    rays[:, 3:] = directions @ rotation  # Rᵀd for each row d
    return rays


def timed(fn, reps, warmup):
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(reps):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return times


def summary(times, rays=None, triangles=None):
    median, best = statistics.median(times), min(times)
    out = {"median_ms": median * 1e3, "min_ms": best * 1e3, "reps": len(times)}
    if rays is not None:
        out["rays"] = rays
        out["mrays_per_s_median"] = rays / median / 1e6
        out["mrays_per_s_min"] = rays / best / 1e6
    if triangles is not None:
        out["triangles"] = triangles
        out["mtriangles_per_s_median"] = triangles / median / 1e6
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--reps", type=int, default=20, help="timed repetitions per case")
    parser.add_argument("--warmup", type=int, default=3, help="untimed runs before timing")
    parser.add_argument("--nthreads", type=int, default=0,
                        help="RaycastingScene(nthreads=) and cast_rays(nthreads=); 0 = automatic")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args()
    nthreads = args.nthreads
    cpu = o3d.core.Device("CPU:0")

    rotation = euler_rotation(ROLL, PITCH, YAW)
    meshes = {}
    for s in (5, 6, 7):
        vertices, faces = sphere(RADIUS, s)
        assert len(faces) == 20 * 4**s
        meshes[s] = (
            o3d.core.Tensor(vertices.astype(np.float32), device=cpu),
            o3d.core.Tensor(faces.astype(np.uint32), device=cpu),
            len(faces),
        )

    def new_scene(s):
        scene = o3d.t.geometry.RaycastingScene(nthreads=nthreads)
        scene.add_triangles(meshes[s][0], meshes[s][1])
        return scene

    centre_ray = o3d.core.Tensor(
        model_frame_rays(rotation, TRANSLATION, 320, 240, 321, 241), device=cpu
    )
    results = {}

    # (a) BVH builds: scene + add_triangles + one ray (the lazy rtcCommitScene happens there).
    laziness = {}
    for s, name in ((6, "bvh_build/82k_triangles"), (7, "bvh_build/328k_triangles")):
        triangles = meshes[s][2]

        def build(s=s):
            new_scene(s).cast_rays(centre_ray, nthreads=nthreads)

        results[name] = summary(timed(build, args.reps, args.warmup), triangles=triangles)

        # The same build taken apart, to show where the time goes (the commit is lazy).
        parts = {"new_scene_ms": [], "add_triangles_ms": [], "first_cast_ms": [],
                 "second_cast_ms": []}
        for _ in range(max(3, args.reps // 4)):
            t0 = time.perf_counter()
            scene = o3d.t.geometry.RaycastingScene(nthreads=nthreads)
            t1 = time.perf_counter()
            scene.add_triangles(meshes[s][0], meshes[s][1])
            t2 = time.perf_counter()
            scene.cast_rays(centre_ray, nthreads=nthreads)
            t3 = time.perf_counter()
            scene.cast_rays(centre_ray, nthreads=nthreads)
            t4 = time.perf_counter()
            for key, dt in zip(parts, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
                parts[key].append(dt * 1e3)
        laziness[name] = {key: statistics.median(v) for key, v in parts.items()}

    # (b), (c) renders of the 20,480-triangle sphere on a scene built beforehand.
    scene = new_scene(5)
    scene.cast_rays(centre_ray, nthreads=nthreads)  # commit (build) the BVH now
    ray_setup = {}
    for name, (u0, v0, u1, v1) in (
        ("depth/640x480_20k_triangles", (0, 0, WIDTH, HEIGHT)),
        ("depth/roi_100x100", ROI),
    ):
        count = (u1 - u0) * (v1 - v0)
        setup_times = timed(lambda: model_frame_rays(rotation, TRANSLATION, u0, v0, u1, v1),
                            max(3, args.reps // 4), 1)
        ray_setup[name] = statistics.median(setup_times) * 1e3
        rays = o3d.core.Tensor(model_frame_rays(rotation, TRANSLATION, u0, v0, u1, v1),
                               device=cpu)
        results[name] = summary(
            timed(lambda: scene.cast_rays(rays, nthreads=nthreads), args.reps, args.warmup),
            rays=count,
        )

    # Sanity: z-depth at the principal pixel and the hit counts.
    full = o3d.core.Tensor(model_frame_rays(rotation, TRANSLATION, 0, 0, WIDTH, HEIGHT),
                           device=cpu)
    depth = scene.cast_rays(full, nthreads=nthreads)["t_hit"].numpy().reshape(HEIGHT, WIDTH)
    hit = np.isfinite(depth)
    centre_depth = float(depth[int(CY), int(CX)])
    u0, v0, u1, v1 = ROI
    roi_hits = int(hit[v0:v1, u0:u1].sum())
    # An exact sphere of radius r at distance D, centred on the optical axis, images to an
    # ellipse of semi-axes f·tan(asin(r/D)): about pi·fx·fy·r²/(D²-r²) pixels.
    D = TRANSLATION[2]
    expected_hits = np.pi * FX * FY * RADIUS**2 / (D**2 - RADIUS**2)
    print(f"sanity: depth at (u=320, v=240) = {centre_depth:.6f} m (expect 0.6, within 1e-3); "
          f"hit pixels: {int(hit.sum())} of {WIDTH * HEIGHT} (exact sphere: "
          f"~{expected_hits:.0f}; ROI: {roi_hits} of 10000); "
          f"depth range {depth[hit].min():.4f}..{depth[hit].max():.4f} m")
    if not abs(centre_depth - 0.6) < 1e-3:
        sys.exit(f"sanity check failed: centre depth {centre_depth} is not 0.6 ± 1e-3")
    if roi_hits != 10000:
        sys.exit(f"sanity check failed: {roi_hits} of the ROI's 10000 rays hit the sphere")

    threads = "automatic (0)" if nthreads == 0 else str(nthreads)
    print(f"\nOpen3D {o3d.__version__} RaycastingScene (Embree), numpy {np.__version__}, "
          f"{os.cpu_count()} CPUs, nthreads {threads}, {args.reps} reps after {args.warmup} "
          "warm-ups")
    print(f"{'case':<30} {'median ms':>10} {'min ms':>10} {'Mrays/s (med)':>14}")
    for name, r in results.items():
        rate = f"{r['mrays_per_s_median']:.2f}" if "rays" in r else ""
        print(f"{name:<30} {r['median_ms']:>10.3f} {r['min_ms']:>10.3f} {rate:>14}")
    print("\nBVH build taken apart (medians, ms): the Embree build is lazy, done by the first "
          "cast")
    for name, parts in laziness.items():
        print(f"  {name:<28} " + ", ".join(f"{k[:-3]} {v:.3f}" for k, v in parts.items()))
    print("ray tensors built in numpy (not in the timed casts, medians, ms): "
          + ", ".join(f"{k} {v:.3f}" for k, v in ray_setup.items()))

    if args.json:
        report = {
            "open3d": o3d.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
            "machine": platform.machine(),
            "cpus": os.cpu_count(),
            "nthreads": nthreads,
            "reps": args.reps,
            "warmup": args.warmup,
            "rays_frame": "model (mesh and BVH in the model frame, rays transformed into it)",
            "bvh_build_is_lazy": True,
            "results": results,
            "bvh_build_parts_ms": laziness,
            "ray_setup_numpy_ms": ray_setup,
            "sanity": {
                "centre_depth_m": centre_depth,
                "hit_pixels": int(hit.sum()),
                "hit_pixels_exact_sphere": expected_hits,
                "roi_hit_pixels": roi_hits,
            },
        }
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as f:
            json.dump(report, f, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
