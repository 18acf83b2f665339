"""Refit each mesh with its rotation fixed to the identity (YCB-Video's models are the YCB scans
moved, not turned): a translation per object, so that the ground-truth rotations stay the
dataset's own. Compared with the full rigid fit of calibrate_offsets.py."""
import json, os, sys
import numpy as np
from scipy.spatial import cKDTree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ycbv_common import *
rng = np.random.default_rng(0)
obs, held = observations()
offsets = json.load(open(os.path.join(HERE, "rigid_offsets.json")))
for c, o in offsets.items():
    c = int(c)
    v, f, src = source_mesh(c)
    surf = sample_surface(v, f, 200000, rng)
    tree = cKDTree(surf)
    P = np.concatenate(obs[c])
    t = np.array(o["t_ycbv_to_src"])
    for it in range(60):
        d, i = tree.query(P + t, workers=2)
        keep = d < max(0.02 * 0.9 ** it, 0.004)
        t = t + (surf[i[keep]] - (P[keep] + t)).mean(0)
    d, _ = tree.query(P + t, workers=2)
    dh, _ = tree.query(np.concatenate(held[c]) + t, workers=2)
    o["R_ycbv_to_src"] = np.eye(3).tolist()
    o["t_ycbv_to_src"] = t.tolist()
    o["rigid_rot_deg"] = o.pop("rot_deg")
    o.update(tonly_fit_median_mm=1000 * np.median(d), tonly_held_median_mm=1000 * np.median(dh), tonly_held_p90_mm=1000 * np.percentile(dh, 90))
    print(c, o["name"], f"t {np.round(1000*t,1)} fit med {1000*np.median(d):.2f} | held med {1000*np.median(dh):.2f} p90 {1000*np.percentile(dh,90):.2f}  (rigid held med {o['held_median_mm']:.2f})", flush=True)
for c in ("10", "14", "21"):  # IsaacGymEnvs' meshes are already in the dataset's frame
    offsets[c]["t_ycbv_to_src"] = [0.0, 0.0, 0.0]
json.dump(offsets, open(os.path.join(HERE, "offsets.json"), "w"), indent=1)
