"""Make "real" data with effects that dem-gap's vocabulary does NOT have, so
its tests can check that what no effect explains is reported as unexplained,
and where. numpy only, independent of the Rust code.

usage: python unmodelled_effects.py SIM.npy LABELS.csv OUT.npy SEED EFFECT [EFFECT ...]
EFFECT: name:param=value,param=value   (applied in the order given)
Record i of OUT is record i of SIM (identity pairing). LABELS.csv is the
sim records' labels (index,terrain,...); effects with `terrain` act on the
records of that terrain only.

Effects (x of row r = -0.55 + 0.1 r; column c is at y = (2 - c) 0.1 m,
columns 0-1 on the robot's left, 3-4 on its right):
  smudge   a smudge on one side of the lens: in columns c0..c1 (inclusive)
           and rows with centre x >= x0, each valid cell is missing with
           probability p   (params c0, c1, x0, p)
  offset   on records of `terrain`, cells in rows with centre x in [x0, x1)
           read dz higher (a height offset on one kind of terrain only, as a
           mis-registered map on steps going down)   (terrain, x0, x1, dz)
  holes    on records of `terrain`, cells in rows with centre x >= x0 are
           missing with probability p (dark material far ahead on one kind
           of terrain)   (terrain, x0, p)
"""
import csv
import sys

import numpy as np

X = -0.55 + 0.1 * np.arange(20)


def main():
    sim_path, labels_path, out_path, seed = sys.argv[1:5]
    d = np.load(sim_path).astype(np.float32).copy()
    with open(labels_path) as f:
        terrain = np.array([row["terrain"] for row in csv.DictReader(f)])
    assert len(terrain) == len(d), "one label per record"
    rng = np.random.default_rng(int(seed))
    for spec in sys.argv[5:]:
        name, _, args = spec.partition(":")
        p = {}
        for kv in filter(None, args.split(",")):
            k, v = kv.split("=")
            p[k] = v
        h, m = d[:, :20, :, 0], d[:, :20, :, 1]
        valid = m > 0
        if name == "smudge":
            c0, c1, x0, prob = int(p["c0"]), int(p["c1"]), float(p["x0"]), float(p["p"])
            where = np.zeros((20, 5), bool)
            where[np.ix_(X >= x0, np.arange(c0, c1 + 1))] = True
            lose = valid & where[None] & (rng.random(valid.shape) < prob)
        elif name == "holes":
            x0, prob = float(p["x0"]), float(p["p"])
            rec = terrain == p["terrain"]
            lose = valid & rec[:, None, None] & (X >= x0)[None, :, None] & (rng.random(valid.shape) < prob)
        elif name == "offset":
            x0, x1, dz = float(p["x0"]), float(p["x1"]), float(p["dz"])
            rec = terrain == p["terrain"]
            up = valid & rec[:, None, None] & ((X >= x0) & (X < x1))[None, :, None]
            h[up] += np.float32(dz)
            lose = np.zeros_like(valid)
        else:
            sys.exit(f"unknown effect {name}")
        h[lose] = 0.0
        m[lose] = -1.0
    np.save(out_path, d)


if __name__ == "__main__":
    main()
