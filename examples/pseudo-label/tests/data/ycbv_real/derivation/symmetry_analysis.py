"""Candidate geometric symmetries of the fixture meshes: 90/180 deg turns about the principal
axes through the centroid (and 30-deg steps for a continuous check), each refined by ICP, with
the surface distance statistics of the turned mesh to itself (mm)."""
import json, os, sys
import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ycbv_common import *

offsets = json.load(open(os.path.join(HERE, "offsets.json")))
rng = np.random.default_rng(1)

out = {}
for c, o in offsets.items():
    v, f, _ = source_mesh(int(c))
    R0, t0 = np.array(o["R_ycbv_to_src"]), np.array(o["t_ycbv_to_src"])
    vy = (v - t0) @ R0 * 1000.0
    surf = sample_surface(vy, f, 60000, rng)
    tree = cKDTree(surf)
    q = surf[rng.choice(len(surf), 8000, replace=False)]
    mu = surf.mean(0)
    w, V = np.linalg.eigh(np.cov((surf - mu).T))
    res = []
    for k in range(3):
        for ang in (30, 60, 90, 120, 180):
            Rc = Rotation.from_rotvec(np.radians(ang) * V[:, k]).as_matrix()
            R, t = Rc, mu - Rc @ mu
            for it in range(30):
                Q = q @ R.T + t
                d, i = tree.query(Q, workers=2)
                dR, dt = kabsch(Q, surf[i])
                R, t = dR @ R, dR @ t + dt
            d, _ = tree.query(q @ R.T + t, workers=2)
            moved = np.degrees(np.arccos(np.clip((np.trace(R @ Rc.T) - 1) / 2, -1, 1)))
            total = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
            res.append(dict(axis=k, axis_vec=V[:, k].tolist(), turn=ang, R=R.tolist(), t=t.tolist(),
                            refined_deg=moved, total_deg=total, mean=d.mean(), p95=np.percentile(d, 95),
                            p99=np.percentile(d, 99), max=d.max()))
            print(c, o["name"], f"axis{k} {ang:3d}: total {total:6.1f} (refined {moved:4.1f}) mean {d.mean():.2f} p95 {np.percentile(d,95):.2f} p99 {np.percentile(d,99):.2f} max {d.max():.2f}", flush=True)
    out[c] = dict(name=o["name"], eig=w.tolist(), candidates=res)
json.dump(out, open(os.path.join(HERE, "symmetry_candidates.json"), "w"), indent=1)
