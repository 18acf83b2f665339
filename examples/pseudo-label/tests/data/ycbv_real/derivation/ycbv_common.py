"""Shared readers of the fixture's derivation: the three source repositories (git directories
named by the environment variables YCBV_REPO, YCB_SIM_REPO and ISAAC_REPO, read with
`git show HEAD:path`), the frames, the meshes, and the registration helpers."""
import io, json, os, struct, subprocess
import numpy as np
import scipy.io
from PIL import Image

YCBV = os.environ.get("YCBV_REPO", "ycbvideo")  # oprb/ycbvideo @ 31513757
SIM = os.environ.get("YCB_SIM_REPO", "YCB_sim")  # vikashplus/YCB_sim @ 57546b87
ISAAC = os.environ.get("ISAAC_REPO", "IsaacGymEnvs")  # isaac-sim/IsaacGymEnvs @ aeed2986
HERE = os.path.dirname(os.path.abspath(__file__))
# The objects of each sequence that have a mesh; frame 1 is labelled, frames 2-5 calibrate.
SEQUENCES = {0: [8, 14, 21], 1: [1, 2, 3, 5], 2: [5, 7, 9, 10]}
DATA = "data/tests/ycb_video_dataset/data"

NAMES = {1: "002_master_chef_can", 2: "003_cracker_box", 3: "004_sugar_box", 4: "005_tomato_soup_can",
         5: "006_mustard_bottle", 6: "007_tuna_fish_can", 7: "008_pudding_box", 8: "009_gelatin_box",
         9: "010_potted_meat_can", 10: "011_banana", 11: "019_pitcher_base", 12: "021_bleach_cleanser",
         13: "024_bowl", 14: "025_mug", 15: "035_power_drill", 16: "036_wood_block", 17: "037_scissors",
         18: "040_large_marker", 19: "051_large_clamp", 20: "052_extra_large_clamp", 21: "061_foam_brick"}


def git_bytes(repo, path):
    return subprocess.run(["git", "-C", repo, "show", f"HEAD:{path}"], check=True, capture_output=True).stdout


def read_msh(data):
    nv, nn, nt, nf = struct.unpack_from("<4i", data, 0)
    off = 16
    v = np.frombuffer(data, "<f4", 3 * nv, off).reshape(-1, 3).astype(np.float64); off += 12 * nv
    off += 12 * nn + 8 * nt
    f = np.frombuffer(data, "<i4", 3 * nf, off).reshape(-1, 3).astype(np.int64)
    return v, f


def read_msh_texcoords(data):
    """The per-vertex texture coordinates of a MuJoCo .msh (v counted from the image's top)."""
    nv, nn, nt, nf = struct.unpack_from("<4i", data, 0)
    assert nt == nv, "one texture coordinate per vertex"
    off = 16 + 12 * nv + 12 * nn
    return np.frombuffer(data, "<f4", 2 * nt, off).reshape(-1, 2).astype(np.float64)


def read_obj_corner_texcoords(text, nv):
    """Each vertex's texture coordinates over the faces' corners that use it (OBJ `f v/vt`)."""
    vt, corners = [], [[] for _ in range(nv)]
    for line in text.splitlines():
        p = line.split()
        if p and p[0] == "vt":
            vt.append([float(x) for x in p[1:3]])
        elif p and p[0] == "f":
            for c in p[1:]:
                i, t = c.split("/")[:2]
                corners[int(i) - 1].append(vt[int(t) - 1] if int(t) > 0 else vt[int(t)])
    return corners


