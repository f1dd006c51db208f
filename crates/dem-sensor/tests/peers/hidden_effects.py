"""Make "real" data in which known measurement effects are hidden: apply the
effects of docs/format.md to sim DEMs, implemented here from the spec's
formulas with numpy, independently of the Rust sensor/fitting code (its own
random draws, its own loops), so dem-gap's tests check the fitter against
data it did not make.

usage: python hidden_effects.py SIM.npy OUT.npy SEED EFFECT [EFFECT ...] [--labels LABELS.csv]
EFFECT: name:param=value,param=value   e.g. noise:sigma0=0.004,k=0.012
Effects are applied in the order given. Record i of OUT is record i of SIM
(identity pairing). map-memory, last, steps each run of LABELS.csv
(sequence, time, x, y, yaw) in file order; without labels it does nothing.

Definitions (x of row r = -0.55 + 0.1 r, y of column c = (2 - c) 0.1,
heights relative to the robot centre; missing = mask -1, height 0):
  noise        h += N(0, s^2), s = sigma0 + k d^2, d = distance from
               (x, y, z) = (0.15, 0, 0.45) to (x_r, y_c, h)
  dropout      each valid cell missing with probability p
  row-dropout  each row wholly missing with probability p
  occlusion    per column, sensor at (x0, h): a cell is hidden when the line
               to the far edge of its top passes more than 1 cm below the top
               of a valid cell between them (tops are 10 cm wide), or when
               its top is more than 1 cm above the sensor and its valid
               neighbour toward the sensor is not more than 1 cm lower
  fov          rows whose centre x is outside [x_min, x_max] missing
  smoothing    3x3 kernel, centre weight w, neighbours (1-w)/8, valid only,
               normalised by the weights used
  bias         h += b + t x
  quantization h = q * floor(h / q + 0.5)
  startup      with probability p the record is a startup frame: rows with
               centre x < x0 - u (x0 + 0.6), u uniform, missing (the
               per-record form, used without times; v is ignored here)
  patch-dropout  each of 8 slots holds a blob with probability n / 8, centre
               uniform over the grid's rectangle widened by r; a cell's
               quarter-cell centres (x +- 2.5 cm, y +- 2.5 cm) within r of a
               centre are covered: 3 or 4 covered, the cell is missing; 1 or
               2, h += a (h_low - h), h_low the lowest of h and its
               x-neighbours the blobs leave valid (a defaults to 0)
  edge-holes   a valid cell with a valid 4-neighbour more than g higher is
               missing with probability p
  rim-holes    a valid cell with a valid 4-neighbour more than g lower is
               missing with probability p
  pit-fill     a valid cell more than g below both valid neighbours along x
               (rows r-1, r+1) or along y (columns c-1, c+1) reads the lower of
               the two with probability p (the higher such rim when both lines
               qualify)
  view-top     cells whose point, turned back by the record's pitch (row
               20, column 0) into the body's frame, lies above h - t x
               missing
  hole-growth  a valid cell with k missing 4-neighbours (inside the grid)
               is missing with probability 1 - (1 - p)^k, k counted before
               any cell is removed
  drop-blend   at a drop along x (valid rows r and r + 1, row r + 1 lower by
               more than 5 cm) each of the two cells, with probability p,
               reads h + u a (h_other - h), u uniform; a cell between two
               drops takes the larger (the one ahead on a tie)
  riser-blend  at a riser along x (valid rows r and r + 1, row r + 1 higher
               by more than 5 cm) the cell at its foot reads h + u foot
               (h_other - h), the cell on its top h + u top (h_other - h),
               u uniform; a cell beside two risers takes the larger step
               (the one ahead on a tie)
  floor-lift     in rows whose centre x < x, a valid cell whose valid neighbour
               behind (row r - 1) is higher by more than 5 cm reads, with
               probability p, h + min(1, u a) (h_behind - h), u uniform
  drop-holes   at a drop along x (valid rows r and r + 1, row r + 1 lower by
               more than 5 cm), with probability p one of the two cells (the
               lip or the floor, equal chances) is missing; drops are found
               before any cell is removed
  mixed-cells  a cell is the mean of its back and front halves (centres 2.5
               cm and 7.5 cm from each boundary); at a boundary between
               valid x-neighbours more than 5 cm apart the step lies at s,
               uniform in [-5, 5] cm past the boundary into the lower cell,
               and the higher surface reaches s + e into it, e = u up (higher
               cell ahead) or u down (higher cell behind), u uniform: each
               half of the lower cell whose centre that reaches reads the
               higher height; each half of the higher cell whose centre
               -(s + e) reaches reads the lower height (a raise wins)
  tilt         per record a = pitch z1, b = roll z2 (standard normals):
               h += a (range + max(x, x0) - x0) + b y
  shake        per record s = sigma + edge J, J the largest |height step|
               between valid x-neighbours in rows 2..9 (|x| <= 0.35 m),
               capped at 0.5 m (0 if none); a = s z1, b = s z2:
               h += a x + b y
  step-jitter  per record s = sigma + edge J (J as in shake); per cell dx =
               clip(s z, -0.1, 0.1), z a standard normal: h += dx (h(r + 1)
               - h(r - 1)) / 0.2, a neighbour missing or outside the grid
               read as the cell's own height
  lag          per record s_r = s (1 + spread (2u - 1)), u uniform;
               h'(x) = h(x - s_r) + s_r tan(pitch), pitch = row 20, column
               0, clamped to +-1 rad; linear interpolation between the two
               row centres around x - s_r, a row outside the grid or missing
               read as the cell's own height; validity kept
  map-memory   per run, frame after frame: the last frame's output and
               input grids moved by the robot's motion (from the labels'
               poses, in the last frame's axes): cell (r, c) of the new
               frame is at (x, y) = R(dyaw) (x_r, y_c) + (dx, dy) in the
               last one; valid where the last frame's nearest cell is,
               its height the bilinear mean of the valid cells of the
               four around it. dz = mean over cells valid in the moved
               last input and the input of (moved last input - input).
               With m the moved last output - dz, f this frame and dt
               the seconds since the last: both valid: m + (1 -
               exp(-dt/tau)) (f - m); f only: f; m only: m with
               probability exp(-dt/keep), else missing (tau or keep 0:
               the frame's)
  drift        rows with centre x < x0 displaced: going back from the last
               such row, dx and dz are cumulative sums of normals of sd
               rate sqrt(0.1) and zrate sqrt(0.1) per row (one of each per
               row); h'(x) = h(x - dx) + dz interpolated as in lag (shifts
               clamped to +-1 m)
"""
import sys
import numpy as np

