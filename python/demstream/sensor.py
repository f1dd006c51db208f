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

A file whose model has a map's memory (``map-memory``) also takes ``state``
``(N, 20, 5, 4)``, ``motion`` ``(N, 4)`` (dx, dy in m, dyaw in rad since the
environment's last frame, in that frame's axes, and dt, the seconds since
it) and ``reset`` ``(N,)``, and
gives ``state_out``. The sensor keeps each environment's state between
calls: ``reset(ids)`` starts those environments' runs again (their next
frame is a run's first: no memory, and with ``time`` since the reset, the
rows measured maps miss at startup), the others keep their maps. Every
call then takes each environment's ``motion`` since its last step:

    sensor = VirtualSensor("gy-sensor.onnx")
    sensor.reset()                                      # every environment starts a run
    out = sensor(dems, time=t, motion=m, rng=rng)       # one step of every environment
    sensor.reset(done_ids)                              # some episodes end
"""

import numpy as np

__all__ = ["VirtualSensor", "draw_uniform", "draw_uniform_torch", "motion_between"]

_STATE = (20, 5, 4)


def motion_between(a, b, dt):
    """The motion ``(N, 4)`` from poses ``a`` to ``b`` (each ``(N, 3)``: world
    x, y, yaw) ``dt`` seconds later (a number or ``(N,)``): forward and left
    in ``a``'s axes, the turn in (-pi, pi], and dt."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    ex, ey = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    turn = np.remainder(b[:, 2] - a[:, 2], 2 * np.pi)
    turn = np.where(turn > np.pi, turn - 2 * np.pi, turn)
    dt = np.broadcast_to(np.asarray(dt, np.float64), ex.shape)
    return np.stack([c * ex + s * ey, -s * ex + c * ey, turn, dt], axis=1).astype(np.float32)

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
        known = ("dem", "uniform", "time", "state", "motion", "reset")
        if self.inputs[0] != "dem" or any(i not in known for i in self.inputs):
            raise ValueError(f"{path}: inputs {self.inputs}; a dem-tools model takes {', '.join(known)}")
        self.stateful = "state" in self.inputs
        if self.stateful and not {"motion", "reset"} <= set(self.inputs):
            raise ValueError(f"{path}: a state input without motion and reset")
        self.state = None
        self.starting = None
        self.uniform_count = int(self.metadata.get("dem.uniform_count", 0))
        if "uniform" in self.inputs and self.uniform_count <= 0:
            raise ValueError(f"{path}: a uniform input but no dem.uniform_count in its metadata")

    def reset(self, ids=None):
        """Start the runs of environments ``ids`` again (all when ``None``):
        their next frame is a run's first, and the others keep their maps.
        Without a map's memory it does nothing."""
        if self.starting is None:
            return
        if ids is None:
            self.starting[:] = True
        else:
            ids = np.asarray(ids, dtype=np.int64).reshape(-1)
            if ids.size and (ids.min() < 0 or ids.max() >= self.starting.size):
                raise ValueError(f"reset: environment ids must lie in 0..{self.starting.size - 1}, got {ids.min()}..{ids.max()}")
            self.starting[ids] = True

    def __call__(self, dem, time=None, rng=None, uniform=None, motion=None):
        """``dem_out`` for the batch ``dem`` ``(N, 21, 5, 2)``.

        ``time``: seconds into each record's run, ``(N,)`` (``None`` or NaN:
        unknown; startup frames are then drawn at the model's rate).
        ``uniform``: the ``(N, K)`` draws; by default fresh ones from ``rng``
        (a ``numpy.random.Generator``; a new one when ``None``).
        ``motion``: with a map's memory, each environment's ``(dx, dy,
        dyaw, dt)`` since its last frame, ``(N, 4)`` (ignored at a run's first
        frame; ``None``: every environment's first). The batch keeps its
        environments: the first call fixes ``N``, and every environment
        starts its run there.
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
        if not self.stateful:
            return self.session.run(["dem_out"], feeds)[0]
        feeds.update(self._state_feeds(n, motion))
        out, self.state = self.session.run(["dem_out", "state_out"], feeds)
        self.starting[:] = False
        return out

    def over_runs(self, dem, run, pose, time=None, uniform=None):
        """The file's output for records of runs, as dem-apply gives it with
        ``--labels``: ``run`` ``(N,)`` each record's run, ``pose`` ``(N, 3)``
        its world x, y, yaw; each run's records in their order in ``dem``,
        the runs side by side as one batch of environments. Without a map's
        memory, one call; with one, ``time`` (seconds in each run) is needed."""
        dem = np.asarray(dem, dtype=np.float32)
        n = dem.shape[0]
        if not self.stateful:
            return self(dem, time=time, uniform=uniform)
        if time is None:
            raise ValueError("over_runs: a map's memory needs each record's time in its run")
        time = np.asarray(time, np.float32).reshape(n)
        run = np.asarray(run).reshape(n)
        pose = np.asarray(pose, dtype=np.float64).reshape(n, 3)
        order = [np.flatnonzero(run == r) for r in dict.fromkeys(run.tolist())]
        sensor = VirtualSensor.__new__(VirtualSensor)
        sensor.__dict__.update(self.__dict__)
        sensor.state = sensor.starting = None
        out = np.empty_like(dem)
        last = None
        for k in range(max(len(o) for o in order)):
            # A run that has ended repeats its last record; its output is not kept.
            idx = np.array([o[min(k, len(o) - 1)] for o in order])
            feeds = dict(
                time=time[idx],
                uniform=None if uniform is None else np.asarray(uniform, np.float32)[idx],
                # A run that has ended steps on its last record, a moment on.
                motion=None if last is None else motion_between(pose[last], pose[idx], np.maximum(time[idx] - time[last], 1e-3)),
            )
            got = sensor(dem[idx], **feeds)
            live = np.array([k < len(o) for o in order])
            out[idx[live]] = got[live]
            last = idx
        return out

    def _state_feeds(self, n, motion):
        """``state``, ``motion`` and ``reset`` of this step; refuses a batch of
        another size than the environments' or a motion that is not finite."""
        if self.state is None:
            self.state = np.zeros((n,) + _STATE, np.float32)
            self.starting = np.ones(n, dtype=bool)
        if self.state.shape[0] != n:
            raise ValueError(
                f"dem has {n} environments, the sensor keeps {self.state.shape[0]}: one batch of environments per sensor "
                "(make a new VirtualSensor for another batch)"
            )
        if motion is None:
            if not self.starting.all():
                raise ValueError("motion is needed: the sensor keeps its environments' maps (reset() starts every run again)")
            motion = np.zeros((n, 4), np.float32)
        motion = np.ascontiguousarray(motion, dtype=np.float32)
        if motion.shape != (n, 4):
            raise ValueError(f"motion has shape {motion.shape}; need ({n}, 4): dx, dy (m), dyaw (rad), dt (s)")
        bad = np.flatnonzero((~np.isfinite(motion).all(axis=1) | (motion[:, 3] <= 0)) & ~self.starting)
        if bad.size:
            raise ValueError(
                f"environment {bad[0]}: motion {motion[bad[0]].tolist()} (dx, dy in m and dyaw in rad must be finite, "
                "and dt, the seconds since its last frame, > 0)"
            )
        motion = np.where(self.starting[:, None], 0.0, motion).astype(np.float32)
        return {"state": self.state, "motion": motion, "reset": self.starting.astype(np.float32)}
