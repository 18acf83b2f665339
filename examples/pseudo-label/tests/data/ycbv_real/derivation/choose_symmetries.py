"""Geometric symmetries of the fixture meshes: a turn is a symmetry when the turned mesh lies
within 2 mm of itself at the 99th percentile of its surface (ICP-refined, symmetry_analysis.py).
Discrete: 180-degree turns about the refined axis; continuous: an axis whose turns by 30-180
degrees all pass (then one 180-degree flip about another axis, if it passes, completes it)."""
import json, os
import numpy as np
from scipy.spatial.transform import Rotation
TOL = 2.0
HERE = os.path.dirname(os.path.abspath(__file__))
sym = json.load(open(os.path.join(HERE, "symmetry_candidates.json")))
chosen = {}
for c, entry in sym.items():
    cands = entry["candidates"]
    cont = []
    for k in range(3):
        turns = [x for x in cands if x["axis"] == k]
        if all(x["p99"] <= TOL and abs(x["total_deg"] - x["turn"]) < 5 for x in turns):
            cont.append(k)
    disc = []
    for x in cands:
        if x["turn"] == 180 and x["p99"] <= TOL and x["total_deg"] > 170 and x["axis"] not in cont:
            rv = Rotation.from_matrix(np.array(x["R"])).as_rotvec()
            a = rv / np.linalg.norm(rv)
            R = Rotation.from_rotvec(np.pi * a).as_matrix()
            t = np.array(x["t"]); t = t - (t @ a) * a
            disc.append((x["axis"], x["p99"], R, t))
    out = {}
    if cont:
        k = cont[0]
        x = [x for x in cands if x["axis"] == k and x["turn"] == 180][0]
        # a point on the axis: t = (I - R) p for the refined turn; p_perp = t/2 for 180 deg
        a = np.array(x["axis_vec"])
        t = np.array(x["t"]); p = (t - (t @ a) * a) / 2
        out["continuous"] = [{"axis": a.tolist(), "offset": p.tolist()}]
        disc = disc[:1]
    if disc:
        out["discrete"] = [np.vstack([np.hstack([R, t[:, None]]), [0, 0, 0, 1]]).flatten().tolist() for _, _, R, t in disc]
    out["why"] = [f"axis{k} continuous" for k in cont] + [f"axis{k} 180 (p99 {p:.2f} mm)" for k, p, _, _ in disc]
    chosen[c] = out
    print(c, entry["name"], out["why"])
json.dump(chosen, open(os.path.join(HERE, "symmetries.json"), "w"), indent=1)