X = -0.55 + 0.1 * np.arange(20)
Y = (2 - np.arange(5)) * 0.1


def parse(spec):
    name, _, rest = spec.partition(":")
    params = {}
    for kv in filter(None, rest.split(",")):
        k, v = kv.split("=")
        params[k] = float(v)
    return name, params


def noise(d, rng, sigma0, k):
    h, valid = d[:20, :, 0].astype(np.float64), d[:20, :, 1] > 0
    dist2 = (X[:, None] - 0.15) ** 2 + Y[None, :] ** 2 + (h - 0.45) ** 2
    h = h + (sigma0 + k * dist2) * rng.standard_normal((20, 5))
    d[:20, :, 0] = np.where(valid, h, d[:20, :, 0])


def record_pitch(d):
    """The record's pitch (row 20, column 0) clamped to +-1 rad, 0 when not finite."""
    pitch = float(d[20, 0, 0])
    return float(np.clip(pitch, -1.0, 1.0)) if np.isfinite(pitch) else 0.0


def set_missing(d, sel):
    d[:20, :, 0][sel] = 0.0
    d[:20, :, 1][sel] = -1.0


def dropout(d, rng, p):
    set_missing(d, (rng.random((20, 5)) < p) & (d[:20, :, 1] > 0))


def row_dropout(d, rng, p):
    set_missing(d, np.repeat((rng.random(20) < p)[:, None], 5, axis=1))


def occlusion(d, rng, h, x0):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    hide = np.zeros((20, 5), bool)
    for c in range(5):
        for t in range(20):
            if not valid[t, c] or abs(X[t] - x0) <= 0.05:
                continue
            # a top above the sensor is seen only where it holds the face
            # toward the sensor (its near neighbour is lower)
            near = t - 1 if X[t] > x0 else t + 1
            if z[t, c] > h + 0.01 and 0 <= near < 20 and valid[near, c] and z[near, c] > z[t, c] - 0.01:
                hide[t, c] = True
                continue
            xf = X[t] + (0.05 if X[t] > x0 else -0.05)
            lo_x, hi_x = min(x0, xf), max(x0, xf)
            for b in range(20):
                if b == t or not valid[b, c]:
                    continue
                # only cells between the sensor and the target
                if (X[t] > x0 and b > t) or (X[t] < x0 and b < t):
                    continue
                a, e = max(X[b] - 0.05, lo_x), min(X[b] + 0.05, hi_x)
                if a >= e:
                    continue
                line = lambda x: h + (z[t, c] - h) * (x - x0) / (xf - x0)
                if z[b, c] > min(line(a), line(e)) + 0.01:
                    hide[t, c] = True
                    break
    set_missing(d, hide)


