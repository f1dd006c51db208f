"""How much each dem-synth emulator stage contributes: for the measured DEMs
of the first 20 testdata runs, with every stage on and with one stage off,
the missing-cell rate, the height residual against the sim DEM of the same
pose on cells both have, and the equation 7.1 error of sim-as-is (Identity).

usage: BIN=target/release python effect_table.py SIM.npy LABEL=REAL.npy [LABEL=REAL.npy ...]
Real record i and sim record i share a pose (dem-synth writes measured runs first).
Prints a Markdown table. The equation 7.1 columns are dem-eval's (`--identity`
on the pairs i <-> i), so the metric has one definition.
"""
import csv
import io
import os
import subprocess
import sys
import tempfile

import numpy as np

BIN = os.environ.get("BIN", "target/release")


def identity_error(sim_path, real_path, n):
    """Mean and median equation 7.1 error of sim as is, by dem-eval."""
    with tempfile.TemporaryDirectory() as d:
        pairs = os.path.join(d, "pairs.csv")
        with open(pairs, "w") as f:
            f.write("sim_index,real_index\n" + "".join(f"{i},{i}\n" for i in range(n)))
        out = subprocess.run(
            [os.path.join(BIN, "dem-eval"), "--sim", sim_path, "--real", real_path, "--pairs", pairs,
             "--identity", "--format", "csv"],
            check=True, capture_output=True, text=True).stdout
    row = next(csv.DictReader(io.StringIO(out)))
    return float(row["mean"]), float(row["median"])


sim_path = sys.argv[1]
sim = np.load(sim_path)
print("| measured data | records | missing cells | missing, rows 0-5 | missing, rows 6-19 | residual mean (m) | residual sd (m) | Identity eq. 7.1 mean | median |")
print("|---|---|---|---|---|---|---|---|---|")
for arg in sys.argv[2:]:
    label, path = arg.split("=", 1)
    real = np.load(path)
    s = sim[: len(real), :20]
    r = real[:, :20]
    valid = r[..., 1] > 0
    res = (r[..., 0] - s[..., 0])[valid]
    mean, median = identity_error(sim_path, path, len(real))
    miss = 1 - valid.mean()
    print(f"| {label} | {len(real)} | {miss:.1%} | {1 - valid[:, :6].mean():.1%} | {1 - valid[:, 6:].mean():.1%} "
          f"| {res.mean():+.4f} | {res.std():.4f} | {mean:.3f} | {median:.3f} |")
