"""How far one of the emulator's stages moves the cells beside a step.

For each gap_demo.sh output folder given (OUT/gap), the measured DEMs of
`--no-STAGE` (data-no-STAGE/real.npy, smoothing unless --stage says) against
all stages (data-all/real.npy), the same poses record by record. For every cell valid
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

With --per-row, per kind of cell and per row (x of the row's centre, m),
the cells there and the shares that read more than 2 cm higher and more
than 2 cm lower with the stage on (the tables of docs/results.md on the
field of view and the dark patches):

    python scripts/riser_shares.py --stage fov --per-row out-high/gap

With --lost, per kind of cell (per row with --per-row), the cells valid without the stage (their
neighbour too) and the share the stage loses, and of the drops (rows r, r + 1
valid without the stage, r + 1 lower by more than 5 cm) the shares that lose
one cell and both (the measurement behind dem-sensor's `drop-holes`):

    python scripts/riser_shares.py --stage holes --lost out-high/gap

With --per-run, per run (the `sequence` of data-all/real_labels.csv) the
records, the records the stage changes, the cells it loses and the cells it
moves by more than 2 cm, largest first, and the share of all lost cells the
three largest runs hold: whether a stage's gap is a property of the
population or of a few events (a dark patch on one stair edge):

    python scripts/riser_shares.py --stage dropout --per-run out/gap
"""
import argparse
import csv
import os
import sys

import numpy as np

# The step size that makes a riser or drop: dem_core::distribution::JUMP
# (which dem-sensor's MIXED_JUMP and the step-side terms use); keep equal.
JUMP = 0.05
# A height change this large counts as a move in the per-row table (m).
MOVE = 0.02
# Row r's centre lies X0 + r * CELL ahead of the robot's centre (m).
X0, CELL = -0.55, 0.1
# Per kind of cell: the row of the neighbour (+1 ahead, -1 behind) and
# the test on the step to it (neighbour minus cell).
KINDS = {
    "riser-lower": (1, lambda s: s > JUMP),
    "riser-upper": (-1, lambda s: s < -JUMP),
    "drop-upper": (1, lambda s: s < -JUMP),
    "drop-lower": (-1, lambda s: s > JUMP),
}


def load(base, stage):
    """Heights and validity of rows 0-19: without the stage, with all."""
    a = np.load(f"{base}/data-no-{stage}/real.npy")
    b = np.load(f"{base}/data-all/real.npy")
    return a[:, :20, :, 0].astype(float), a[:, :20, :, 1] > 0, b[:, :20, :, 0].astype(float), b[:, :20, :, 1] > 0


def beside_steps(za, va):
    """Per kind, per row r: (row of the neighbour, step to it, the cells
    valid without the stage whose neighbour, valid too, makes the step)."""
    for kind, (dr, is_kind) in KINDS.items():
        for r in range(max(0, -dr), min(20, 20 - dr)):
            step = za[:, r + dr] - za[:, r]
            yield kind, r, r + dr, step, va[:, r] & va[:, r + dr] & is_kind(step)


def cells(base, stage):
    """Per kind, per row: (step to the neighbour, h_all - h_no) of the cells
    valid in both whose neighbour (valid without the stage) makes the step."""
    za, va, zb, vb = load(base, stage)
    out = {kind: {} for kind in KINDS}
    for kind, r, _, step, m in beside_steps(za, va):
        m = m & vb[:, r]
        out[kind][r] = (step[m], (zb[:, r] - za[:, r])[m])
    return out


def lost(base, stage):
    """Per kind: (cells valid without the stage whose neighbour, valid too,
    makes the step, share of them missing with it, per row: (cells, lost));
    and of the drops (a drop's upper cell and the one beyond):
    (drops, share with a cell lost, share with both lost)."""
    za, va, _, vb = load(base, stage)
    gone = va & ~vb
    rows = {kind: {} for kind in KINDS}
    n = one = both = 0
    for kind, r, rn, _, m in beside_steps(za, va):
        rows[kind][r] = (int(m.sum()), int((m & gone[:, r]).sum()))
        if kind == "drop-upper":
            n += m.sum()
            one += (m & (gone[:, r] | gone[:, rn])).sum()
            both += (m & gone[:, r] & gone[:, rn]).sum()
    out = {}
    for kind, per_row in rows.items():
        total, k = sum(v[0] for v in per_row.values()), sum(v[1] for v in per_row.values())
        out[kind] = (total, k / total if total else None, per_row)
    return out, (int(n), one / n if n else None, both / n if n else None)