def fov(d, rng, x_min, x_max):
    out = (X < x_min) | (X > x_max)
    set_missing(d, np.repeat(out[:, None], 5, axis=1))


def smoothing(d, rng, w):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    zp = np.pad(np.where(valid, z, 0.0), 1)
    vp = np.pad(valid.astype(np.float64), 1)
    s = np.zeros((20, 5))
    n = np.zeros((20, 5))
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr == 0 and dc == 0:
                continue
            s += zp[1 + dr:21 + dr, 1 + dc:6 + dc]
            n += vp[1 + dr:21 + dr, 1 + dc:6 + dc]
    wn = (1 - w) / 8
    out = (w * z + wn * s) / (w + wn * n)
    d[:20, :, 0] = np.where(valid, out, d[:20, :, 0])


def bias(d, rng, b, t):
    valid = d[:20, :, 1] > 0
    d[:20, :, 0] = np.where(valid, d[:20, :, 0] + (b + t * X)[:, None], d[:20, :, 0])


def quantization(d, rng, q):
    valid = d[:20, :, 1] > 0
    hq = q * np.floor(d[:20, :, 0].astype(np.float64) / q + 0.5)
    d[:20, :, 0] = np.where(valid, hq, d[:20, :, 0])


def startup(d, rng, x0, p, v=0.0):
    u1, u2 = rng.random(2)
    if u1 < p:
        edge = x0 - u2 * (x0 + 0.6)
        set_missing(d, np.repeat((X < edge)[:, None], 5, axis=1))


def patch_dropout(d, rng, n, r, a=0.0):
    xlo, xhi, ylo, yhi = X[0] - 0.05, X[-1] + 0.05, Y[-1] - 0.05, Y[0] + 0.05
    blobs = []
    for u, s, t in rng.random((8, 3)):
        if u < n / 8:
            blobs.append((xlo - r + s * (xhi - xlo + 2 * r), ylo - r + t * (yhi - ylo + 2 * r)))
    if not blobs:
        return
    # How many of each cell's four quarter-cell centres no blob covers.
    seen = np.zeros((20, 5), int)
    for sx in (-1, 1):
        for sy in (-1, 1):
            qx, qy = (X + sx * 0.025)[:, None], (Y + sy * 0.025)[None, :]
            cov = np.zeros((20, 5), bool)
            for px, py in blobs:
                cov |= (qx - px) ** 2 + (qy - py) ** 2 <= r * r
            seen += ~cov
    z = d[:20, :, 0].astype(np.float64)
    left = (d[:20, :, 1] > 0) & (seen >= 2)
    # The lowest of h and its x-neighbours the blobs leave valid.
    zn = np.pad(np.where(left, z, np.inf), ((1, 1), (0, 0)), constant_values=np.inf)
    low = np.minimum(z, np.minimum(zn[:-2], zn[2:]))
    part = left & (seen < 4)
    d[:20, :, 0] = np.where(part, z + a * (low - z), d[:20, :, 0])
    set_missing(d, (d[:20, :, 1] > 0) & ~left)


def edge_holes(d, rng, g, p):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    zp = np.pad(np.where(valid, z, -np.inf), 1, constant_values=-np.inf)
    jump = np.zeros((20, 5), bool)
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        jump |= zp[1 + dr:21 + dr, 1 + dc:6 + dc] - z > g
    set_missing(d, jump & valid & (rng.random((20, 5)) < p))


def rim_holes(d, rng, g, p):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    zp = np.pad(np.where(valid, z, np.inf), 1, constant_values=np.inf)
    jump = np.zeros((20, 5), bool)
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        jump |= z - zp[1 + dr:21 + dr, 1 + dc:6 + dc] > g
    set_missing(d, jump & valid & (rng.random((20, 5)) < p))


