"""The dem-tools virtual sensor in Python: one ONNX file, any batch.

A file written by ``dem-train export --residual`` (a generator and its
residual sensor model) or ``dem-sensor export`` (a sensor model alone) is
one ONNX graph: ``dem`` float32 ``(N, 21, 5, 2)``, ``uniform`` float32
``(N, K)`` in [0, 1) and ``time`` float32 ``(N,)`` (seconds into the run,
NaN where unknown) in, ``dem_out`` out. ``K`` and the inputs the file has
are in its metadata (``dem.uniform_count``, ``dem.inputs``).

    from demstream.sensor import VirtualSensor
    sensor = VirtualSensor("gy-sensor.onnx")        # onnxruntime, CPU
    rng = np.random.default_rng(0)
    measured_like = sensor(sim_dems, time=t, rng=rng)   # fresh draws per call

Fed the uniforms dem-apply drew (``dem-apply --emit-uniform u.npy``),
``sensor(dems, time=t, uniform=np.load("u.npy"))`` gives dem-apply's output.
"""

import numpy as np

__all__ = ["VirtualSensor", "draw_uniform", "draw_uniform_torch"]

_GRID = 2 ** 24


def draw_uniform(rng, n, k):
    """``(n, k)`` float32 uniforms in [0, 1), 24 bits each, as dem-apply draws."""
    return (rng.integers(0, _GRID, size=(n, k), dtype=np.int64) / _GRID).astype(np.float32)


def draw_uniform_torch(n, k, generator=None, device=None):
    """The same draws as a torch tensor (on ``device``), for a GPU loop."""
    import torch

    x = torch.randint(0, _GRID, (n, k), generator=generator, device=device, dtype=torch.int64)
    return x.to(torch.float32) / _GRID


def _contract(dem):
    """``dem`` as the contract reads it (docs/format.md), as every tool reads
    its input: a NaN height is a missing cell (height 0, mask -1), a NaN
    attitude 0; an infinite value anywhere, or a NaN in a mask, is refused
    naming the environment (the record of the batch) and the cell."""
    bad = np.isinf(dem)
    bad[..., 1] |= np.isnan(dem[..., 1])
    if bad.any():
        i, r, c, ch = (int(v) for v in np.argwhere(bad)[0])
        what = "height" if ch == 0 else ("attitude mask" if r == 20 else "mask")
        raise ValueError(
            f"environment {i}: {dem[i, r, c, ch]} in the {what} at row {r}, column {c}, channel {ch} "
            "(the contract allows no infinite value, and NaN only as a height)"
        )
    if np.isnan(dem).any():
        dem = dem.copy()
        holes = np.isnan(dem[:, :20, :, 0])
        dem[:, :20, :, 1][holes] = -1.0
        dem[:, :20, :, 0][holes] = 0.0
        dem[:, 20, :, 0][np.isnan(dem[:, 20, :, 0])] = 0.0
    return dem


class VirtualSensor:
    """An exported virtual sensor run by onnxruntime on batches of DEMs.

    ``threads`` sets onnxruntime's intra-op threads (default: its own);
    ``providers`` its execution providers (default: CPU).
    """

    def __init__(self, path, providers=None, threads=None):
        import onnxruntime as ort

        options = ort.SessionOptions()
        if threads:
            options.intra_op_num_threads = threads
        self.session = ort.InferenceSession(path, options, providers=providers or ["CPUExecutionProvider"])
        meta = self.session.get_modelmeta()
        self.description = meta.description
        self.metadata = dict(meta.custom_metadata_map)
        self.inputs = [i.name for i in self.session.get_inputs()]
        if self.inputs[0] != "dem" or any(i not in ("dem", "uniform", "time") for i in self.inputs):
            raise ValueError(f"{path}: inputs {self.inputs}; a dem-tools model takes dem, uniform and time")
        self.uniform_count = int(self.metadata.get("dem.uniform_count", 0))
        if "uniform" in self.inputs and self.uniform_count <= 0:
            raise ValueError(f"{path}: a uniform input but no dem.uniform_count in its metadata")

    def __call__(self, dem, time=None, rng=None, uniform=None):
        """``dem_out`` for the batch ``dem`` ``(N, 21, 5, 2)``.

        ``time``: seconds into each record's run, ``(N,)`` (``None`` or NaN:
        unknown; startup frames are then drawn at the model's rate).
        ``uniform``: the ``(N, K)`` draws; by default fresh ones from ``rng``
        (a ``numpy.random.Generator``; a new one when ``None``).
        """
        dem = np.ascontiguousarray(dem, dtype=np.float32)
        if dem.ndim != 4 or dem.shape[1:] != (21, 5, 2):
            raise ValueError(f"dem has shape {dem.shape}; need (N, 21, 5, 2)")
        dem = _contract(dem)
        n = dem.shape[0]
        feeds = {"dem": dem}
        if "uniform" in self.inputs:
            if uniform is None:
                uniform = draw_uniform(rng if rng is not None else np.random.default_rng(), n, self.uniform_count)
            uniform = np.ascontiguousarray(uniform, dtype=np.float32)
            if uniform.shape != (n, self.uniform_count):
                raise ValueError(f"uniform has shape {uniform.shape}; need ({n}, {self.uniform_count})")
            feeds["uniform"] = uniform
        if "time" in self.inputs:
            t = np.full(n, np.nan, np.float32) if time is None else np.ascontiguousarray(time, dtype=np.float32).reshape(n)
            bad = np.flatnonzero(np.isinf(t))
            if bad.size:
                raise ValueError(f"environment {bad[0]}: time {t[bad[0]]} (a time is seconds into the run, or NaN when unknown)")
            feeds["time"] = t
        return self.session.run(["dem_out"], feeds)[0]
