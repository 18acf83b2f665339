"""Regenerates healpy_nested.txt, the published-healpy reference values the HEALPix tests check.

Run with any Python that has healpy and numpy: `python make_healpy_fixture.py` (in this folder).
"""
import healpy as hp
import numpy as np

rng = np.random.default_rng(3)
lines = [
    "# healpy %s, nest=True. 'center depth pixel lon lat' (radians) from pix2ang(lonlat=True);" % hp.__version__,
    "# 'hash depth lon lat pixel' from ang2pix(lonlat=True) on random directions.",
]
for depth in (0, 1, 2, 3):
    nside = 2**depth
    for pix in range(hp.nside2npix(nside)):
        lon, lat = hp.pix2ang(nside, pix, nest=True, lonlat=True)
        lines.append("center %d %d %.17g %.17g" % (depth, pix, np.radians(lon), np.radians(lat)))
for depth in (2, 4, 6):
    nside = 2**depth
    v = rng.normal(size=(100, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    lon = np.arctan2(v[:, 1], v[:, 0]) % (2 * np.pi)
    lat = np.arcsin(v[:, 2])
    pix = hp.ang2pix(nside, np.degrees(lon), np.degrees(lat), nest=True, lonlat=True)
    for a, b, p in zip(lon, lat, pix):
        lines.append("hash %d %.17g %.17g %d" % (depth, a, b, p))
open("healpy_nested.txt", "w").write("\n".join(lines) + "\n")
