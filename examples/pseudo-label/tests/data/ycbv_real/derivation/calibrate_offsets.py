"""Fit each source mesh's rigid transform into the YCB-Video model frame on frames 2-5 of each
sequence (ground-truth poses fixed), holding frame 1 out for the labelling test."""
import json, os, sys
import numpy as np
from scipy.spatial import cKDTree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ycbv_common import *

rng = np.random.default_rng(0)
obs, held = observations()

out = {}
for c in sorted(obs):
    v, f, src = source_mesh(c)
    surf = sample_surface(v, f, 200000, rng)
    tree = cKDTree(surf)
    P = np.concatenate(obs[c])
    # start: align centroids of observed points to the nearest surface after translating by mesh centroid offset
    R = np.eye(3); t = np.zeros(3)
    # coarse: translation search from bbox-centre difference
    sub = P[rng.choice(len(P), min(800, len(P)), replace=False)]
    centre = np.zeros(3)
    for step, half in ((0.02, 6), (0.005, 4), (0.002, 3)):
        g = np.arange(-half, half + 1) * step
        grid = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) + centre
        scores = [np.median(tree.query(sub + tt, workers=2)[0]) for tt in grid]
        best = (min(scores), grid[int(np.argmin(scores))])
        centre = best[1]
    t = best[1]
    print("  grid", np.round(1000 * t), f"{1000*best[0]:.1f} mm", flush=True)
    for it in range(60):
        Q = P @ R.T + t
        d, i = tree.query(Q)
        keep = d < max(0.02 * 0.9 ** it, 0.004)
        dR, dt = kabsch(Q[keep], surf[i[keep]])
        R, t = dR @ R, dR @ t + dt
    Q = P @ R.T + t
    d, _ = tree.query(Q)
    H = np.concatenate(held[c]) @ R.T + t
    dh, _ = tree.query(H)
    ang = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
    # source -> ycbv: x_y = R^T (x_s - t)
    out[int(c)] = dict(name=NAMES[c], source=src, R_ycbv_to_src=R.tolist(), t_ycbv_to_src=t.tolist(),
                       rot_deg=ang, fit_median_mm=1000 * np.median(d), fit_p90_mm=1000 * np.percentile(d, 90),
                       held_median_mm=1000 * np.median(dh), held_p90_mm=1000 * np.percentile(dh, 90), n=len(P))
    print(c, NAMES[c], f"rot {ang:.2f} deg t {np.round(1000*t,1)} mm fit med {1000*np.median(d):.2f} p90 {1000*np.percentile(d,90):.2f} | held med {1000*np.median(dh):.2f} p90 {1000*np.percentile(dh,90):.2f}", flush=True)
json.dump(out, open(os.path.join(HERE, "rigid_offsets.json"), "w"), indent=1)
