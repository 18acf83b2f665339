"""Baseline for the `grid/generate` criterion benches: the same SO(3) grids with healpy + numpy.

Two ways, both timed as the best of several runs on the machine that runs the script:
- `ipdf_reference`: the construction of the Implicit-PDF reference implementation
  (`generate_healpix_grid`: healpy pix2vec, then per tilt a product of Euler rotation matrices),
  with numpy in place of tensorflow-graphics; N×3×3 float64 matrices.
- `numpy_hopf`: a fully vectorised numpy version of what so3-grid computes (shortest-arc
  section per pixel times ψ bin centres, as quaternions); N×4 float64.

Run: `make bench-python` (creates .venv-bench with healpy and numpy).
"""
import json
import time

import healpy as hp
import numpy as np


def euler_x(a):
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    return np.stack([one, zero, zero, zero, c, -s, zero, s, c], -1).reshape(a.shape + (3, 3))


def euler_z(a):
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    return np.stack([c, -s, zero, s, c, zero, zero, zero, one], -1).reshape(a.shape + (3, 3))


def ipdf_reference(level):
    nside = 2**level
    npix = hp.nside2npix(nside)
    x, y, z = hp.pix2vec(nside, np.arange(npix), nest=True)
    azimuths = np.arctan2(y, x)
    polars = np.arccos(z)
    tilts = np.linspace(0, 2 * np.pi, 6 * 2**level, endpoint=False)
    base = euler_x(azimuths) @ euler_z(polars)
    return np.concatenate([base @ euler_x(np.array(t)) for t in tilts], 0)


def numpy_hopf(level):
    nside = 2**level
    npix = hp.nside2npix(nside)
    x, y, z = hp.pix2vec(nside, np.arange(npix), nest=True)
    north = np.stack([1 + z, -y, x, np.zeros_like(z)], 1)
    south = np.stack([-y, 1 - z, np.zeros_like(z), x], 1)
    base = np.where((np.arange(npix) >> (2 * level) >= 8)[:, None], south, north)
    base /= np.linalg.norm(base, axis=1, keepdims=True)
    nbins = 6 * 2**level
    half = 0.5 * (np.arange(nbins) + 0.5) * 2 * np.pi / nbins
    c, s = np.cos(half)[None, :], np.sin(half)[None, :]
    p0, p1, p2, p3 = (base[:, i : i + 1] for i in range(4))
    q = np.stack([p0 * c - p3 * s, p1 * c + p2 * s, p2 * c - p1 * s, p3 * c + p0 * s], -1)
    return q.reshape(-1, 4)


def best_of(fn, level, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn(level)
        times.append(time.perf_counter() - start)
    return min(times), len(out)


def main():
    results = {}
    for level, repeats in ((4, 20), (5, 5)):
        for fn in (ipdf_reference, numpy_hopf):
            seconds, count = best_of(fn, level, repeats)
            results[f"{fn.__name__}/level{level}"] = {"count": count, "ms": round(seconds * 1e3, 3)}
    print(json.dumps({"healpy": hp.__version__, "numpy": np.__version__, "results": results}, indent=2))


if __name__ == "__main__":
    main()
