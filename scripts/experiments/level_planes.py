"""How a set of DEMs moves whole records: each planar record (half the
cells valid or more, the valid heights within 2 cm rms of the plane
h = m + a x + b y fitted to them) gives its plane, and the planes spread
over the records. A mount's angle, drift and vibration move level ground
with a random sign per run or frame, which leaves every per-row mean where
it was; the planes show it. The spread is the interquartile range / 1.349
(an sd that the few ramps and pallet tops of a world, which are terrain,
do not carry), and the slopes are given as the heights they make 1 m away.

    python level_planes.py W/sim.npy W/real.npy [model.npy ...]

Prints, per file, the planar records and the spread of m (the height at
C), a and b in mm.
"""

import sys

import numpy as np

PLANAR_RMS = 0.02
# Cell centres (docs/format.md): row r at x = -0.55 + 0.1 r, column c at
# y = 0.2 - 0.1 c.
X, Y = np.meshgrid(-0.55 + 0.1 * np.arange(20), 0.2 - 0.1 * np.arange(5), indexing="ij")


def planes(path):
    """The (m, a, b) of each planar record of the NPY file at `path`."""
    a = np.load(path, mmap_mode="r")
    out = []
    for d in a:
        valid = d[:20, :, 1] > 0
        if 2 * valid.sum() < valid.size:
            continue
        h = d[:20, :, 0][valid].astype(np.float64)
        design = np.stack([np.ones(h.size), X[valid], Y[valid]], axis=1)
        p, *_ = np.linalg.lstsq(design, h, rcond=None)
        if np.sqrt(np.mean((h - design @ p) ** 2)) < PLANAR_RMS:
            out.append(p)
    return np.array(out).reshape(-1, 3), len(a)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    print("| file | records | planar | spread of m / a / b (mm) |")
    print("|---|---|---|---|")
    for path in sys.argv[1:]:
        p, n = planes(path)
        if len(p) == 0:
            print(f"| {path} | {n} | 0 | - |")
            continue
        q1, q3 = np.percentile(p, [25, 75], axis=0)
        spread = " / ".join(f"{1000 * s:.1f}" for s in (q3 - q1) / 1.349)
        print(f"| {path} | {n} | {len(p)} | {spread} |")


if __name__ == "__main__":
    main()