def pit_fill(d, rng, g, p):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    zp = np.pad(np.where(valid, z, -np.inf), 1, constant_values=-np.inf)
    rims = []
    for (a, b) in (((-1, 0), (1, 0)), ((0, -1), (0, 1))):
        lo = np.minimum(zp[1 + a[0]:21 + a[0], 1 + a[1]:6 + a[1]], zp[1 + b[0]:21 + b[0], 1 + b[1]:6 + b[1]])
        rims.append(np.where(lo - z > g, lo, -np.inf))
    rim = np.maximum(*rims)
    fill = valid & np.isfinite(rim) & (rng.random((20, 5)) < p)
    d[:20, :, 0] = np.where(fill, rim, d[:20, :, 0])


def hole_growth(d, rng, p):
    missing = np.pad(d[:20, :, 1] <= 0, 1, constant_values=False)
    k = sum(missing[1 + dr:21 + dr, 1 + dc:6 + dc].astype(int) for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)))
    lose = rng.random((20, 5)) < 1.0 - (1.0 - p) ** k
    set_missing(d, lose & (d[:20, :, 1] > 0))


def drop_blend(d, rng, p, a):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    step = np.zeros((20, 5))
    for r in range(20):
        for c in range(5):
            if not valid[r, c]:
                continue
            cands = []
            if r + 1 < 20 and valid[r + 1, c] and z[r, c] - z[r + 1, c] > 0.05:
                cands.append(z[r + 1, c] - z[r, c])
            if r > 0 and valid[r - 1, c] and z[r - 1, c] - z[r, c] > 0.05:
                cands.append(z[r - 1, c] - z[r, c])
            if cands:
                step[r, c] = max(cands, key=abs)  # the first (ahead) on a tie
    u, v = rng.random((20, 5)), rng.random((20, 5))
    blend = (step != 0) & (u < p)
    d[:20, :, 0] = np.where(blend, z + v * a * step, d[:20, :, 0])


def floor_lift(d, rng, x, p, a):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    edge = np.zeros((20, 5))
    edge[1:] = z[:-1] - z[1:]
    beyond = valid & np.vstack([np.zeros((1, 5), bool), valid[:-1]]) & (edge > 0.05) & (X < x)[:, None]
    u, v = rng.random((20, 5)), rng.random((20, 5))
    d[:20, :, 0] = np.where(beyond & (u < p), z + np.minimum(1.0, v * a) * edge, d[:20, :, 0])


def drop_holes(d, rng, p):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    drop = valid[:-1] & valid[1:] & (z[:-1] - z[1:] > 0.05)
    lose = drop & (rng.random((19, 5)) < p)
    lip = rng.random((19, 5)) < 0.5
    gone = np.zeros((20, 5), bool)
    gone[:-1] |= lose & lip
    gone[1:] |= lose & ~lip
    set_missing(d, gone)


def view_top(d, rng, h, t):
    # Each cell's point turned back by the pitch into the body's frame,
    # there compared with the level top ray.
    p = record_pitch(d)
    z = d[:20, :, 0].astype(np.float64)
    x = np.broadcast_to(X[:, None], z.shape)
    xb, zb = x * np.cos(p) + z * np.sin(p), -x * np.sin(p) + z * np.cos(p)
    valid = d[:20, :, 1] > 0
    set_missing(d, valid & (zb > h - t * xb))


def mixed_cells(d, rng, up, down):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    halves = np.repeat(z[:, :, None], 2, axis=2)  # [..., 0] back, [..., 1] front
    raised = np.zeros((20, 5, 2), bool)
    for b in range(19):
        s = rng.uniform(-0.05, 0.05)
        for c in range(5):
            e = rng.random()
            if not (valid[b, c] and valid[b + 1, c]) or abs(z[b + 1, c] - z[b, c]) <= 0.05:
                continue
            if z[b + 1, c] > z[b, c]:  # riser ahead: row b is the lower cell, its front half touches
                lo, lo_near, hi, hi_near, reach = b, 1, b + 1, 0, s + e * up
            else:  # drop ahead: row b + 1 is lower, its back half touches
                lo, lo_near, hi, hi_near, reach = b + 1, 0, b, 1, s + e * down
            zlo, zhi = min(z[b, c], z[b + 1, c]), max(z[b, c], z[b + 1, c])
            for dist, h in ((0.025, lo_near), (0.075, 1 - lo_near)):
                if reach > dist:
                    halves[lo, c, h] = zhi if not raised[lo, c, h] else max(halves[lo, c, h], zhi)
                    raised[lo, c, h] = True
            for dist, h in ((0.025, hi_near), (0.075, 1 - hi_near)):
                if -reach > dist and not raised[hi, c, h]:
                    halves[hi, c, h] = min(halves[hi, c, h], zlo)
    d[:20, :, 0] = np.where(valid, halves.mean(axis=2), d[:20, :, 0])


