"""NPY stream read + write throughput: dem-cat against numpy, in the same run.

Run through scripts/bench/npy.sh (which picks the Python and the binaries).
Environment:
  BIN      directory of the release binaries      (default target/release)
  OUT      working directory for files and report (default .bench)
  NPY_MB   size of the input file in MB (1e6 B)   (default 500)
  RUNS     timed runs of each command             (default 7)
  NPY_OUT_DIR  where the outputs go               (default OUT; /dev/shm takes
               the disk's writeback out of the figures)

Each command is a whole process, timed wall-clock from spawn to exit:
  numpy    python -c "np.save(out, np.load(in))"  (interpreter + import included;
           its own load+save time is reported too)
  file     dem-cat in.npy -o out.npy
  stream   dem-cat < in.npy | dem-cat > out.npy   (pipe between two processes)
  cat      cat < in.npy | cat > out.npy           (reference: a pipeline of two
           processes over a default 64 KiB pipe; not a contestant)
The page cache cannot be dropped here, so every command runs once untimed
first and the input stays cached for all of them equally. Outputs are deleted
before each run (untimed): replacing a 500 MB file costs the filesystem
~0.1-0.2 s of freeing the old one, in numpy's open(O_TRUNC) as in dem-cat's
rename, which is not I/O throughput. Runs go in turn (numpy, file, stream,
numpy, ...) so machine drift hits all alike; the median is quoted, with the
min-max range (a wide range means a noisy machine).

Peak RSS comes from one extra, untimed run of each command that polls VmHWM
in /proc/<pid>/status every 2 ms. Not ru_maxrss (getrusage/wait4): Linux
carries the parent's RSS high-water mark into a vforked-and-exec'ed child,
so from this Python parent every child would report at least this process's
own peak (~200 MB after making the input). Every output is compared byte for
byte with the input afterwards.
"""

import filecmp
import os
import statistics
import subprocess
import sys
import threading
import time

import numpy as np

BIN = os.environ.get("BIN", "target/release")
OUT = os.environ.get("OUT", ".bench")
DST = os.environ.get("NPY_OUT_DIR", OUT)
MB = float(os.environ.get("NPY_MB", "500"))
RUNS = int(os.environ.get("RUNS", "7"))
DEM_CAT = os.path.join(BIN, "dem-cat")
LIMIT_MB = 100  # streaming goal: a filter holds a chunk, not the file

NUMPY_SNIPPET = """
import sys, time
import numpy as np
t = time.perf_counter()
np.save(sys.argv[2], np.load(sys.argv[1]))
print(time.perf_counter() - t)
"""