def per_run(base, stage):
    """Per run, largest loss first: (run, terrain, records, records
    changed, cells lost, cells moved by more than MOVE), over rows 0-19."""
    za, va, zb, vb = load(base, stage)
    with open(f"{base}/data-all/real_labels.csv", newline="") as f:
        labels = list(csv.DictReader(f))
    if len(labels) != len(za):
        raise SystemExit(f"{base}/data-all/real_labels.csv: {len(labels)} labels for {len(za)} records")
    run = np.array([int(l["sequence"]) for l in labels])
    gone = (va & ~vb).sum(axis=(1, 2))
    moved = (va & vb & (np.abs(zb - za) > MOVE)).sum(axis=(1, 2))
    changed = (va != vb).any(axis=(1, 2)) | (va & vb & (zb != za)).any(axis=(1, 2))
    out = []
    for k in np.unique(run):
        m = run == k
        out.append((int(k), labels[int(np.argmax(m))]["terrain"], int(m.sum()), int(changed[m].sum()), int(gone[m].sum()), int(moved[m].sum())))
    return sorted(out, key=lambda t: (-t[4], -t[5], t[0]))


def shares(base, stage="smoothing"):
    out = {}
    for kind, rows in cells(base, stage).items():
        u = np.concatenate([d / s for s, d in rows.values()])
        # A folder without cells of a kind (no risers, say) gets n = 0.
        out[kind] = (len(u), np.mean(np.abs(u) > 0.1), np.quantile(u, 0.9), np.mean(u)) if len(u) else (0, None, None, None)
    return out


def per_row(base, stage, least):
    """Per kind, the rows with at least `least` cells: (x, cells, share
    higher by more than MOVE, share lower by more than MOVE)."""
    return {
        kind: [(X0 + CELL * r, len(d), np.mean(d > MOVE), np.mean(d < -MOVE)) for r, (_, d) in rows.items() if len(d) >= least]
        for kind, rows in cells(base, stage).items()
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+", metavar="OUT/gap")
    ap.add_argument("--stage", default="smoothing", help="the stage left out (data-no-STAGE): smoothing, fov, dropout, ...")
    ap.add_argument("--per-row", action="store_true", help="per row: the shares of cells that read higher and lower with the stage on")
    ap.add_argument("--least", type=int, default=10, help="per row: leave out rows with fewer cells of a kind (default 10)")
    ap.add_argument("--lost", action="store_true", help="per kind: the share of the cells beside a step that the stage loses, and of the drops")
    ap.add_argument("--per-run", action="store_true", help="per run: the records the stage changes and the cells it loses and moves")
    a = ap.parse_args()
    pct = lambda v: "-" if v is None else f"{100 * v:.1f} %"
    if a.per_run:
        print(f"| folder | run | terrain | records | changed | cells lost | cells moved > {100 * MOVE:.0f} cm |")
        print("|---|---|---|---|---|---|---|")
        for base in a.folders:
            runs = per_run(base, a.stage)
            for r in runs:
                print(f"| {base} | {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]} | {r[5]} |")
            lost_all, moved_all = sum(r[4] for r in runs), sum(r[5] for r in runs)
            top = sum(r[4] for r in runs[:3])
            print(f"| {base} | all {len(runs)} | | {sum(r[2] for r in runs)} | {sum(r[3] for r in runs)} | {lost_all} | {moved_all} |")
            print(f"| {base} | the 3 that lose most | | | | {pct(top / lost_all if lost_all else None)} | |")
        return
    if a.lost:
        print("| folder | cell | cells | lost |")
        print("|---|---|---|---|")
        for base in a.folders:
            kinds, (n, one, both) = lost(base, a.stage)
            for kind, (k, share, rows) in kinds.items():
                if a.per_row:
                    for r, (kr, lr) in rows.items():
                        if kr >= a.least:
                            print(f"| {base} | {kind} at x = {X0 + CELL * r:+.2f} | {kr} | {pct(lr / kr)} |")
                else:
                    print(f"| {base} | {kind} | {k} | {pct(share)} |")
            print(f"| {base} | drops: a cell lost | {n} | {pct(one)} |")
            print(f"| {base} | drops: both lost | {n} | {pct(both)} |")
        return
    if a.per_row:
        print(f"| folder | cell | x (m) | cells | > {100 * MOVE:.0f} cm higher | > {100 * MOVE:.0f} cm lower |")
        print("|---|---|---|---|---|---|")
        for base in a.folders:
            for kind, rows in per_row(base, a.stage, a.least).items():
                for x, n, up, down in rows:
                    print(f"| {base} | {kind} | {x:+.2f} | {n} | {100 * up:.0f} % | {100 * down:.0f} % |")
        return
    print("| folder | cell | cells | moved > 0.1 of the step | u, 90th percentile | u, mean |")
    print("|---|---|---|---|---|---|")
    for base in a.folders:
        for kind, (n, moved, q90, mean) in shares(base, a.stage).items():
            if n == 0:
                print(f"| {base} | {kind} | 0 | - | - | - |")
                continue
            print(f"| {base} | {kind} | {n} | {100 * moved:.0f} % | {q90:.2f} | {mean:.3f} |")


if __name__ == "__main__":
    try:
        main()
    except BrokenPipeError:
        # `| head` took what it wanted: end quietly, as the tools do.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
