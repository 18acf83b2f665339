"""Writes the fixture (python3 make_fixture.py OUT_DIR) from the three repositories, the offsets
and the symmetries. The whole derivation, in order: calibrate_offsets.py (rigid fit, for
comparison), translation_only.py (offsets.json), symmetry_analysis.py, choose_symmetries.py
(symmetries.json), make_fixture.py."""
import io, json, os, sys
import numpy as np
from PIL import Image
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ycbv_common import *

OUT = sys.argv[1]
offsets = json.load(open(os.path.join(HERE, "offsets.json")))
symm = json.load(open(os.path.join(HERE, "symmetries.json")))
SCENES = {0: 1, 1: 1, 2: 1}  # sequence -> image id (frames 2-5 calibrated the meshes)

def write_ply(path, v, f, appearance):
    """Binary PLY: positions, then the scan's surface (texture_u/v and `comment TextureFile`, or
    red/green/blue), then the faces."""
    kind, values, _ = appearance
    texture = os.path.basename(path)[:-4] + ".jpg"
    header = "ply\nformat binary_little_endian 1.0\ncomment YCB scan in the YCB-Video model frame, mm (see SOURCES.md)\n"
    if kind == "texture":
        header += f"comment TextureFile {texture}\n"
    header += f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
    if kind == "texture":
        fields = [("p", "<f4", 3), ("uv", "<f4", 2)]
        header += "property float texture_u\nproperty float texture_v\n"
    else:
        fields = [("p", "<f4", 3), ("rgb", "u1", 3)]
        header += "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    header += f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n"
    vert = np.zeros(len(v), dtype=fields)
    vert["p"] = v
    vert["uv" if kind == "texture" else "rgb"] = values
    with open(path, "wb") as fh:
        fh.write(header.encode())
        fh.write(vert.tobytes())
        rec = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", 3)])
        rec["n"] = 3; rec["i"] = f
        fh.write(rec.tobytes())
    if kind == "texture":
        appearance[2].save(os.path.join(os.path.dirname(path), texture), quality=85)

def dump(path, obj):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as fh:
        json.dump(obj, fh, indent=2)

os.makedirs(f"{OUT}/models", exist_ok=True)
info = {}
for c, o in offsets.items():
    c = int(c)
    v, f, _ = source_mesh(c)
    R0, t0 = np.array(o["R_ycbv_to_src"]), np.array(o["t_ycbv_to_src"])
    vy = (v - t0) @ R0 * 1000.0
    write_ply(f"{OUT}/models/obj_{c:06d}.ply", vy, f, source_appearance(c))
    from scipy.spatial import ConvexHull
    from scipy.spatial.distance import pdist
    hull = vy[ConvexHull(vy).vertices]
    lo, hi = vy.min(0), vy.max(0)
    entry = dict(diameter=float(pdist(hull).max()), min_x=float(lo[0]), min_y=float(lo[1]), min_z=float(lo[2]),
                 size_x=float(hi[0] - lo[0]), size_y=float(hi[1] - lo[1]), size_z=float(hi[2] - lo[2]))
    s = symm.get(str(c), {})
    if s.get("continuous"):
        entry["symmetries_continuous"] = s["continuous"]
    if s.get("discrete"):
        entry["symmetries_discrete"] = s["discrete"]
    info[str(c)] = entry
dump(f"{OUT}/models/models_info.json", info)

for seq, im in SCENES.items():
    fr = frame(seq, im)
    sd = f"{OUT}/test/{seq:06d}"
    os.makedirs(f"{sd}/depth", exist_ok=True); os.makedirs(f"{sd}/rgb", exist_ok=True); os.makedirs(f"{sd}/mask_visib", exist_ok=True)
    open(f"{sd}/depth/{im:06d}.png", "wb").write(fr["depth_png"])
    rgb = Image.open(io.BytesIO(git_bytes(YCBV, fr["base"] + "-color.png"))).convert("RGB")
    rgb.save(f"{sd}/rgb/{im:06d}.jpg", quality=90)
    K = fr["K"]
    dump(f"{sd}/scene_camera.json", {str(im): {"cam_K": [float(x) for x in K.flatten()], "depth_scale": 0.1}})
    gts = []
    k = 0
    for j, c in enumerate(fr["cls"]):
        if str(c) not in offsets:
            continue
        m = fr["label"] == c
        Image.fromarray((m * 255).astype(np.uint8)).save(f"{sd}/mask_visib/{im:06d}_{k:06d}.png")
        R, t = fr["poses"][:, :3, j], fr["poses"][:, 3, j] * 1000.0
        gts.append({"cam_R_m2c": [float(x) for x in R.flatten()], "cam_t_m2c": [float(x) for x in t], "obj_id": int(c)})
        k += 1
    dump(f"{sd}/scene_gt.json", {str(im): gts})
print("factor_depth", [float(frame(s, i)["meta"]["factor_depth"].squeeze()) for s, i in SCENES.items()])
