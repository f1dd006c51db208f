"""How much each dem-synth emulator stage contributes: for the measured DEMs
of the first 20 testdata runs, with every stage on and with one stage off,
the missing-cell rate, the height residual against the sim DEM of the same
pose on cells both have, and the equation 7.1 error of sim-as-is (Identity).

usage: python effect_table.py SIM.npy LABEL=REAL.npy [LABEL=REAL.npy ...]
Real record i and sim record i share a pose (dem-synth writes measured runs first).
Prints a Markdown table.
"""
import sys
import numpy as np

sim = np.load(sys.argv[1])
print("| measured data | records | missing cells | missing, rows 0-5 | missing, rows 6-19 | residual mean (m) | residual sd (m) | Identity eq. 7.1 mean | median |")
print("|---|---|---|---|---|---|---|---|---|")
for arg in sys.argv[2:]:
    label, path = arg.split("=", 1)
    real = np.load(path)
    s = sim[: len(real), :20]
    r = real[:, :20]
    valid = r[..., 1] > 0
    res = (r[..., 0] - s[..., 0])[valid]
    e = ((valid * (r[..., 0] - s[..., 0])) ** 2 + (r[..., 1] - s[..., 1]) ** 2).sum(axis=(1, 2)) / 100
    miss = 1 - valid.mean()
    print(f"| {label} | {len(real)} | {miss:.1%} | {1 - valid[:, :6].mean():.1%} | {1 - valid[:, 6:].mean():.1%} "
          f"| {res.mean():+.4f} | {res.std():.4f} | {e.mean():.3f} | {np.median(e):.3f} |")
