"""What a map's memory costs: the virtual sensor with `map-memory` (one graph
with state) against the same sensor without it, per record, in dem-apply and
in onnxruntime, in the same run.

Run through scripts/bench/state.sh (which picks the Python, the binaries and
makes both models). Environment:
  BIN       directory of the release binaries          (default target/release)
  OUT       working directory for files and report     (default .bench)
  RECORDS   records in the input                       (default 100000)
  THREADS   threads for both                           (default 2)
  RUNS      timed runs of each command                 (default 3)
  BATCH     records per call                           (default 4096)

The input is the bundled sim and measured records tiled, labelled as runs of
50 frames at 10 Hz driving forward and turning (every record in a run, in
time order). dem-apply runs each file with --labels (the stateful one steps
its runs); onnxruntime runs the stateless file on batches of BATCH records
and the stateful one as BATCH environments stepped side by side, feeding
each step's state_out to the next (the loop of a training run). Each
command is a whole process timed from spawn to exit, the four in turn RUNS
times; medians quoted.
"""

import csv
import os
import statistics
import subprocess
import sys
import time

import numpy as np

BIN = os.environ.get("BIN", "target/release")
OUT = os.environ.get("OUT", ".bench")
RECORDS = int(os.environ.get("RECORDS", "100000"))
THREADS = int(os.environ.get("THREADS", "2"))
RUNS = int(os.environ.get("RUNS", "3"))
BATCH = int(os.environ.get("BATCH", "4096"))
FRAMES = 50

ORT_SNIPPET = """
import sys, numpy as np, onnxruntime as ort
model, src, threads, batch = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
o = ort.SessionOptions()
o.intra_op_num_threads = threads
o.inter_op_num_threads = 1
o.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
s = ort.InferenceSession(model, o, providers=["CPUExecutionProvider"])
inputs = [i.name for i in s.get_inputs()]
k = int(s.get_modelmeta().custom_metadata_map.get("dem.uniform_count", 0))
rng = np.random.default_rng(1)
x = np.load(src)
steps = len(x) // batch
state = np.zeros((batch, 20, 5, 4), np.float32)
motion = np.tile(np.array([[0.05, 0.0, 0.02, 0.1]], np.float32), (batch, 1))
for i in range(steps):
    feed = {"dem": x[i * batch:(i + 1) * batch]}
    feed["uniform"] = (rng.integers(0, 1 << 24, size=(batch, k)) / (1 << 24)).astype(np.float32)
    if "time" in inputs:
        feed["time"] = np.full(batch, 0.1 * (i % 50), np.float32)
    if "state" in inputs:
        feed.update(state=state, motion=motion, reset=np.full(batch, 1.0 if i == 0 else 0.0, np.float32))
        y, state = s.run(["dem_out", "state_out"], feed)
    else:
        y = s.run(["dem_out"], feed)[0]
print(steps * batch)
"""


def make_input(src, labels, n):
    sim, real = np.load("testdata/sim.npy"), np.load("testdata/real.npy")
    both = np.concatenate([sim, real])
    np.save(src, np.tile(both, (-(-n // len(both)), 1, 1, 1))[:n])
    with open(labels, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["index", "terrain", "x", "y", "yaw", "sequence", "time"])
        for i in range(n):
            run, k = divmod(i, FRAMES)
            w.writerow([i, "flat", f"{0.05 * k:.4f}", "0.0", f"{0.02 * k:.4f}", run, f"{0.1 * k:.2f}"])


def wall(cmd):
    t = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed with exit {p.returncode}: {p.stderr.decode(errors='replace')}")
    return time.perf_counter() - t


def main():
    src, labels = os.path.join(OUT, "state_in.npy"), os.path.join(OUT, "state_labels.csv")
    make_input(src, labels, RECORDS)
    models = {"stateless": os.path.join(OUT, "state_off.onnx"), "map-memory": os.path.join(OUT, "state_on.onnx")}
    dst = os.path.join(OUT, "state_out.npy")
    cmds = {}
    for name, model in models.items():
        cmds[("dem-apply", name)] = [os.path.join(BIN, "dem-apply"), "--model", model, "--threads", str(THREADS),
                                      "--labels", labels, src, "-o", dst]
        cmds[("onnxruntime", name)] = [sys.executable, "-c", ORT_SNIPPET, model, src, str(THREADS), str(BATCH)]
    for c in cmds.values():
        wall(c)
    times = {k: [] for k in cmds}
    for _ in range(RUNS):
        for k, c in cmds.items():
            times[k].append(wall(c))
    n_ort = (RECORDS // BATCH) * BATCH
    lines = [f"A map's memory: {RECORDS} records ({n_ort} for onnxruntime: whole batches of {BATCH}), {THREADS} threads, "
             f"median of {RUNS} runs (wall s, process spawn to exit)"]
    for runtime in ("dem-apply", "onnxruntime"):
        off, on = (statistics.median(times[(runtime, m)]) for m in models)
        n = RECORDS if runtime == "dem-apply" else n_ort
        lines.append(f"{runtime:<12} stateless {n / off:>9.0f} records/s   map-memory {n / on:>9.0f} records/s   "
                     f"cost per record {on / off:.2f}x")
    report = "\n".join(lines)
    print(report)
    with open(os.path.join(OUT, "state.txt"), "w") as f:
        f.write(report + "\n")


if __name__ == "__main__":
    main()
