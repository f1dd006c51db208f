"""How together the cells of one record move: the correlation of height
residuals (a DEM minus the same pose's DEM without the cause) between
across-robot neighbours (columns c and c + 1 of a row), between the two
outer columns (0 and 4), and between rows three apart (r and r + 3, mostly
different steps), at step cells (a jump of more than 5 cm to the row ahead
or behind in the reference) and on even ground.

A cause that moves whole rows or the whole record (a pose error) gives
correlations near 1; one that moves each cell on its own gives 0. The
neighbours' correlation at step cells is what dem-gap's evidence for drift
and step-jitter reports (`step_coherence` in dem_core::distribution).

    python step_coherence.py REFERENCE.npy OTHER.npy LABEL [LABEL ...]

prints one Markdown table row: the labels, then the step and even-ground
correlations. Records are paired by index (the first min(n) of each).
"""

import sys

import numpy as np

from residual_bands import step_cells


def correlation(res, mask, a, b):
    """Correlation of res[a] and res[b] where both cells lie in mask."""
    x, y = res[a], res[b]
    m = mask[a] & mask[b] & np.isfinite(x) & np.isfinite(y)
    if m.sum() < 10:
        return float("nan")
    return float(np.corrcoef(x[m], y[m])[0, 1])


def main():
    reference, other, labels = sys.argv[1], sys.argv[2], sys.argv[3:]
    a, b = np.load(reference), np.load(other)
    n = min(len(a), len(b))
    a, b = a[:n, :20], b[:n, :20]
    valid = (a[..., 1] > 0) & (b[..., 1] > 0)
    res = np.where(valid, b[..., 0] - a[..., 0], np.nan)
    step = step_cells(np.where(a[..., 1] > 0, a[..., 0], np.nan))
    cells = []
    for mask in (valid & step, valid & ~step):
        s = np.s_
        cells += [
            correlation(res, mask, s[:, :, :-1], s[:, :, 1:]),
            correlation(res, mask, s[:, :, 0], s[:, :, 4]),
            correlation(res, mask, s[:, :-3, :], s[:, 3:, :]),
        ]
        cells.append(1000 * float(np.nanstd(res[mask])))
    print("| " + " | ".join(labels + [f"{v:.2f}" for v in cells]) + " |")


if __name__ == "__main__":
    main()