def make_input(path, mb):
    """A (N, 21, 5, 2) <f4 file of about `mb` MB from a fixed seed; kept between runs."""
    n = max(1, int(mb * 1e6) // 840)
    want = 128 + n * 840
    if os.path.exists(path) and os.path.getsize(path) == want:
        return n
    rng = np.random.default_rng(0)
    with open(path, "wb") as f:
        # Written in parts, with numpy's own header, so making it needs little memory.
        np.lib.format.write_array_header_1_0(
            f, {"descr": "<f4", "fortran_order": False, "shape": (n, 21, 5, 2)})
        left = n
        while left:
            k = min(left, 100_000)
            f.write(rng.standard_normal((k, 21, 5, 2), dtype=np.float32).tobytes())
            left -= k
    assert os.path.getsize(path) == want
    return n


class PeakRss:
    """Poll VmHWM (peak RSS) of the given processes until they have all exited."""

    def __init__(self, procs):
        self.peak = {p.pid: 0 for p in procs}
        self.thread = threading.Thread(target=self._poll, daemon=True)
        self.thread.start()

    def _poll(self):
        live = set(self.peak)
        while live:
            for pid in list(live):
                try:
                    with open(f"/proc/{pid}/status") as f:
                        text = f.read()
                except OSError:
                    live.discard(pid)
                    continue
                hwm = [line for line in text.splitlines() if line.startswith("VmHWM:")]
                if not hwm:  # a zombie: its memory is gone, the peak is final
                    live.discard(pid)
                    continue
                self.peak[pid] = max(self.peak[pid], int(hwm[0].split()[1]))
            time.sleep(0.002)

    def mb(self, proc):
        self.thread.join()
        return self.peak[proc.pid] / 1024


def run_numpy(src, dst, measure):
    t = time.perf_counter()
    p = subprocess.Popen([sys.executable, "-c", NUMPY_SNIPPET, src, dst],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    rss = PeakRss([p]) if measure else None
    out, err = p.communicate()
    wall = time.perf_counter() - t
    check(p.returncode, "numpy", err)
    return wall, rss and {"numpy": rss.mb(p)}, float(out)


def run_file(src, dst, measure):
    t = time.perf_counter()
    p = subprocess.Popen([DEM_CAT, src, "-o", dst], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    rss = PeakRss([p]) if measure else None
    _, err = p.communicate()
    wall = time.perf_counter() - t
    check(p.returncode, "dem-cat -o", err)
    return wall, rss and {"dem-cat in -o out": rss.mb(p)}, None


def run_stream(src, dst, measure):
    with open(src, "rb") as fin, open(dst, "wb") as fout:
        t = time.perf_counter()
        a = subprocess.Popen([DEM_CAT], stdin=fin, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        b = subprocess.Popen([DEM_CAT], stdin=a.stdout, stdout=fout, stderr=subprocess.DEVNULL)
        a.stdout.close()  # b holds the read end now
        rss = PeakRss([a, b]) if measure else None
        b.wait()
        a.wait()
        wall = time.perf_counter() - t
    check(a.returncode, "dem-cat < in |", b"")
    check(b.returncode, "| dem-cat > out", b"")
    return wall, rss and {"dem-cat < in |": rss.mb(a), "| dem-cat > out": rss.mb(b)}, None


def run_cat(src, dst, measure):
    """Reference: what a two-process pipeline over a default 64 KiB pipe costs here."""
    with open(src, "rb") as fin, open(dst, "wb") as fout:
        t = time.perf_counter()
        a = subprocess.Popen(["cat"], stdin=fin, stdout=subprocess.PIPE)
        b = subprocess.Popen(["cat"], stdin=a.stdout, stdout=fout)
        a.stdout.close()
        b.wait()
        a.wait()
        wall = time.perf_counter() - t
    check(a.returncode or b.returncode, "cat | cat", b"")
    return wall, {}, None


def check(code, what, err):
    if code != 0:
        sys.exit(f"{what} failed with exit {code}: {err.decode(errors='replace')}")


def main():
    os.makedirs(OUT, exist_ok=True)
    os.makedirs(DST, exist_ok=True)
    src = os.path.join(OUT, "npy_in.npy")
    n = make_input(src, MB)
    size = os.path.getsize(src)
    cases = [
        ("numpy", "python: np.save(out, np.load(in))", run_numpy, os.path.join(DST, "npy_out_numpy.npy")),
        ("file", "dem-cat in.npy -o out.npy", run_file, os.path.join(DST, "npy_out_file.npy")),
        ("stream", "dem-cat < in.npy | dem-cat > out.npy", run_stream, os.path.join(DST, "npy_out_stream.npy")),
        ("cat", "  (reference) cat < in.npy | cat > out.npy", run_cat, os.path.join(DST, "npy_out_cat.npy")),
    ]
    walls = {name: [] for name, *_ in cases}
    inner = []
    peaks = {}
    # Run 0 warms the cache; the last one measures memory; neither is timed.
    for i in range(RUNS + 2):
        for name, _, fn, dst in cases:
            if os.path.exists(dst):
                os.remove(dst)
            measure = i == RUNS + 1
            wall, rss, numpy_inner = fn(src, dst, measure)
            if measure:
                peaks.update(rss)
            elif i > 0:
                walls[name].append(wall)
                if numpy_inner is not None:
                    inner.append(numpy_inner)
    for name, _, _, dst in cases:
        if not filecmp.cmp(src, dst, shallow=False):
            sys.exit(f"{name}: output differs from the input")

    med = {k: statistics.median(v) for k, v in walls.items()}
    med_inner = statistics.median(inner)
    rate = lambda s: size / 1e6 / s  # noqa: E731
    lines = [
        f"NPY read + write of one ({n}, 21, 5, 2) <f4 file, {size / 1e6:.0f} MB; "
        f"median of {RUNS} runs after a warm-up, in turn; MB/s = input MB / wall s",
        f"input {src}, outputs in {DST}, dem-cat = {DEM_CAT}",
        "",
        f"{'command':<44} {'wall s':>7} {'(min-max)':>13} {'MB/s':>6} {'vs numpy':>9}",
    ]
    for name, label, _, _ in cases:
        spread = f"{min(walls[name]):.2f}-{max(walls[name]):.2f}"
        lines.append(f"{label:<44} {med[name]:>7.3f} {spread:>13} {rate(med[name]):>6.0f} "
                     f"{med['numpy'] / med[name]:>8.2f}x")
    spread = f"{min(inner):.2f}-{max(inner):.2f}"
    lines.append(f"{'  numpy load+save alone (no python startup)':<44} "
                 f"{med_inner:>7.3f} {spread:>13} {rate(med_inner):>6.0f} {med['numpy'] / med_inner:>8.2f}x")
    lines += [
        "",
        "vs numpy = numpy's whole-process wall / this wall (above 1 = faster than numpy)",
        f"dem-cat -o vs numpy load+save alone: {med_inner / med['file']:.2f}x; "
        f"stream vs numpy load+save alone: {med_inner / med['stream']:.2f}x",
        f"best run vs numpy's best run (numpy's wide spread is kernel time; it maps "
        f"{size / 1e6:.0f} MB afresh each run): "
        f"dem-cat -o {min(walls['numpy']) / min(walls['file']):.2f}x, "
        f"stream {min(walls['numpy']) / min(walls['stream']):.2f}x",
        "",
        "peak RSS (VmHWM of each process, one untimed run):",
    ]
    for k, v in peaks.items():
        verdict = ""
        if k.startswith(("dem-cat <", "| dem-cat")):
            verdict = f"  (streaming goal < {LIMIT_MB} MB: {'met' if v < LIMIT_MB else 'NOT MET'})"
        lines.append(f"  {k:<20} {v:>7.1f} MB{verdict}")
    lines.append("")
    lines.append(f"python {sys.version.split()[0]}, numpy {np.__version__}, {os.cpu_count()} cores")
    report = "\n".join(lines) + "\n"
    sys.stdout.write(report)
    with open(os.path.join(OUT, "npy.txt"), "w") as f:
        f.write(report)
    for _, _, _, dst in cases:
        os.remove(dst)
    print(f"written to {os.path.join(OUT, 'npy.txt')} (input kept: {src})")


if __name__ == "__main__":
    main()