def riser_blend(d, rng, foot, top):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    step, share = np.zeros((20, 5)), np.zeros((20, 5))
    for r in range(20):
        for c in range(5):
            if not valid[r, c]:
                continue
            cands = []
            if r + 1 < 20 and valid[r + 1, c] and z[r + 1, c] - z[r, c] > 0.05:
                cands.append((z[r + 1, c] - z[r, c], foot))
            if r > 0 and valid[r - 1, c] and z[r, c] - z[r - 1, c] > 0.05:
                cands.append((z[r - 1, c] - z[r, c], top))
            if cands:
                step[r, c], share[r, c] = max(cands, key=lambda t: abs(t[0]))
    u = rng.random((20, 5))
    d[:20, :, 0] = np.where(step != 0, z + u * share * step, d[:20, :, 0])


def _read_at(z, valid, r, c, p):
    """Height of column c read at x = p (linear between row centres; a row
    outside the grid or missing reads cell (r, c)'s own height)."""
    k = int(np.floor((p - X[0]) / 0.1 + 1e-9))
    w = (p - (X[0] + 0.1 * k)) / 0.1
    w = min(max(w, 0.0), 1.0)
    own = z[r, c]

    def val(j):
        return z[j, c] if 0 <= j < 20 and valid[j, c] else own

    return (1 - w) * val(k) + w * val(k + 1)


def _shift(d, dx, dz):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    out = z.copy()
    for r in range(20):
        for c in range(5):
            if valid[r, c]:
                p = X[r] - np.clip(dx[r], -1.0, 1.0)
                out[r, c] = _read_at(z, valid, r, c, p) + dz[r]
    d[:20, :, 0] = np.where(valid, out, d[:20, :, 0])


def _plane(d, a, b, lever):
    valid = d[:20, :, 1] > 0
    h = d[:20, :, 0].astype(np.float64) + a * lever[:, None] + b * Y[None, :]
    d[:20, :, 0] = np.where(valid, h, d[:20, :, 0])


def tilt(d, rng, pitch, roll, x0, range):
    z1, z2 = rng.standard_normal(2)
    _plane(d, pitch * z1, roll * z2, range + np.maximum(X, x0) - x0)


def _step_under_tracks(d):
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    both = valid[2:9] & valid[3:10]
    steps = np.abs(z[3:10] - z[2:9])[both]
    return min(steps.max(), 0.5) if steps.size else 0.0


def shake(d, rng, sigma, edge):
    z1, z2 = rng.standard_normal(2)
    s = sigma + edge * _step_under_tracks(d)
    _plane(d, s * z1, s * z2, X)


def step_jitter(d, rng, sigma, edge):
    s = sigma + edge * _step_under_tracks(d)
    dx = np.clip(s * rng.standard_normal((20, 5)), -0.1, 0.1)
    z = d[:20, :, 0].astype(np.float64)
    valid = d[:20, :, 1] > 0
    ahead, behind = z.copy(), z.copy()
    ahead[:-1] = np.where(valid[1:], z[1:], z[:-1])
    behind[1:] = np.where(valid[:-1], z[:-1], z[1:])
    h = z + dx * (ahead - behind) / 0.2
    d[:20, :, 0] = np.where(valid, h, d[:20, :, 0])


def lag(d, rng, s, spread):
    sr = s * (1 + spread * (2 * rng.random() - 1))
    climb = sr * np.tan(record_pitch(d))
    _shift(d, np.full(20, sr), np.full(20, climb))


def drift(d, rng, rate, zrate, x0):
    steps = rng.standard_normal((20, 2)) * np.sqrt(0.1) * np.array([rate, zrate])
    behind = X < x0
    dx, dz = np.zeros(20), np.zeros(20)
    for r in range(20):
        if behind[r]:
            dx[r] = steps[r:, 0][behind[r:]].sum()
            dz[r] = steps[r:, 1][behind[r:]].sum()
    _shift(d, dx, dz)


def map_memory(d, rng, tau, keep):
    """A frame alone is a run's first: the map is the frame (the step is map_memory_step)."""


