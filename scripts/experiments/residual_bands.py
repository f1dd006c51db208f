"""Where a fitted model's height spread lies against real's: the sd of the
height residual (a DEM minus its sim pose's DEM) per terrain and band of
rows, real against model(sim), over the pairs. dem-gap's spread terms pool
every terrain; this splits them, to see whether a model spreads heights
where real does (at steps, far ahead) or everywhere alike.

    dem-sensor apply --sensor GAP/sensor.json --labels DATA/sim_labels.csv \
        --seed S DATA/sim.npy -o model.npy
    python residual_bands.py DATA model.npy

DATA holds sim.npy, real.npy, pairs.csv and real_labels.csv (as
`scripts/gap_demo.sh` writes `OUT/gap/data-all`); model.npy is sim.npy
through the model. Prints a Markdown table: per terrain and band of rows
(behind: x < 0; near: 0 <= x < 0.5 m; far: x >= 0.5 m; row r spans x from
-0.6 + 0.1 r) the share of step cells (a jump of more than 5 cm to the
row ahead or behind in sim), and the residual sd in mm, real / model, on
even ground and at the step cells.
"""

import csv
import sys

import numpy as np

JUMP = 0.05
BANDS = (("behind", 0, 6), ("near", 6, 11), ("far", 11, 20))


def heights(a):
    """Channel 0 where the mask says valid, else NaN; rows 0..19."""
    return np.where(a[:, :20, :, 1] > 0, a[:, :20, :, 0], np.nan)


def step_cells(sim):
    """Cells with a jump of more than JUMP to the row ahead or behind."""
    jump = np.abs(np.diff(sim, axis=1)) > JUMP
    at = np.zeros(sim.shape, bool)
    at[:, :-1] |= jump
    at[:, 1:] |= jump
    return at


def sd_mm(res, mask):
    v = res[mask]
    v = v[np.isfinite(v)]
    return 1000 * float(np.std(v)) if v.size > 1 else float("nan")


def main():
    data, model_path = sys.argv[1], sys.argv[2]
    pairs = np.loadtxt(f"{data}/pairs.csv", delimiter=",", skiprows=1, dtype=int, ndmin=2)
    sim = heights(np.load(f"{data}/sim.npy")[pairs[:, 0]])
    real = heights(np.load(f"{data}/real.npy")[pairs[:, 1]])
    model = heights(np.load(model_path)[pairs[:, 0]])
    with open(f"{data}/real_labels.csv", newline="") as f:
        terrain = np.array([row["terrain"] for row in csv.DictReader(f)])[pairs[:, 1]]
    steps = step_cells(sim)
    print("| terrain | band | records | step cells | residual sd real / model (mm): even ground | at steps |")
    print("|---|---|---|---|---|---|")
    for name in sorted(set(terrain)):
        of = (terrain == name)[:, None, None]
        for band, lo, hi in BANDS:
            rows = np.zeros(sim.shape, bool)
            rows[:, lo:hi] = True
            mask = of & rows
            even, at = mask & ~steps, mask & steps
            print(
                f"| {name} | {band} | {int(of.sum())} | {100 * steps[mask].mean():.0f} % "
                f"| {sd_mm(real - sim, even):.1f} / {sd_mm(model - sim, even):.1f} "
                f"| {sd_mm(real - sim, at):.1f} / {sd_mm(model - sim, at):.1f} |"
            )


if __name__ == "__main__":
    main()