def bilinear(img, u, v):
    """RGB of an image at OpenGL texture coordinates (v counted from the bottom)."""
    h, w, _ = img.shape
    x = np.clip(u % 1.0 * w - 0.5, 0, w - 1)
    y = np.clip((1.0 - v % 1.0) * h - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


TEXTURE_SIZE = 512  # the fixture's texture images, downscaled from 4096² (YCB_sim)


def source_appearance(obj_id):
    """The scan's surface: ("texture", per-vertex UV with v from the bottom, RGB image) for the
    YCB_sim meshes, whose .msh carries one texture coordinate per vertex; ("colours", per-vertex
    RGB 0-255) for the IsaacGymEnvs meshes, whose OBJ indexes its texture per corner: each vertex
    takes the mean of its corners' texels (their own vertex colours are a uniform grey)."""
    name = NAMES[obj_id]
    if obj_id in (10, 14, 21):
        folder = f"assets/urdf/ycb/{name}"
        text = git_bytes(ISAAC, f"{folder}/textured.obj").decode()
        nv = sum(1 for line in text.splitlines() if line.startswith("v "))
        img = np.asarray(Image.open(io.BytesIO(git_bytes(ISAAC, f"{folder}/MI_{name}_MI_{name}_D.png"))).convert("RGB"), np.float64)
        rgb = np.zeros((nv, 3))
        for i, c in enumerate(read_obj_corner_texcoords(text, nv)):
            if c:
                c = np.array(c)
                rgb[i] = bilinear(img, c[:, 0], c[:, 1]).mean(0)
        return "colours", np.round(rgb).astype(np.uint8), None
    uv = read_msh_texcoords(git_bytes(SIM, f"meshes/{name}.msh"))
    uv[:, 1] = 1.0 - uv[:, 1]
    img = Image.open(io.BytesIO(git_bytes(SIM, f"textures/{name}.png"))).convert("RGB")
    return "texture", uv, img.resize((TEXTURE_SIZE, TEXTURE_SIZE), Image.LANCZOS)


def read_obj(text):
    v, f = [], []
    for line in text.splitlines():
        p = line.split()
        if not p:
            continue
        if p[0] == "v":
            v.append([float(x) for x in p[1:4]])
        elif p[0] == "f":
            idx = [int(x.split("/")[0]) for x in p[1:]]
            idx = [i - 1 if i > 0 else len(v) + i for i in idx]
            for k in range(1, len(idx) - 1):
                f.append([idx[0], idx[k], idx[k + 1]])
    return np.array(v), np.array(f, dtype=np.int64)


def source_mesh(obj_id):
    """Vertices in metres in the source's own frame, faces, and the source path."""
    name = NAMES[obj_id]
    if obj_id in (10, 14, 21):
        path = f"assets/urdf/ycb/{name}/textured.obj"
        v, f = read_obj(git_bytes(ISAAC, path).decode())
        return v * 0.01, f, ("isaac-sim/IsaacGymEnvs", path)
    path = f"meshes/{name}.msh"
    v, f = read_msh(git_bytes(SIM, path))
    return v, f, ("vikashplus/YCB_sim", path)


def frame(seq, im):
    base = f"{DATA}/{seq:04d}/{im:06d}"
    meta = scipy.io.loadmat(io.BytesIO(git_bytes(YCBV, base + "-meta.mat")))
    depth_png = git_bytes(YCBV, base + "-depth.png")
    depth = np.array(Image.open(io.BytesIO(depth_png))).astype(np.float64) / float(meta["factor_depth"].squeeze())
    label = np.array(Image.open(io.BytesIO(git_bytes(YCBV, base + "-label.png"))))
    cls = meta["cls_indexes"].flatten().astype(int)
    poses = meta["poses"]
    K = meta["intrinsic_matrix"]
    return dict(meta=meta, depth=depth, depth_png=depth_png, label=label, cls=cls, poses=poses, K=K, base=base)


def backproject(depth, mask, K):
    v, u = np.nonzero(mask & (depth > 0))
    z = depth[v, u]
    x = (u - K[0, 2]) * z / K[0, 0]
    y = (v - K[1, 2]) * z / K[1, 1]
    return np.stack([x, y, z], 1)


def sample_surface(v, f, n, rng):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    idx = rng.choice(len(f), n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    return (1 - s)[:, None] * a[idx] + (s * (1 - r2))[:, None] * b[idx] + (s * r2)[:, None] * c[idx]


def observations():
    """Per object, the masked depth of frames 2-5 and of frame 1 (two lists of point arrays),
    taken into the YCB-Video model frame by the ground-truth poses (metres)."""
    calibrate, held = {}, {}
    for seq, ids in SEQUENCES.items():
        for im in range(1, 6):
            fr = frame(seq, im)
            for j, c in enumerate(fr["cls"]):
                if c not in ids:
                    continue
                R, t = fr["poses"][:, :3, j], fr["poses"][:, 3, j]
                model = (backproject(fr["depth"], fr["label"] == c, fr["K"]) - t) @ R
                (held if im == 1 else calibrate).setdefault(c, []).append(model)
    return calibrate, held


def kabsch(p, q):
    """The rigid transform (R, t) taking points p onto q in the least-squares sense."""
    mp, mq = p.mean(0), q.mean(0)
    U, S, Vt = np.linalg.svd((p - mp).T @ (q - mq))
    D = np.diag([1, 1, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, mq - R @ mp
