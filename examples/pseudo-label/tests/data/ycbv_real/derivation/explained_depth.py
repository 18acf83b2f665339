"""How much of each instance's depth a pose explains: the instance's masked depth taken into the
model frame by the ground-truth pose and by each pseudo label, and the distance of each point to
the scan (200,000 points sampled on it, nearest by k-d tree). Prints, per instance, the median
and 90th-percentile distance (mm) and the fraction within 5 mm, for the truth and every label.

Usage: label a copy of the fixture first, then point this at it:
    cp -r examples/pseudo-label/tests/data/ycbv_real /tmp/ycbv
    ipdf label --dataset /tmp/ycbv --split test --sensor kinect
    python3 explained_depth.py /tmp/ycbv
Reads only the fixture's own files (no source repository)."""
import json, os, sys
import numpy as np
from PIL import Image
from scipy.spatial import cKDTree

from ycbv_common import backproject, sample_surface


def read_ply(path):
    """The fixture's binary PLY (as `make_fixture.write_ply` writes it): vertices, faces."""
    with open(path, "rb") as fh:
        data = fh.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    nv = int(next(l for l in header if l.startswith("element vertex")).split()[2])
    nf = int(next(l for l in header if l.startswith("element face")).split()[2])
    v = np.frombuffer(data, "<f4", 3 * nv, end).reshape(-1, 3).astype(np.float64)
    rec = np.frombuffer(data, [("n", "u1"), ("i", "<i4", 3)], nf, end + 12 * nv)
    return v, rec["i"].astype(np.int64)


def distances(points, pose, tree):
    rotation = np.array(pose["cam_R_m2c"]).reshape(3, 3)
    return tree.query((points - np.array(pose["cam_t_m2c"])) @ rotation)[0]


def summary(d):
    return f"{np.median(d):5.2f} {np.percentile(d, 90):6.2f} {np.mean(d < 5.0):5.1%}"


def main(root):
    rng = np.random.default_rng(0)
    trees = {}
    print("scene obj  pose    median   p90  within 5 mm  (mm; score of the label)")
    for scene in sorted(os.listdir(f"{root}/test")):
        base = f"{root}/test/{scene}"
        if not os.path.isdir(base):
            continue
        camera = json.load(open(f"{base}/scene_camera.json"))
        truth = json.load(open(f"{base}/scene_gt.json"))
        labels = json.load(open(f"{base}/scene_pseudo_gt.json"))
        for im, instances in truth.items():
            K = np.array(camera[im]["cam_K"]).reshape(3, 3)
            depth_png = f"{base}/depth/{int(im):06d}.png"
            depth = np.array(Image.open(depth_png)).astype(np.float64) * camera[im]["depth_scale"]
            for k, gt in enumerate(instances):
                obj = gt["obj_id"]
                if obj not in trees:
                    v, f = read_ply(f"{root}/models/obj_{obj:06d}.ply")
                    trees[obj] = cKDTree(sample_surface(v, f, 200_000, rng))
                mask = np.array(Image.open(f"{base}/mask_visib/{int(im):06d}_{k:06d}.png")) > 0
                points = backproject(depth, mask, K)
                print(f"{scene} {obj:3d}  truth   {summary(distances(points, gt, trees[obj]))}")
                entry = labels.get(im, [])[k] if k < len(labels.get(im, [])) else {}
                for label in entry.get("labels", []):
                    d = distances(points, label, trees[obj])
                    print(f"{scene} {obj:3d}  label   {summary(d)}  ({label['score']:.3f})")


if __name__ == "__main__":
    main(sys.argv[1])
