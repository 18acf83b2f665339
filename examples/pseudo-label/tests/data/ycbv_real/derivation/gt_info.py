"""Writes each scene's `scene_gt_info.json` as the BOP toolkit's `calc_gt_info.py` computes it:
the scan rendered alone at the ground-truth pose (`ipdf render`) into an image three times the
frame's width and height, centred on it, so that the silhouette cut by the frame's border is
counted whole (`px_count_all`, `bbox_obj`); its pixels inside the frame with a depth reading
(`px_count_valid`); the visible pixels (`px_count_visib`, `bbox_visib`): those of the visible
mask (`mask_visib/`, from YCB-Video's label image rather than BOP's depth test) on the
silhouette, which BOP's visible mask is by construction; `visib_fract = px_count_visib /
px_count_all`. Boxes `[x, y, w, h]` count from the first pixel to the last (`calc_2d_bbox`).

    python3 gt_info.py IPDF   # IPDF: the ipdf binary (numpy and Pillow needed)
"""
import json, os, subprocess, sys, tempfile
import numpy as np
from PIL import Image

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def box(mask, dx=0, dy=0):
    """BOP's [x, y, w, h] of a mask's pixels (w = last column - first), shifted by (dx, dy)."""
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        return [-1, -1, -1, -1]
    return [int(xs.min()) + dx, int(ys.min()) + dy, int(xs.max() - xs.min()), int(ys.max() - ys.min())]


def silhouette(ipdf, mesh, k, width, height, pose, work):
    """The mesh's mask at `pose` in the frame's camera extended by a frame on every side."""
    camera = {"cam_K": [k[0], k[1], k[2] + width, k[3], k[4], k[5] + height, 0, 0, 1],
              "width": 3 * width, "height": 3 * height, "depth_scale": 1.0}
    paths = {name: os.path.join(work, name) for name in ("camera.json", "pose.json", "depth.png", "mask.png")}
    json.dump(camera, open(paths["camera.json"], "w"))
    json.dump(pose, open(paths["pose.json"], "w"))
    subprocess.run([ipdf, "render", "--mesh", mesh, "--camera", paths["camera.json"], "--pose",
                    paths["pose.json"], "--out", paths["depth.png"], "--mask", paths["mask.png"]],
                   check=True, capture_output=True)
    return np.array(Image.open(paths["mask.png"])) > 0


def scene_info(ipdf, scene, work):
    gt = json.load(open(os.path.join(scene, "scene_gt.json")))
    cameras = json.load(open(os.path.join(scene, "scene_camera.json")))
    info = {}
    for image, instances in gt.items():
        depth = np.array(Image.open(os.path.join(scene, "depth", f"{int(image):06d}.png")))
        height, width = depth.shape
        k = cameras[image]["cam_K"]
        entries = []
        for i, instance in enumerate(instances):
            mesh = os.path.join(ROOT, "models", f"obj_{instance['obj_id']:06d}.ply")
            whole = silhouette(ipdf, mesh, k, width, height, instance, work)
            inside = whole[height:2 * height, width:2 * width]
            label = np.array(Image.open(os.path.join(scene, "mask_visib", f"{int(image):06d}_{i:06d}.png"))) > 0
            visib = label & inside
            count_all = int(whole.sum())
            entries.append({
                "bbox_obj": box(whole, -width, -height),
                "bbox_visib": box(visib),
                "px_count_all": count_all,
                "px_count_valid": int((inside & (depth > 0)).sum()),
                "px_count_visib": int(visib.sum()),
                "visib_fract": float(visib.sum() / count_all) if count_all else 0.0,
            })
        info[image] = entries
    return info


def main():
    ipdf = sys.argv[1]
    test = os.path.join(ROOT, "test")
    with tempfile.TemporaryDirectory() as work:
        for name in sorted(os.listdir(test)):
            scene = os.path.join(test, name)
            info = scene_info(ipdf, scene, work)
            with open(os.path.join(scene, "scene_gt_info.json"), "w") as f:
                json.dump(info, f, indent=2)
            for image, entries in info.items():
                fractions = ", ".join(f"{e['visib_fract']:.2f}" for e in entries)
                print(f"scene {name}, image {image}: visib_fract {fractions}")


if __name__ == "__main__":
    main()
