"""Generator inference throughput: dem-apply (native path) against onnxruntime's
Python InferenceSession, same model, same records, same thread count, in
the same run.

Run through scripts/bench/apply.sh (which picks the Python, the binaries and
makes the model). Environment:
  BIN       directory of the release binaries          (default target/release)
  OUT       working directory for files and report     (default .bench)
  MODEL     the ONNX model                             (default OUT/apply_w32.onnx)
  RECORDS   records in the input                       (default 100000)
  THREADS   threads for both                           (default 2)
  RUNS      timed runs of each command                 (default 3)
  BATCHES   batch sizes tried for each, comma-separated (default 64,256,1024)
  REPORT    report file name under OUT                 (default apply.txt)

Fair batches: each contestant first runs a 10,000-record slice of the input
once per batch size in BATCHES (untimed warm-up, then timed), and runs the
comparison with its own fastest. Then, RUNS times in turn (dem-apply,
onnxruntime, dem-apply, ...) so machine drift hits both alike, each as a whole
process, wall-clock from spawn to exit (start-up, model load, NPY read and
write included): records/s = records / wall s, medians quoted with min-max.
onnxruntime runs with intra_op_num_threads = THREADS, inter_op 1, sequential
execution, all graph optimisations; dem-apply with --threads THREADS. The two
outputs are compared value by value afterwards (tolerance 1e-4).
"""

import os
import statistics
import subprocess
import sys
import time

import numpy as np
import onnxruntime as ort

BIN = os.environ.get("BIN", "target/release")
OUT = os.environ.get("OUT", ".bench")
MODEL = os.environ.get("MODEL", os.path.join(OUT, "apply_w32.onnx"))
RECORDS = int(os.environ.get("RECORDS", "100000"))
THREADS = int(os.environ.get("THREADS", "2"))
RUNS = int(os.environ.get("RUNS", "3"))
BATCHES = [int(b) for b in os.environ.get("BATCHES", "64,256,1024").split(",")]
REPORT = os.path.join(OUT, os.environ.get("REPORT", "apply.txt"))
DEM_APPLY = os.path.join(BIN, "dem-apply")

# The peer: what a user would write with onnxruntime's Python API.
ORT_SNIPPET = """
import sys, numpy as np, onnxruntime as ort
model, src, dst, threads, batch = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5])
o = ort.SessionOptions()
o.intra_op_num_threads = threads
o.inter_op_num_threads = 1
o.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
o.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
s = ort.InferenceSession(model, o, providers=["CPUExecutionProvider"])
name, out = s.get_inputs()[0].name, s.get_outputs()[0].name
inputs = [i.name for i in s.get_inputs()]
k = int(s.get_modelmeta().custom_metadata_map.get("dem.uniform_count", 0))
rng = np.random.default_rng(1)
x = np.load(src)
y = np.empty_like(x)
for i in range(0, len(x), batch):
    feed = {name: x[i:i + batch]}
    n = len(feed[name])
    if "uniform" in inputs:  # a virtual sensor: fresh 24-bit draws per call, as dem-apply's
        feed["uniform"] = (rng.integers(0, 1 << 24, size=(n, k)) / (1 << 24)).astype(np.float32)
    if "time" in inputs:
        feed["time"] = np.full(n, np.nan, np.float32)
    y[i:i + batch] = s.run([out], feed)[0]
np.save(dst, y)
"""


