"""Is a virtual sensor's output as true as measured DEMs, frame by frame? (numpy only)

    sensor_goals.py --sim SIM.npy --real REAL.npy --virtual V.npy --pairs PAIRS.csv \
        [--labels SIM_LABELS.csv] [--goals demo|recipe] [--check]

PAIRS.csv (sim_index,real_index) says which sim record shows the pose of which measured
record; V.npy holds the virtual sensor's output for every record of SIM.npy (dem-apply's
output on it). Over the pairs, per terrain (sim labels) and for all records, it prints:

  height_cm     mean |v - measured| over cells valid in both (cm); `sim` the same for sim
  vs_sim        mean |v - sim| over cells valid in both, over measured's mean |measured - sim|
  spread        sd over records of each record's mean (v - sim), over measured's
  lift99_cm     99th percentile of |record mean (v - sim)| (cm); measured's beside it
  rough         roughness across (|h(r,c) - h(r,c+1)|) and along (|h(r,c) - h(r+1,c)|),
                over measured's, on neighbour cells valid in both
  rows_closer   1 - sum_r |miss_v(r) - miss_m(r)| / sum_r |miss_s(r) - miss_m(r)|, miss(r) the
                share of row r's cells missing: how much closer to measured than sim v's
                missing cells per row are (1: the same as measured)
  whole_rows    per row, the share of records with all five cells of the row missing, v's
                less measured's: the largest excess over the rows (a row that v strips
                where measured does not), and the row it is in

With --goals, each goal is checked and printed as `goal ... ok` or `goal ... MISSED`, and
--check exits 1 when one is missed:
  demo    (the bundled data, made without the motion stages): height_cm within 2 cm,
          roughness within 1.5x, spread within 1.5x, whole_rows at most 5 points (the
          tolerance of a missing-cell rate), lift99 within 1.5x measured's (or under 2 cm)
  recipe  (worlds with a mount error drawn per run and drift): vs_sim within 0.75-1.33,
          spread within 1.5x, roughness within 1.5x, rows_closer at least 0.7, lift99 as demo
"""
import argparse
import csv
import sys

import numpy as np

FLAT_ROWS = 20


