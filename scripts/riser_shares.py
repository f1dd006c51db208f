"""How far the emulator's smoothing stage moves the cells beside a step.

For each gap_demo.sh output folder given (OUT/gap), the measured DEMs of
`--no-smoothing` (data-no-smoothing/real.npy) against all stages
(data-all/real.npy), the same poses record by record. For every cell valid
in both whose x-neighbour (valid in --no-smoothing) differs by more than
5 cm, u = (h_all - h_no) / (h_neighbour - h_no): the share of the step the
cell moves toward its neighbour (negative: away from it). Prints, per kind
of cell, how many there are, the share with |u| > 0.1, the 90th percentile
of u and its mean:

- riser-lower: the cell before a riser (the higher neighbour ahead);
- riser-upper: the top cell after a riser (the lower neighbour behind);
- drop-upper: the top cell before a drop (the lower neighbour ahead);
- drop-lower: the cell beyond a drop (the higher neighbour behind).

    python scripts/riser_shares.py out/gap out-high/gap
"""
import sys

import numpy as np

# The step size that makes a riser or drop: dem_core::distribution::JUMP
# (which dem-sensor's MIXED_JUMP and the step-side terms use); keep equal.
JUMP = 0.05


def shares(base):
    a = np.load(f"{base}/data-no-smoothing/real.npy")
    b = np.load(f"{base}/data-all/real.npy")
    za, va = a[:, :20, :, 0].astype(float), a[:, :20, :, 1] > 0
    zb, vb = b[:, :20, :, 0].astype(float), b[:, :20, :, 1] > 0
    kinds = {
        "riser-lower": (1, lambda s: s > JUMP),
        "riser-upper": (-1, lambda s: s < -JUMP),
        "drop-upper": (1, lambda s: s < -JUMP),
        "drop-lower": (-1, lambda s: s > JUMP),
    }
    out = {}
    for kind, (dr, is_kind) in kinds.items():
        us = []
        for r in range(20):
            rn = r + dr
            if not 0 <= rn < 20:
                continue
            step = za[:, rn] - za[:, r]
            m = va[:, r] & va[:, rn] & vb[:, r] & is_kind(step)
            us.append((zb[:, r] - za[:, r])[m] / step[m])
        u = np.concatenate(us)
        # A folder without cells of a kind (no risers, say) gets n = 0.
        out[kind] = (len(u), np.mean(np.abs(u) > 0.1), np.quantile(u, 0.9), np.mean(u)) if len(u) else (0, None, None, None)
    return out


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: riser_shares.py OUT/gap [OUT/gap ...]")
    print("| folder | cell | cells | moved > 0.1 of the step | u, 90th percentile | u, mean |")
    print("|---|---|---|---|---|---|")
    for base in sys.argv[1:]:
        for kind, (n, moved, q90, mean) in shares(base).items():
            if n == 0:
                print(f"| {base} | {kind} | 0 | - | - | - |")
                continue
            print(f"| {base} | {kind} | {n} | {100 * moved:.0f} % | {q90:.2f} | {mean:.3f} |")


if __name__ == "__main__":
    main()
