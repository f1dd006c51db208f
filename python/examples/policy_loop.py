"""A vectorised training loop with the virtual sensor in it.

Many environments step together; each step the simulator's perfect height
scans (here: DEMs of a dem-synth world, one run per environment) go
through the virtual sensor as one batch, with each environment's time
since its reset, so a fresh episode's first frames miss the rows the
measured maps miss at startup. A sensor with a map's memory keeps each
environment's map from step to step: it takes each environment's motion
since its last step (from the labels' poses), and `reset(ids)` starts the
runs of the episodes that ended while the others keep their maps. The "policy" is a stand-in (a fixed linear
map to a flipper command); what matters is where the sensor sits.

    python python/examples/policy_loop.py gy-sensor.onnx sim.npy sim_labels.csv --envs 64 --steps 50

Prints one line per 10 steps: valid cells per DEM and the share of rows
missing behind the robot in the episodes' first second.
"""

import argparse
import csv

import numpy as np

import demstream
from demstream.sensor import VirtualSensor, motion_between


def runs_of(labels_csv):
    """Record indices of each run (its `sequence`), in time order, and every
    record's pose (x, y, yaw), from a labels CSV."""
    runs, poses = {}, []
    with open(labels_csv) as f:
        for i, row in enumerate(csv.DictReader(f)):
            runs.setdefault(row["sequence"], []).append((float(row["time"]), i))
            poses.append([float(row[k]) for k in ("x", "y", "yaw")])
    return [[i for _, i in sorted(r)] for r in runs.values() if len(r) > 1], np.array(poses)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model")
    ap.add_argument("sim")
    ap.add_argument("labels")
    ap.add_argument("--envs", type=int, default=64)
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--dt", type=float, default=0.1, help="seconds per step")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)

    dems = demstream.read(a.sim)
    runs, poses = runs_of(a.labels)
    sensor = VirtualSensor(a.model)
    rng = np.random.default_rng(a.seed)
    policy = rng.normal(0.0, 0.1, size=(21 * 5 * 2, 4)).astype(np.float32)

    run = rng.integers(0, len(runs), a.envs)
    frame = np.zeros(a.envs, dtype=np.int64)
    t = np.zeros(a.envs, dtype=np.float32)
    stats = []
    last = None
    for step in range(a.steps):
        idx = np.array([runs[r][min(f, len(runs[r]) - 1)] for r, f in zip(run, frame)])
        motion = None if last is None else motion_between(poses[last], poses[idx], a.dt)
        seen = sensor(dems[idx], time=t, rng=rng, motion=motion)  # the virtual sensor, one batch
        last = idx
        action = np.tanh(seen.reshape(a.envs, -1) @ policy)        # the policy's input is what a robot would see
        assert action.shape == (a.envs, 4) and np.isfinite(action).all()
        valid = seen[:, :20, :, 1] > 0
        early = t < 1.0
        behind = (~valid[:, :6]).mean(axis=(1, 2))
        stats.append((valid.sum(axis=(1, 2)).mean(), behind[early].mean() if early.any() else np.nan))
        frame += 1
        t += a.dt
        done = rng.random(a.envs) < 0.05                           # episodes end; resets start at time 0
        sensor.reset(np.flatnonzero(done))                         # their maps start again, the others keep theirs
        run[done] = rng.integers(0, len(runs), done.sum())
        frame[done] = 0
        t[done] = 0.0
        if step % 10 == 9:
            v, b = np.nanmean(np.array(stats[-10:]), axis=0)
            print(f"step {step + 1}: {v:.1f} valid cells per DEM, {b:.2f} of the rows behind missing in the first second")
    return stats


if __name__ == "__main__":
    main()