def read_pairs(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return np.array([int(r["sim_index"]) for r in rows]), np.array([int(r["real_index"]) for r in rows])


def read_terrain(path):
    with open(path) as f:
        return np.array([r["terrain"] for r in csv.DictReader(f)])


def grid(x):
    """Heights and validity of rows 0..19."""
    return x[:, :FLAT_ROWS, :, 0].astype(np.float64), x[:, :FLAT_ROWS, :, 1] > 0


def mean_abs(a, va, b, vb):
    both = va & vb
    return float(np.abs(a - b)[both].mean()) if both.any() else float("nan")


def record_means(a, va, b, vb):
    """Each record's mean (a - b) over cells valid in both; NaN where none is."""
    both = va & vb
    n = both.sum(axis=(1, 2))
    s = np.where(both, a - b, 0.0).sum(axis=(1, 2))
    return np.where(n > 0, s / np.maximum(n, 1), np.nan)


def roughness(h, v):
    across = np.abs(np.diff(h, axis=2))[v[:, :, 1:] & v[:, :, :-1]].mean()
    along = np.abs(np.diff(h, axis=1))[v[:, 1:, :] & v[:, :-1, :]].mean()
    return np.array([across, along])


def whole_rows(v):
    """(records, rows): the row has no valid cell."""
    return ~v.any(axis=2)


def measures(s, r, x):
    (hs, vs), (hr, vr), (hx, vx) = grid(s), grid(r), grid(x)
    m_real = record_means(hr, vr, hs, vs)
    m_virt = record_means(hx, vx, hs, vs)
    miss = lambda v: 1.0 - v.mean(axis=(0, 2))
    ms, mr, mx = miss(vs), miss(vr), miss(vx)
    sim_off = np.abs(ms - mr).sum()
    excess = whole_rows(vx).mean(axis=0) - whole_rows(vr).mean(axis=0)
    lift = lambda m: float(np.nanpercentile(np.abs(m), 99))
    return {
        "records": len(s),
        "height_cm": 100 * mean_abs(hx, vx, hr, vr),
        "sim_height_cm": 100 * mean_abs(hs, vs, hr, vr),
        "vs_sim": mean_abs(hx, vx, hs, vs) / mean_abs(hr, vr, hs, vs),
        "spread": float(np.nanstd(m_virt) / np.nanstd(m_real)),
        "lift99_cm": 100 * lift(m_virt),
        "real_lift99_cm": 100 * lift(m_real),
        "rough": roughness(hx, vx) / roughness(hr, vr),
        "rows_closer": float(1 - np.abs(mx - mr).sum() / sim_off) if sim_off > 0 else float("nan"),
        "whole_rows": float(excess.max()),
        "whole_rows_at": int(excess.argmax()),
    }


def line(name, m):
    return (
        f"{name:<12} {m['records']:>6}  height {m['height_cm']:5.2f} cm (sim {m['sim_height_cm']:4.2f})  "
        f"vs_sim {m['vs_sim']:4.2f}x  spread {m['spread']:4.2f}x  lift99 {m['lift99_cm']:5.2f} cm (measured {m['real_lift99_cm']:4.2f})  "
        f"rough {m['rough'][0]:4.2f}x/{m['rough'][1]:4.2f}x  rows_closer {m['rows_closer']:5.2f}  "
        f"whole_rows {100 * m['whole_rows']:+5.1f} points (row {m['whole_rows_at']})"
    )


def lift_ok(m):
    return m["lift99_cm"] <= max(1.5 * m["real_lift99_cm"], 2.0)


GOALS = {
    "demo": [
        ("heights within 2 cm of measured", lambda m: m["height_cm"] <= 2.0),
        ("roughness within 1.5x measured", lambda m: bool(np.all(m["rough"] <= 1.5) and np.all(m["rough"] >= 1 / 1.5))),
        ("spread of record-mean errors within 1.5x measured's", lambda m: m["spread"] <= 1.5),
        ("no row stripped of all its cells more often than in measured (by at most 5 points)", lambda m: m["whole_rows"] <= 0.05),
        ("no whole-record lift (lift99 within 1.5x measured's or under 2 cm)", lift_ok),
    ],
    "recipe": [
        ("height error against sim within 0.75-1.33x measured's", lambda m: 0.75 <= m["vs_sim"] <= 1.33),
        ("spread of record-mean errors within 1.5x measured's", lambda m: m["spread"] <= 1.5),
        ("roughness within 1.5x measured", lambda m: bool(np.all(m["rough"] <= 1.5) and np.all(m["rough"] >= 1 / 1.5))),
        ("missing cells per row >= 70 % closer to measured than sim's", lambda m: m["rows_closer"] >= 0.7),
        ("no whole-record lift (lift99 within 1.5x measured's or under 2 cm)", lift_ok),
    ],
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", required=True)
    ap.add_argument("--real", required=True)
    ap.add_argument("--virtual", required=True)
    ap.add_argument("--pairs", required=True)
    ap.add_argument("--labels", help="sim labels CSV: a line per terrain too")
    ap.add_argument("--goals", choices=sorted(GOALS))
    ap.add_argument("--check", action="store_true", help="exit 1 when a goal is missed")
    a = ap.parse_args()
    sim, real, virt = (np.load(p, mmap_mode="r") for p in (a.sim, a.real, a.virtual))
    if len(virt) != len(sim):
        sys.exit(f"sensor_goals.py: {a.virtual}: {len(virt)} records, but {a.sim} has {len(sim)} (one output per sim record)")
    si, ri = read_pairs(a.pairs)
    s, r, x = np.asarray(sim[si]), np.asarray(real[ri]), np.asarray(virt[si])
    rows = [("all", np.ones(len(si), bool))]
    if a.labels:
        t = read_terrain(a.labels)[si]
        rows += [(name, t == name) for name in ("flat", "stairs-up", "stairs-down", "pallet", "other") if (t == name).sum() >= 20]
    for name, sel in rows:
        print(line(name, measures(s[sel], r[sel], x[sel])))
    if not a.goals:
        return
    m = measures(s, r, x)
    missed = 0
    for text, ok in GOALS[a.goals]:
        good = ok(m)
        missed += not good
        print(f"goal ({a.goals}): {text}: {'ok' if good else 'MISSED'}")
    if missed and a.check:
        sys.exit(1)


if __name__ == "__main__":
    main()
