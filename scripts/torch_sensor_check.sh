#!/usr/bin/env bash
# The virtual sensor through PyTorch: every graph dem-sensor export and
# dem-train export write (each effect of testdata/effects.json alone, a model
# of several, a generator with testdata/residual.json) converted with
# onnx2torch and run on the uniforms dem-sensor / dem-apply drew (a graph
# with a map's memory stepped through the labels' runs); their outputs must match (validity on >= 99.99 % of cells, heights within 1e-5 m,
# row 20 untouched). Needs torch and onnx2torch (make venv-torch).
#   TORCH_PY=.venv-torch/bin/python BIN=target/release OUT=.bench scripts/torch_sensor_check.sh
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}/torch_sensor
TORCH_PY=${TORCH_PY:-.venv-torch/bin/python}
CARGO=${CARGO:-cargo}
mkdir -p "$OUT"
SIM=testdata/sim.npy
LABELS=testdata/sim_labels.csv
cases=()
n=$("$TORCH_PY" -c 'import json; d = json.load(open("testdata/effects.json")); print(len(d["every_effect"]))')
for i in $(seq 0 "$n"); do
  "$TORCH_PY" -c "
import json, sys
d = json.load(open('testdata/effects.json'))
e = d['every_effect'][$i:$i + 1] if $i < $n else d['several']
json.dump({'effects': e}, open('$OUT/m$i.json', 'w'))"
  "$BIN/dem-sensor" export --sensor "$OUT/m$i.json" -o "$OUT/m$i.onnx" 2>/dev/null
  "$BIN/dem-sensor" apply --sensor "$OUT/m$i.json" --seed 3 --labels "$LABELS" --emit-uniform "$OUT/u$i.npy" "$SIM" -o "$OUT/o$i.npy" 2>/dev/null
  cases+=("$OUT/m$i.onnx" "$OUT/u$i.npy" "$OUT/o$i.npy")
done
"$CARGO" run -q --release -p dem-onnx --example export_random -- "$OUT/gy.onnx" 8 1 testdata/residual.json
"$BIN/dem-apply" --model "$OUT/gy.onnx" --seed 3 --labels "$LABELS" --emit-uniform "$OUT/ugy.npy" "$SIM" -o "$OUT/ogy.npy" 2>/dev/null
cases+=("$OUT/gy.onnx" "$OUT/ugy.npy" "$OUT/ogy.npy")
"$TORCH_PY" - "$SIM" "$LABELS" "${cases[@]}" <<'PY'
import csv, json, sys, warnings
import numpy as np, onnx, torch
from onnx2torch import convert
warnings.filterwarnings("ignore")
sim, labels, rest = sys.argv[1], sys.argv[2], sys.argv[3:]
dem = torch.from_numpy(np.load(sim))
rows = list(csv.DictReader(open(labels)))
t = torch.from_numpy(np.array([float(r["time"]) for r in rows], dtype=np.float32))
run = np.array([int(r["sequence"]) for r in rows])
pose = np.array([[float(r[k]) for k in ("x", "y", "yaw")] for r in rows])


def motion(a, b, dt):
    """(dx, dy, dyaw, dt) from poses a to b, in a's axes (docs/virtual-sensor.md)."""
    ex, ey = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    turn = np.remainder(b[:, 2] - a[:, 2], 2 * np.pi)
    turn = np.where(turn > np.pi, turn - 2 * np.pi, turn)
    return torch.from_numpy(np.stack([c * ex + s * ey, -s * ex + c * ey, turn, dt], axis=1).astype(np.float32))


def stepped(net, names, feeds):
    """A graph with a map's memory stepped through the labels' runs side by side, as dem-sensor and dem-apply step them."""
    order = [np.flatnonzero(run == r) for r in dict.fromkeys(run.tolist())]
    out = np.empty(tuple(dem.shape), np.float32)
    state, last = torch.zeros((len(order), 20, 5, 4)), None
    for k in range(max(len(o) for o in order)):
        idx = np.array([o[min(k, len(o) - 1)] for o in order])
        step = {n: v[idx] for n, v in feeds.items()}
        tt = t.numpy()
        step["motion"] = torch.zeros((len(idx), 4)) if last is None else motion(pose[last], pose[idx], np.maximum(tt[idx] - tt[last], 1e-3))
        step["reset"] = torch.full((len(idx),), 1.0 if last is None else 0.0)
        step["state"] = state
        with torch.no_grad():
            got, state = net(*[step[n] for n in names])
        live = np.array([k < len(o) for o in order])
        out[idx[live]] = got.numpy()[live]
        last = idx
    return out


bad = 0
print(f"{'model':<28} {'validity differs':>17} {'max height diff':>16}  row 20")
for model, u, out in zip(rest[0::3], rest[1::3], rest[2::3]):
    m = onnx.load(model)
    net = convert(m)
    names = [i.name for i in m.graph.input]
    feeds = {"dem": dem, "uniform": torch.from_numpy(np.load(u)), "time": t}
    if "state" in names:
        got = stepped(net, names, feeds)
    else:
        with torch.no_grad():
            got = net(*[feeds[n] for n in names]).numpy()
    want = np.load(out)
    va, vb = want[:, :20, :, 1] > 0, got[:, :20, :, 1] > 0
    differ = (va != vb).mean()
    worst = float(np.abs(np.where(va & vb, want[:, :20, :, 0] - got[:, :20, :, 0], 0)).max())
    row20 = np.array_equal(want[:, 20], got[:, 20])
    ok = differ <= 1e-4 and worst <= 1e-5 and row20
    bad += not ok
    meta = {p.key: p.value for p in m.metadata_props}
    effects = json.loads(meta["dem.residual"])["effects"]
    if meta.get("dem.graph") == "network+sensor":
        name = f"G_Y + {len(effects)} effects"
    else:
        name = effects[0]["effect"] if len(effects) == 1 else f"{len(effects)} effects"
    print(f"{name[:28]:<28} {100 * differ:>16.4f}% {worst:>16.1e}  {'same' if row20 else 'CHANGED'}{'' if ok else '  FAIL'}")
print(f"torch {torch.__version__}; {len(rest) // 3} graphs, {bad} failed")
sys.exit(1 if bad else 0)
PY