def _moved(grid, fr, fc):
    """grid (20, 5, 2) at fractional cells (fr, fc): (valid, height) by the nearest cell and bilinear weights."""
    rn, cn = int(np.floor(fr + 0.5)), int(np.floor(fc + 0.5))
    if not (0 <= rn < 20 and 0 <= cn < 5) or grid[rn, cn, 1] <= 0:
        return False, 0.0
    r0, c0 = int(np.floor(fr)), int(np.floor(fc))
    num = den = 0.0
    for rr, wr in ((r0, 1 - (fr - r0)), (r0 + 1, fr - r0)):
        for cc, wc in ((c0, 1 - (fc - c0)), (c0 + 1, fc - c0)):
            if 0 <= rr < 20 and 0 <= cc < 5 and grid[rr, cc, 1] > 0:
                num += wr * wc * grid[rr, cc, 0]
                den += wr * wc
    return True, num / den


def map_memory_step(last_out, last_in, d, inp, motion, rng, tau, keep):
    dx, dy, dyaw, dt = motion
    rate = 1.0 if tau == 0 else 1.0 - np.exp(-dt / tau)
    hold = 0.0 if keep == 0 else np.exp(-dt / keep)
    src = {}
    for r in range(20):
        for c in range(5):
            x = np.cos(dyaw) * X[r] - np.sin(dyaw) * Y[c] + dx
            y = np.sin(dyaw) * X[r] + np.cos(dyaw) * Y[c] + dy
            src[r, c] = (x + 0.55) / 0.1, 2 - y / 0.1
    diffs = []
    for (r, c), (fr, fc) in src.items():
        ok, h = _moved(last_in, fr, fc)
        if ok and inp[r, c, 1] > 0:
            diffs.append(h - inp[r, c, 0])
    dz = float(np.mean(diffs)) if diffs else 0.0
    keep = rng.random((20, 5)) < hold
    for (r, c), (fr, fc) in src.items():
        ok, m = _moved(last_out, fr, fc)
        m -= dz
        if d[r, c, 1] > 0 and ok:
            d[r, c, 0] = m + rate * (d[r, c, 0] - m)
        elif d[r, c, 1] <= 0 and ok and keep[r, c]:
            d[r, c] = (m, 1.0)
        elif d[r, c, 1] <= 0:
            d[r, c] = (0.0, -1.0)


def runs_of(labels):
    """Per record: (run, pose) from a labels CSV with sequence, time, x, y, yaw."""
    import csv
    with open(labels) as f:
        return [(r["sequence"], (float(r["x"]), float(r["y"]), float(r["yaw"]), float(r["time"]))) for r in csv.DictReader(f)]


def motion_between(a, b):
    (xa, ya, wa, ta), (xb, yb, wb, tb) = a, b
    ex, ey = xb - xa, yb - ya
    turn = (wb - wa + np.pi) % (2 * np.pi) - np.pi
    return np.cos(wa) * ex + np.sin(wa) * ey, -np.sin(wa) * ex + np.cos(wa) * ey, turn, tb - ta


EFFECTS = {"noise": noise, "dropout": dropout, "row-dropout": row_dropout, "occlusion": occlusion,
           "fov": fov, "smoothing": smoothing, "bias": bias, "quantization": quantization,
           "startup": startup, "patch-dropout": patch_dropout, "edge-holes": edge_holes,
           "mixed-cells": mixed_cells, "rim-holes": rim_holes, "pit-fill": pit_fill, "view-top": view_top,
           "hole-growth": hole_growth, "drop-blend": drop_blend, "riser-blend": riser_blend, "floor-lift": floor_lift,
           "drop-holes": drop_holes, "tilt": tilt, "shake": shake, "step-jitter": step_jitter, "lag": lag, "drift": drift,
           "map-memory": map_memory}


def main():
    args = sys.argv[1:]
    labels = None
    if "--labels" in args:
        i = args.index("--labels")
        labels = args[i + 1]
        args = args[:i] + args[i + 2:]
    sim_path, out_path, seed = args[0], args[1], int(args[2])
    effects = [parse(s) for s in args[3:]]
    memory = dict(effects).get("map-memory")
    sim = np.load(sim_path).astype(np.float32)
    rng = np.random.default_rng(seed)
    out = sim.copy()
    runs = runs_of(labels) if labels and memory is not None else None
    last = {}
    for i, d in enumerate(out):
        for name, params in effects:
            EFFECTS[name](d, rng, **params)
        if runs is not None:
            run, pose = runs[i]
            if run in last:
                was_pose, was_out, was_in = last[run]
                map_memory_step(was_out, was_in, d, sim[i], motion_between(was_pose, pose), rng, **memory)
            last[run] = (pose, d.copy(), sim[i])
    np.save(out_path, out.astype(np.float32))


if __name__ == "__main__":
    main()
