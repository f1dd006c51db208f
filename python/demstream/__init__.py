"""Read and write the DEM streams of the dem-* tools with numpy.

A stream is one or more complete ``.npy`` arrays of shape ``(n, 21, 5, 2)``
written back to back (``docs/format.md``). ``numpy.load``
reads only the first array, silently: a tool writing to a pipe
(``dem-cat run/sim.npy | cat > x.npy``) writes one array per 4,096 records,
so ``np.load('x.npy')`` returns 4,096 of them. This module reads them all.

    import demstream
    dems = demstream.read("x.npy")              # every record, (N, 21, 5, 2) float32
    dems = demstream.read(sys.stdin.buffer)     # from a pipe
    for chunk in demstream.iter_chunks("big.npy"):
        ...                                     # one array at a time, bounded memory
    demstream.write("out.npy", dems)            # one array, as numpy.save writes it

The contract's input rules apply: float64 is converted to float32, a NaN
height becomes a missing cell (height 0, mask -1), a NaN attitude becomes 0;
an infinite value anywhere or a NaN in a mask or in row 20's channel 1 is
refused (``ValueError`` naming the record). ``write`` refuses NaN and
infinities, as the tools never write them.
"""

import ast
import io
import os

import numpy as np

__all__ = ["read", "iter_chunks", "write", "RECORD_SHAPE"]

RECORD_SHAPE = (21, 5, 2)
_MAGIC = b"\x93NUMPY"


def _open(src):
    """A binary file object and whether we opened it."""
    if isinstance(src, (str, os.PathLike)):
        return open(src, "rb"), True
    return src, False


def _read_exact(f, n):
    parts, got = [], 0
    while got < n:
        b = f.read(n - got)
        if not b:
            break
        parts.append(b)
        got += len(b)
    return b"".join(parts)


def _header(f, name, offset):
    """The next array's (dtype, records, header bytes) or None at a clean end."""
    pre = _read_exact(f, 8)
    if not pre:
        return None
    if len(pre) < 8 or pre[:6] != _MAGIC:
        raise ValueError(f"{name}: byte {offset}: not an NPY array (no \\x93NUMPY magic)")
    major = pre[6]
    if major == 1:
        hlen = int.from_bytes(_read_exact(f, 2), "little")
        plen = 10
    elif major in (2, 3):
        hlen = int.from_bytes(_read_exact(f, 4), "little")
        plen = 12
    else:
        raise ValueError(f"{name}: byte {offset}: unsupported NPY version {major}")
    text = _read_exact(f, hlen)
    if len(text) < hlen:
        raise ValueError(f"{name}: byte {offset}: truncated header")
    d = ast.literal_eval(text.decode("latin1"))
    dtype = np.dtype(d["descr"])
    if dtype not in (np.dtype("<f4"), np.dtype("<f8")):
        raise ValueError(f"{name}: byte {offset}: dtype {d['descr']} is not <f4 or <f8")
    if d.get("fortran_order"):
        raise ValueError(f"{name}: byte {offset}: Fortran order is not accepted")
    shape = tuple(d["shape"])
    if len(shape) != 4 or shape[1:] != RECORD_SHAPE:
        raise ValueError(f"{name}: byte {offset}: shape {shape} is not (n, 21, 5, 2)")
    return dtype, shape[0], plen + hlen


def _canonical(a, name, first):
    """The contract's input rules on a chunk of records (a copy, float32)."""
    a = np.array(a, dtype="<f4")
    bad = np.isinf(a)
    bad[..., 1] |= np.isnan(a[..., 1])
    if bad.any():
        r, row, col, ch = (int(x) for x in np.argwhere(bad)[0])
        raise ValueError(f"{name}: record {first + r}: {a[r, row, col, ch]} at row {row}, column {col}, "
                         f"channel {ch} (the contract allows no infinite value, and NaN only as a height)")
    grid = a[:, :20]
    nan = np.isnan(grid[..., 0])
    grid[..., 0][nan] = 0.0
    grid[..., 1][nan] = -1.0
    att = a[:, 20, :, 0]
    att[np.isnan(att)] = 0.0
    return a


def iter_chunks(src):
    """Yield each array of the stream at ``src`` (a path, ``-`` for stdin, or a
    binary file object such as ``sys.stdin.buffer``) as a float32
    ``(n, 21, 5, 2)`` array, under the contract's input rules."""
    if src == "-":
        import sys
        src = sys.stdin.buffer
    f, owned = _open(src)
    name = getattr(f, "name", "stream")
    try:
        offset, records = 0, 0
        while True:
            h = _header(f, name, offset)
            if h is None:
                return
            dtype, n, hbytes = h
            offset += hbytes
            want = n * 210 * dtype.itemsize
            payload = _read_exact(f, want)
            if len(payload) < want:
                raise ValueError(f"{name}: record {records + len(payload) // (210 * dtype.itemsize)}, "
                                 f"byte {offset + len(payload)}: truncated payload: stream ends {want - len(payload)} bytes early")
            a = np.frombuffer(payload, dtype=dtype).reshape((n,) + RECORD_SHAPE)
            yield _canonical(a, name, records)
            offset += want
            records += n
    finally:
        if owned:
            f.close()


def read(src):
    """Every record of the stream at ``src`` as one float32 (N, 21, 5, 2) array."""
    chunks = list(iter_chunks(src))
    if not chunks:
        return np.zeros((0,) + RECORD_SHAPE, dtype="<f4")
    return np.concatenate(chunks)


def write(dst, records):
    """Write ``records`` (N, 21, 5, 2) to ``dst`` (a path, written to a temp
    file and renamed, or a binary file object) as one array, the bytes
    ``numpy.save`` writes for float32."""
    a = np.ascontiguousarray(records, dtype="<f4")
    if a.ndim != 4 or a.shape[1:] != RECORD_SHAPE:
        raise ValueError(f"shape {a.shape} is not (n, 21, 5, 2)")
    if not np.isfinite(a).all():
        r = int(np.argwhere(~np.isfinite(a))[0][0])
        raise ValueError(f"record {r} holds NaN or an infinity: the contract never writes one")
    if isinstance(dst, (str, os.PathLike)):
        dst = os.fspath(dst)
        d = os.path.dirname(os.path.abspath(dst))
        tmp = os.path.join(d, f".{os.path.basename(dst)}.{os.getpid()}.tmp")
        try:
            with open(tmp, "wb") as f:
                np.save(f, a)
            os.replace(tmp, dst)
        finally:
            if os.path.exists(tmp):
                os.remove(tmp)
    else:
        buf = io.BytesIO()
        np.save(buf, a)
        dst.write(buf.getvalue())