def make_input(path, n):
    """n records: the bundled sim and measured records in turn, tiled."""
    if os.path.exists(path) and os.path.getsize(path) == 128 + n * 840:
        return
    sim, real = np.load("testdata/sim.npy"), np.load("testdata/real.npy")
    both = np.concatenate([sim, real])
    reps = -(-n // len(both))
    np.save(path, np.tile(both, (reps, 1, 1, 1))[:n])


def wall(cmd):
    t = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    w = time.perf_counter() - t
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed with exit {p.returncode}: {p.stderr.decode(errors='replace')}")
    return w


def dem_apply(src, dst, batch):
    return [DEM_APPLY, "--model", MODEL, "--threads", str(THREADS), "--batch", str(batch), src, "-o", dst]


def onnxruntime(src, dst, batch):
    return [sys.executable, "-c", ORT_SNIPPET, MODEL, src, dst, str(THREADS), str(batch)]


def best_batch(make_cmd, src, dst):
    times = {}
    for b in BATCHES:
        wall(make_cmd(src, dst, b))
        times[b] = wall(make_cmd(src, dst, b))
    return min(times, key=times.get), times


def main():
    os.makedirs(OUT, exist_ok=True)
    src = os.path.join(OUT, "apply_in.npy")
    small = os.path.join(OUT, "apply_in_10k.npy")
    make_input(src, RECORDS)
    make_input(small, 10_000)
    outs = {"dem-apply": os.path.join(OUT, "apply_out_tract.npy"),
            "onnxruntime": os.path.join(OUT, "apply_out_ort.npy")}
    makers = {"dem-apply": dem_apply, "onnxruntime": onnxruntime}
    batch, sweep = {}, {}
    for name, make in makers.items():
        batch[name], sweep[name] = best_batch(make, small, outs[name])
    walls = {name: [] for name in makers}
    for i in range(RUNS + 1):  # run 0 warms the page cache and is not counted
        for name, make in makers.items():
            w = wall(make(src, outs[name], batch[name]))
            if i > 0:
                walls[name].append(w)
    a, b = np.load(outs["dem-apply"]), np.load(outs["onnxruntime"])
    sensor = "uniform" in [i.name for i in ort.InferenceSession(MODEL, providers=["CPUExecutionProvider"]).get_inputs()]
    if sensor:
        # Each drew its own uniforms: the same distribution, not the same values.
        va, vb = (a[:, :20, :, 1] > 0).mean(), (b[:, :20, :, 1] > 0).mean()
        diff = abs(va - vb)
        if not diff <= 0.005:
            sys.exit(f"outputs differ: valid cells {va:.4f} (dem-apply) against {vb:.4f} (onnxruntime)")
        check = f"valid cells {va:.4f} (dem-apply) and {vb:.4f} (onnxruntime), each with its own draws"
    else:
        diff = float(np.abs(a - b).max())
        if not diff <= 1e-4:
            sys.exit(f"outputs differ: max |dem-apply - onnxruntime| = {diff}")
        check = f"max |dem-apply - onnxruntime| = {diff:.2e} (tolerance 1e-4)"

    med = {k: statistics.median(v) for k, v in walls.items()}
    lines = [
        f"{'The whole virtual sensor' if sensor else 'Generator inference'}, model {MODEL}, {RECORDS} records, {THREADS} threads each; "
        f"whole-process wall, median of {RUNS} runs in turn after a warm-up",
        "",
        f"{'command':<14} {'batch':>6} {'wall s':>8} {'(min-max)':>13} {'records/s':>10}",
    ]
    for name in makers:
        spread = f"{min(walls[name]):.2f}-{max(walls[name]):.2f}"
        lines.append(f"{name:<14} {batch[name]:>6} {med[name]:>8.2f} {spread:>13} {RECORDS / med[name]:>10.0f}")
    lines += [
        "",
        f"dem-apply / onnxruntime throughput: {med['onnxruntime'] / med['dem-apply']:.2f}x "
        "(above 1 = dem-apply faster)",
        f"pairwise (run i against run i): "
        + ", ".join(f"{o / d:.2f}x" for d, o in zip(walls["dem-apply"], walls["onnxruntime"])),
        "batch sweep on 10,000 records (wall s): "
        + "; ".join(f"{n} " + ", ".join(f"{b}: {t:.2f}" for b, t in sweep[n].items()) for n in makers),
        check,
        f"dem-apply = {DEM_APPLY}; python {sys.version.split()[0]}, onnxruntime {ort.__version__}, "
        f"numpy {np.__version__}, {os.cpu_count()} cores",
    ]
    report = "\n".join(lines) + "\n"
    sys.stdout.write(report)
    with open(REPORT, "w") as f:
        f.write(report)
    for p in outs.values():
        os.remove(p)
    print(f"written to {REPORT}")


if __name__ == "__main__":
    main()
