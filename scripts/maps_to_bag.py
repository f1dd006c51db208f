#!/usr/bin/env python3
"""Turn a `dem-synth --emit-maps` folder into ROS recordings of a tracked
robot running elevation_mapping: grid_map_msgs/GridMap messages, TF and
joint states, as a ROS 1 bag or a ROS 2 recording (MCAP or SQLite), for testing
dem-import.

    maps_to_bag.py DIR --out PATH --format ros1|mcap|db3 [--verify] ...

Reads DIR/maps.npy ((M, 2, n, n) float32: elevation and variance in
grid_map's unwrapped index order) and DIR/maps.csv (window centre and robot
pose per map), and with --verify DIR/real.npy. Writes, for each selected map
(runs of --sequences, in index order; stamp = --stamp0 + 1000 * sequence +
time, exact to the nanosecond):

- the map on --map-topic (grid_map_msgs/GridMap, frame "odom", layers
  elevation + variance, basic layer elevation, centre (center_x, center_y),
  identity orientation), in a circular buffer: message k (k-th map written)
  has outer_start_index (7 k) % n and inner_start_index (3 k) % n, and the
  data as grid_map_ros writes Eigen's default column-major matrices
  (--row-major: row-major); --pad-to N writes every n x n window (n = 80
  from dem-synth) as an N x N map with the same centre, the n x n window in
  its middle and NaN around it in both layers (N - n even; lengths
  N * resolution), so maps are larger (N = 200: 320 KB a message) and the
  DEMs imported from them unchanged (default: no padding);
- /tf: odom -> base_footprint (x, y, 0; yaw about z) and base_footprint ->
  base_link (0, 0, z; pitch about y as -pitch: the data's pitch is nose-up
  positive, ROS's positive rotation about +y points the nose down), each at
  stamp - 0.02 s and stamp + 0.02 s with values offset symmetrically
  (x, y -/+ 0.004 m, yaw -/+ 0.003 rad, z -/+ 0.001 m, pitch -/+ 0.002 rad),
  so interpolation at the map's stamp (linear, slerp) gives the pose;
  /tf_static once: base_link -> camera_link;
- /joint_states at stamp -/+ 0.02 s: the four flippers (-/+ 0.01 rad around
  their value) and two track joints, in a fixed shuffled order.

Receive (bag) time: a map at stamp + 0.05 s, TF and joints at their stamp;
messages are written in receive-time order. Defects for importer tests:
--shuffle-maps swaps the receive times of maps 2m and 2m+1, --tf-late
receives every TF message 0.5 s after its stamp (a map arrives before its
TF), --extra-map-without-tf adds a copy of the first map stamped 30 s
before it, where no TF exists, --damaged-map K cuts the serialized bytes of
the K-th map message written (0-based, in the order maps are written, i.e.
receive-time order; the --extra-map-without-tf copy, written first, counts)
to their first half, as a broken driver or a disk error leaves a message.

ros1: one .bag file (rosbags.rosbag1.Writer; --compression none|bz2|lz4;
each TF link has its own connection on /tf, callerid /odometry and
/robot_state_publisher, as two publishers give). mcap: a rosbag2 folder PATH
holding PATH/metadata.yaml and PATH/<name of PATH>.mcap (rosbags.rosbag2.Writer,
version 9, storage MCAP; --compression zstd compresses the MCAP chunks, lz4
too, through the writer's chunk compressor, none leaves them plain). db3:
the same messages (CDR) in a rosbag2 folder with SQLite storage, as ROS 2
before Iron records by default: PATH/metadata.yaml and PATH/<name of
PATH>.db3 (rosbags' SQLite writer, Python's sqlite3: tables topics and
messages, an index on the timestamp; --compression none).

The message definitions are grid_map's own (ANYbotics/grid_map, ROS 1
master/noetic and ROS 2 humble differ: the header moved from GridMapInfo to
GridMap), registered from .msg text; TF and joint states are rosbags'
built-in types (ROS 1's tf2_msgs/TFMessage is registered from its .msg
text: rosbags' noetic store lacks it). --verify reads the recording back
with rosbags' readers, deserializes every message with types parsed from
the definitions stored in the recording, and checks the maps, stamps,
receive times, TF and joints, and that the importer's rule rebuilds every
real.npy record from the recording alone. With --damaged-map it expects
that one message to fail to deserialize, skips it in the checks, and says so.

Needs numpy and rosbags >= 0.11 (0.10 has no MCAP writer, no Qos type,
and connection definitions as plain strings; tested with 0.11.0 and 0.11.9).

Exit 0 on success, 2 on bad input or usage (nothing written), 1 when the
verification fails or on an internal error (the partial output is removed).
"""

from __future__ import annotations

import argparse
import csv
import math
import shutil
import sys
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path

import numpy as np

try:
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg
except ImportError:  # pragma: no cover
    sys.exit("maps_to_bag.py: needs the rosbags package (pip install 'rosbags>=0.11')")

# grid_map_msgs as ANYbotics/grid_map defines them (comments dropped).
# ROS 1 (branch master, released for noetic): the header is in GridMapInfo.
ROS1_GRID_MAP_INFO = """\
std_msgs/Header header
float64 resolution
float64 length_x
float64 length_y
geometry_msgs/Pose pose
"""
ROS1_GRID_MAP = """\
GridMapInfo info
string[] layers
string[] basic_layers
std_msgs/Float32MultiArray[] data
uint16 outer_start_index
uint16 inner_start_index
"""
# ROS 2 (branches ros2, humble, ...): the header is in GridMap.
ROS2_GRID_MAP_INFO = """\
float64 resolution
float64 length_x
float64 length_y
geometry_msgs/Pose pose
"""
ROS2_GRID_MAP = """\
std_msgs/Header header
GridMapInfo info
string[] layers
string[] basic_layers
std_msgs/Float32MultiArray[] data
uint16 outer_start_index
uint16 inner_start_index
"""
# tf2_msgs/TFMessage (geometry2, noetic); not in rosbags' noetic store.
ROS1_TF_MESSAGE = "geometry_msgs/TransformStamped[] transforms\n"
# The MD5 sums ROS 1 gives these definitions (rosmsg md5).
ROS1_MD5 = {
    "grid_map_msgs/msg/GridMap": "95681e052b1f73bf87b7eb984382b401",
    "tf2_msgs/msg/TFMessage": "94810edda583a504dfda3829e70d7eec",
    "sensor_msgs/msg/JointState": "3066dcd76a6cfaef579bd0f34173e9fd",
}

GRID_MAP = "grid_map_msgs/msg/GridMap"
TF = "tf2_msgs/msg/TFMessage"
JOINTS = "sensor_msgs/msg/JointState"

NS = 1_000_000_000
HALF_GAP_NS = 20_000_000  # TF and joints at stamp -/+ 0.02 s
MAP_DELAY_NS = 50_000_000  # a map is received 0.05 s after its stamp
TF_LATE_NS = 500_000_000  # --tf-late
EXTRA_MAP_BEFORE_NS = 30 * NS  # --extra-map-without-tf
# Symmetric offsets of the two samples around the stamp.
D_XY, D_YAW, D_Z, D_PITCH, D_FLIPPER = 0.004, 0.003, 0.001, 0.002, 0.01
TRACKS = ("left_track_j", "right_track_j")
# Joint order in /joint_states: index into flippers (0..3) or tracks ("L", "R").
JOINT_ORDER = ("L", 3, 0, "R", 1, 2)

CSV_COLUMNS = (
    "index,sequence,time,center_x,center_y,resolution,x,y,z,yaw,pitch,"
    "flipper_fl,flipper_fr,flipper_rl,flipper_rr"
).split(",")


class BadInput(Exception):
    """Bad input or usage: exit 2."""


@dataclass
class MapRow:
    index: int
    sequence: int
    stamp_ns: int
    center_x: float
    center_y: float
    resolution: float
    x: float
    y: float
    z: float
    yaw: float
    pitch: float
    flippers: tuple[float, float, float, float]


def log(msg: str) -> None:
    print(f"maps_to_bag.py: {msg}", file=sys.stderr)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        prog="maps_to_bag.py",
        description="Write a dem-synth --emit-maps folder as a ROS 1 bag or a ROS 2 recording (MCAP or SQLite) "
        "of grid_map_msgs/GridMap, /tf and /joint_states.",
        epilog="Example: maps_to_bag.py run/ --out run.bag --format ros1 --verify",
    )
    p.add_argument("dir", type=Path, help="dem-synth --out folder made with --emit-maps")
    p.add_argument("--out", type=Path, required=True, help="the .bag file (ros1) or rosbag2 folder (mcap, db3) to create")
    p.add_argument("--format", choices=("ros1", "mcap", "db3"), required=True)
    p.add_argument("--sequences", help="runs to write, comma-separated (default: all)")
    p.add_argument("--stamp0", type=int, default=1_700_000_000, help="stamp of run 0 at time 0 (whole seconds)")
    p.add_argument("--compression", choices=("none", "bz2", "lz4", "zstd"), default="none")
    p.add_argument("--row-major", action="store_true", help="row-major Float32MultiArray layout")
    p.add_argument("--shuffle-maps", action="store_true", help="swap the receive times of maps 2m and 2m+1")
    p.add_argument("--tf-late", action="store_true", help="receive TF 0.5 s after its stamp")
    p.add_argument("--extra-map-without-tf", action="store_true", help="add a map 30 s before the first, without TF")
    p.add_argument(
        "--damaged-map",
        type=int,
        metavar="K",
        help="cut the K-th map message written (0-based, the --extra-map-without-tf copy counts) to its first half",
    )
    p.add_argument(
        "--pad-to",
        type=int,
        metavar="N",
        help="write each n x n window as an N x N map, same centre, NaN around it (N - n even; default: no padding)",
    )
    p.add_argument(
        "--crop",
        type=int,
        metavar="N",
        help="write the middle N x N cells of each n x n window (same centre, n - N even), for small maps",
    )
    p.add_argument(
        "--loop-for",
        type=float,
        metavar="SECONDS",
        help="a long recording: the selected maps over and over, one every --loop-dt, for SECONDS",
    )
    p.add_argument("--loop-dt", type=float, default=0.2, metavar="DT", help="seconds between maps with --loop-for (default 0.2: 5 Hz)")
    p.add_argument("--map-topic", default="/elevation_mapping/elevation_map")
    p.add_argument(
        "--flippers",
        default="front_left_flipper_j,front_right_flipper_j,rear_left_flipper_j,rear_right_flipper_j",
        help="joint names of the flippers front-left, front-right, rear-left, rear-right",
    )
    p.add_argument("--verify", action="store_true", help="read the recording back and check it")
    a = p.parse_args(argv)
    a.flippers = a.flippers.split(",")
    if len(a.flippers) != 4 or len(set(a.flippers) | set(TRACKS)) != 6 or not all(a.flippers):
        p.error("--flippers needs four distinct names, other than " + ", ".join(TRACKS))
    if a.sequences is not None:
        try:
            a.sequences = {int(s) for s in a.sequences.split(",")}
        except ValueError:
            p.error(f"--sequences {a.sequences!r} is not a comma-separated list of run indices")
    allowed = {"ros1": ("none", "bz2", "lz4"), "mcap": ("none", "zstd", "lz4"), "db3": ("none",)}[a.format]
    if a.compression not in allowed:
        p.error(f"--compression {a.compression} is not available for {a.format} (one of {', '.join(allowed)})")
    if a.stamp0 < 0:
        p.error("--stamp0 must not be negative")
    if a.damaged_map is not None and a.damaged_map < 0:
        p.error("--damaged-map must not be negative")
    if a.pad_to is not None and not 1 <= a.pad_to <= 65535:
        p.error("--pad-to must be 1 .. 65535 (grid_map's start indices are uint16)")
    if a.crop is not None and (a.crop < 1 or a.pad_to is not None):
        p.error("--crop must be at least 1, and not with --pad-to")
    if a.loop_for is not None:
        if not (a.loop_for > 0 and a.loop_dt * NS > 2 * HALF_GAP_NS and math.isfinite(a.loop_for)):
            p.error(f"--loop-for must be > 0 and --loop-dt > {2 * HALF_GAP_NS / NS} s (the TF samples around a map)")
        if a.verify or a.damaged_map is not None or a.extra_map_without_tf or a.shuffle_maps:
            p.error(
                "--loop-for writes a long recording as it goes: not with --verify, --damaged-map, "
                "--extra-map-without-tf or --shuffle-maps"
            )
    return a


def seconds_to_ns(text: str) -> int:
    """Exact integer nanoseconds of a decimal number of seconds."""
    return int((Decimal(text) * NS).to_integral_value())


def read_maps(
    folder: Path, sequences: set[int] | None, pad_to: int | None = None, crop: int | None = None
) -> tuple[list[MapRow], np.ndarray, int]:
    """The selected rows, maps.npy (memory-mapped) and the size n of the map
    messages (the windows' size, --pad-to or --crop)."""
    csv_path, npy_path = folder / "maps.csv", folder / "maps.npy"
    for f in (csv_path, npy_path):
        if not f.is_file():
            raise BadInput(f"{f} not found (make the folder with dem-synth --emit-maps)")
    try:
        maps = np.load(npy_path, mmap_mode="r")
    except ValueError as e:
        raise BadInput(f"{npy_path}: {e}") from None
    if maps.dtype != np.float32 or maps.ndim != 4 or maps.shape[1] != 2 or maps.shape[2] != maps.shape[3]:
        raise BadInput(f"{npy_path}: expected (M, 2, n, n) float32, got {maps.shape} {maps.dtype}")
    n = maps.shape[2]
    if pad_to is not None and (pad_to < n or (pad_to - n) % 2):
        raise BadInput(f"--pad-to {pad_to}: must be at least the windows' {n} cells, with an even difference (same centre)")
    if crop is not None and (crop > n or (n - crop) % 2):
        raise BadInput(f"--crop {crop}: must be at most the windows' {n} cells, with an even difference (same centre)")
    with csv_path.open(newline="") as f:
        reader = csv.DictReader(f)
        if reader.fieldnames != CSV_COLUMNS:
            raise BadInput(f"{csv_path}: header is not {','.join(CSV_COLUMNS)}")
        rows = list(reader)
    if len(rows) != len(maps):
        raise BadInput(f"{csv_path} has {len(rows)} rows, {npy_path} {len(maps)} maps")
    selected = []
    for k, r in enumerate(rows):
        try:
            if int(r["index"]) != k:
                raise BadInput(f"{csv_path}: row {k} has index {r['index']}")
            seq = int(r["sequence"])
            if sequences is not None and seq not in sequences:
                continue
            selected.append(
                MapRow(
                    index=k,
                    sequence=seq,
                    stamp_ns=0,
                    center_x=float(r["center_x"]),
                    center_y=float(r["center_y"]),
                    resolution=float(r["resolution"]),
                    x=float(r["x"]),
                    y=float(r["y"]),
                    z=float(r["z"]),
                    yaw=float(r["yaw"]),
                    pitch=float(r["pitch"]),
                    flippers=tuple(float(r[c]) for c in CSV_COLUMNS[11:15]),
                )
            )
            selected[-1].stamp_ns = seconds_to_ns(r["time"]) + 1000 * seq * NS
        except (ValueError, ArithmeticError) as e:
            raise BadInput(f"{csv_path}: row {k}: {e}") from None
    if sequences is not None:
        missing = sequences - {m.sequence for m in selected}
        if missing:
            raise BadInput(f"no maps of run(s) {', '.join(map(str, sorted(missing)))} in {csv_path}")
    if not selected:
        raise BadInput(f"{csv_path}: no maps to write")
    n = pad_to if pad_to is not None else crop if crop is not None else n
    for a, b in zip(selected, selected[1:]):
        if b.stamp_ns - a.stamp_ns <= 2 * HALF_GAP_NS:
            raise BadInput(
                f"maps {a.index} and {b.index} are {(b.stamp_ns - a.stamp_ns) / NS} s apart: their TF samples "
                f"(-/+ {HALF_GAP_NS / NS} s) would interleave (runs longer than 1000 s, or --dt below 0.04?)"
            )
    return selected, maps, n


def window(maps: np.ndarray, index: int, n: int) -> np.ndarray:
    """Map `index` as (2, n, n) float32: the window itself, or (--pad-to) in
    the middle of an n x n map of NaN (same centre: the unwrapped index i of
    the window is i + (n - w) / 2 of the map), or (--crop) the window's
    middle n x n cells."""
    w = maps.shape[2]
    if n == w:
        return np.asarray(maps[index])
    if n < w:
        o = (w - n) // 2
        return np.ascontiguousarray(maps[index][:, o : o + n, o : o + n])
    out = np.full((2, n, n), np.nan, dtype=np.float32)
    o = (n - w) // 2
    out[:, o : o + w, o : o + w] = maps[index]
    return out


def make_typestore(fmt: str):
    """rosbags' built-in store of the distribution plus grid_map_msgs."""
    if fmt == "ros1":
        ts = get_typestore(Stores.ROS1_NOETIC)
        defs = [(ROS1_GRID_MAP_INFO, "grid_map_msgs/msg/GridMapInfo"), (ROS1_GRID_MAP, GRID_MAP)]
        if TF not in ts.types:
            defs.append((ROS1_TF_MESSAGE, TF))
    else:
        ts = get_typestore(Stores.ROS2_HUMBLE)
        defs = [(ROS2_GRID_MAP_INFO, "grid_map_msgs/msg/GridMapInfo"), (ROS2_GRID_MAP, GRID_MAP)]
    types = {}
    for text, name in defs:
        types.update(get_types_from_msg(text, name))
    ts.register(types)
    if fmt == "ros1":
        for name, md5 in ROS1_MD5.items():
            got = ts.generate_msgdef(name)[1]
            assert got == md5, f"{name}: MD5 {got}, ROS 1 says {md5}"
    return ts


def quat_z(a: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(a / 2), math.cos(a / 2))


def quat_y(a: float) -> tuple[float, float, float, float]:
    return (0.0, math.sin(a / 2), 0.0, math.cos(a / 2))


class Messages:
    """Builds messages of one ROS version from the typestore's classes."""

    def __init__(self, ts, fmt: str):
        self.ts, self.ros1 = ts, fmt == "ros1"
        self.T = ts.types
        self.seq: dict[str, int] = {}

    def time(self, ns: int):
        return self.T["builtin_interfaces/msg/Time"](sec=ns // NS, nanosec=ns % NS)

    def header(self, ns: int, frame: str, publisher: str):
        if self.ros1:
            seq = self.seq.get(publisher, 0)
            self.seq[publisher] = seq + 1
            return self.T["std_msgs/msg/Header"](seq=seq, stamp=self.time(ns), frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=self.time(ns), frame_id=frame)

    def serialize(self, msg, typename: str) -> bytes:
        if self.ros1:
            return bytes(self.ts.serialize_ros1(msg, typename))
        return bytes(self.ts.serialize_cdr(msg, typename))

    def grid_map(self, m: MapRow, ns: int, layers: np.ndarray, k: int, row_major: bool) -> bytes:
        T = self.T
        n = layers.shape[1]
        s0, s1 = (7 * k) % n, (3 * k) % n
        dim = T["std_msgs/msg/MultiArrayDimension"]
        if row_major:
            dims = [dim(label="row_index", size=n, stride=n * n), dim(label="column_index", size=n, stride=n)]
        else:
            dims = [dim(label="column_index", size=n, stride=n * n), dim(label="row_index", size=n, stride=n)]
        data = []
        for layer in layers:
            # Unwrapped (i, j) sits at buffer ((i + s0) % n, (j + s1) % n).
            buf = np.roll(np.asarray(layer, dtype=np.float32), (s0, s1), axis=(0, 1))
            flat = buf.ravel(order="C" if row_major else "F")
            data.append(
                T["std_msgs/msg/Float32MultiArray"](
                    layout=T["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0),
                    data=np.ascontiguousarray(flat, dtype=np.float32),
                )
            )
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=m.center_x, y=m.center_y, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        )
        length = round(n * m.resolution, 9)
        header = self.header(ns, "odom", "map")
        if self.ros1:
            info = T["grid_map_msgs/msg/GridMapInfo"](
                header=header, resolution=m.resolution, length_x=length, length_y=length, pose=pose
            )
            msg = T[GRID_MAP](
                info=info,
                layers=["elevation", "variance"],
                basic_layers=["elevation"],
                data=data,
                outer_start_index=s0,
                inner_start_index=s1,
            )
        else:
            info = T["grid_map_msgs/msg/GridMapInfo"](resolution=m.resolution, length_x=length, length_y=length, pose=pose)
            msg = T[GRID_MAP](
                header=header,
                info=info,
                layers=["elevation", "variance"],
                basic_layers=["elevation"],
                data=data,
                outer_start_index=s0,
                inner_start_index=s1,
            )
        return self.serialize(msg, GRID_MAP)

    def tf(self, ns: int, parent: str, child: str, xyz, quat, publisher: str) -> bytes:
        T = self.T
        t = T["geometry_msgs/msg/TransformStamped"](
            header=self.header(ns, parent, publisher),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=xyz[0], y=xyz[1], z=xyz[2]),
                rotation=T["geometry_msgs/msg/Quaternion"](x=quat[0], y=quat[1], z=quat[2], w=quat[3]),
            ),
        )
        return self.serialize(T[TF](transforms=[t]), TF)

    def joints(self, ns: int, names: list[str], positions: list[float]) -> bytes:
        msg = self.T[JOINTS](
            header=self.header(ns, "", "joints"),
            name=names,
            position=np.array(positions, dtype=np.float64),
            velocity=np.zeros(len(names), dtype=np.float64),
            effort=np.array([], dtype=np.float64),
        )
        return self.serialize(msg, JOINTS)


@dataclass
class Planned:
    """One message to write: receive time, a tie-break, its connection and bytes."""

    recv_ns: int
    order: int
    conn: str
    data: bytes
    stamp_ns: int | None = None  # header stamp, for maps


def samples(a: argparse.Namespace, mb: Messages, m: MapRow, ns: int, add) -> None:
    """The TF (two links) and joint states of map `m` stamped `ns`, at ns -/+ 0.02 s."""
    for sign in (-1, 1):
        t = ns + sign * HALF_GAP_NS
        recv = t + (TF_LATE_NS if a.tf_late else 0)
        xyz = (m.x + sign * D_XY, m.y + sign * D_XY, 0.0)
        add(recv, "tf_odom", mb.tf(t, "odom", "base_footprint", xyz, quat_z(m.yaw + sign * D_YAW), "odom"))
        quat = quat_y(-(m.pitch + sign * D_PITCH))
        add(recv, "tf_body", mb.tf(t, "base_footprint", "base_link", (0.0, 0.0, m.z + sign * D_Z), quat, "body"))
        track = 0.1 * (m.stamp_ns / NS) + sign * 0.002
        pos = {"L": track, "R": -track} | {f: m.flippers[f] + sign * D_FLIPPER for f in range(4)}
        names = [TRACKS[0] if j == "L" else TRACKS[1] if j == "R" else a.flippers[j] for j in JOINT_ORDER]
        add(t, "joints", mb.joints(t, names, [pos[j] for j in JOINT_ORDER]))


def static_tf(mb: Messages, ns: int) -> bytes:
    return mb.tf(ns, "base_link", "camera_link", (0.15, 0.0, 0.45), quat_y(math.radians(35.0)), "static")


def plan_loop(a: argparse.Namespace, rows: list[MapRow], maps: np.ndarray, n: int, mb: Messages, counts: dict):
    """--loop-for: map k is rows[k % len(rows)] (its window and pose) stamped
    --stamp0 + k * --loop-dt, with its TF and joint states as plan() makes
    them; messages are made as they are written, in receive-time order
    (memory stays a few maps whatever the length). Counts into `counts`."""
    import heapq

    base, dt = a.stamp0 * NS, round(a.loop_dt * NS)
    total = int(round(a.loop_for * NS) // dt)
    windows = [window(maps, m.index, n) for m in rows]
    heap: list = []

    def add(recv: int, conn: str, data: bytes, stamp_ns: int | None = None) -> None:
        heapq.heappush(heap, (recv, counts["messages"], conn, data, stamp_ns))
        counts["messages"] += 1

    add(base - HALF_GAP_NS - 100_000_000, "tf_static", static_tf(mb, base - HALF_GAP_NS - 100_000_000))
    for k in range(total):
        m = rows[k % len(rows)]
        ns = base + k * dt
        add(ns + MAP_DELAY_NS, "map", mb.grid_map(m, ns, windows[k % len(rows)], k, a.row_major), ns)
        samples(a, mb, m, ns, add)
        counts["maps"] += 1
        counts["tf"] += 4
        counts["joints"] += 2
        # Messages of later maps are received at their stamp - 0.02 s or later.
        horizon = ns + dt - HALF_GAP_NS
        while heap and heap[0][0] < horizon:
            yield Planned(*heapq.heappop(heap))
    while heap:
        yield Planned(*heapq.heappop(heap))


def plan(a: argparse.Namespace, rows: list[MapRow], maps: np.ndarray, n: int, mb: Messages) -> tuple[list[Planned], dict]:
    """Every message in writing order, and what --verify expects."""
    out: list[Planned] = []
    base = a.stamp0 * NS
    expected = {"maps": [], "tf": 0, "joints": 0, "damaged": None}

    def add(recv: int, conn: str, data: bytes, stamp_ns: int | None = None) -> None:
        out.append(Planned(recv, len(out), conn, data, stamp_ns))

    map_recv = [base + m.stamp_ns + MAP_DELAY_NS for m in rows]
    if a.shuffle_maps:
        for i in range(0, len(rows) - 1, 2):
            map_recv[i], map_recv[i + 1] = map_recv[i + 1], map_recv[i]
    for k, m in enumerate(rows):
        ns = base + m.stamp_ns
        add(map_recv[k], "map", mb.grid_map(m, ns, window(maps, m.index, n), k, a.row_major), ns)
        expected["maps"].append((ns, map_recv[k], m, k))
        samples(a, mb, m, ns, add)
        expected["tf"] += 4
        expected["joints"] += 2
    if a.extra_map_without_tf:
        m = rows[0]
        ns = base + m.stamp_ns - EXTRA_MAP_BEFORE_NS
        if ns < 0:
            raise BadInput("--extra-map-without-tf needs --stamp0 of at least 30")
        add(ns + MAP_DELAY_NS, "map", mb.grid_map(m, ns, window(maps, m.index, n), 0, a.row_major), ns)
        expected["maps"].append((ns, ns + MAP_DELAY_NS, m, 0))
    first = min(p.recv_ns for p in out) - 100_000_000
    add(first, "tf_static", static_tf(mb, first))
    expected["tf_static"] = 1
    out.sort(key=lambda p: (p.recv_ns, p.order))
    if a.damaged_map is not None:
        written = [p for p in out if p.conn == "map"]
        if a.damaged_map >= len(written):
            raise BadInput(f"--damaged-map {a.damaged_map}: only {len(written)} map messages are written (0 .. {len(written) - 1})")
        p = written[a.damaged_map]
        full = len(p.data)
        p.data = p.data[: full // 2]
        expected["damaged"] = (a.damaged_map, p.stamp_ns, len(p.data), full)
    return out, expected


def write_ros1(a, ts, planned: list[Planned]) -> None:
    from rosbags.rosbag1 import Writer

    w = Writer(a.out)
    if a.compression != "none":
        w.set_compression({"bz2": Writer.CompressionFormat.BZ2, "lz4": Writer.CompressionFormat.LZ4}[a.compression])
    with w:
        conns = {
            "map": w.add_connection(a.map_topic, GRID_MAP, typestore=ts, callerid="/elevation_mapping"),
            "tf_odom": w.add_connection("/tf", TF, typestore=ts, callerid="/odometry"),
            "tf_body": w.add_connection("/tf", TF, typestore=ts, callerid="/robot_state_publisher"),
            "tf_static": w.add_connection("/tf_static", TF, typestore=ts, callerid="/camera_tf", latching=1),
            "joints": w.add_connection("/joint_states", JOINTS, typestore=ts, callerid="/flipper_driver"),
        }
        for p in planned:
            w.write(conns[p.conn], p.recv_ns, p.data)


def write_mcap(a, ts, planned: list[Planned]) -> None:
    """A rosbag2 folder: MCAP storage (--format mcap) or SQLite (--format db3)."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

    plugin = StoragePlugin.SQLITE3 if a.format == "db3" else StoragePlugin.MCAP
    w = Writer(a.out, version=9, storage_plugin=plugin)
    if a.compression == "zstd":
        w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)

    def qos(durability: QosDurability) -> list:
        never = QosTime(sec=9223372036, nsec=854775807)  # what rosbag2 records for "infinite"
        return [Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE, durability, never, never,
                    QosLiveliness.AUTOMATIC, never, False)]

    with w:
        if a.compression == "lz4":
            # rosbags' MCAP writer compresses chunks with zstd only; its
            # chunk compressor is a plain attribute: give it LZ4 frames,
            # what MCAP's "lz4" compression means.
            import lz4.frame

            storage = w.storage
            if not (hasattr(storage, "compressor") and hasattr(storage, "compression")):
                raise RuntimeError("this rosbags version's MCAP writer has no chunk compressor to set; use zstd")
            storage.compression, storage.compressor = "lz4", lz4.frame.compress
        volatile, latched = qos(QosDurability.VOLATILE), qos(QosDurability.TRANSIENT_LOCAL)
        tf = w.add_connection("/tf", TF, typestore=ts, offered_qos_profiles=volatile)
        conns = {
            "map": w.add_connection(a.map_topic, GRID_MAP, typestore=ts, offered_qos_profiles=volatile),
            "tf_odom": tf,
            "tf_body": tf,
            "tf_static": w.add_connection("/tf_static", TF, typestore=ts, offered_qos_profiles=latched),
            "joints": w.add_connection("/joint_states", JOINTS, typestore=ts, offered_qos_profiles=volatile),
        }
        for p in planned:
            w.write(conns[p.conn], p.recv_ns, p.data)


# ---------------------------------------------------------------- verify


def quat_to_yaw_pitch(q) -> tuple[float, float]:
    """Yaw about z and rotation about y of a quaternion (x, y, z, w) of ZYX order, roll 0."""
    x, y, z, w = q
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    pitch_y = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    return yaw, pitch_y


def slerp(q0, q1, t: float):
    d = sum(a * b for a, b in zip(q0, q1))
    if d < 0:
        q1, d = tuple(-c for c in q1), -d
    if d > 0.9999995:
        q = [a + t * (b - a) for a, b in zip(q0, q1)]
    else:
        th = math.acos(d)
        s0, s1 = math.sin((1 - t) * th) / math.sin(th), math.sin(t * th) / math.sin(th)
        q = [s0 * a + s1 * b for a, b in zip(q0, q1)]
    norm = math.sqrt(sum(c * c for c in q))
    return tuple(c / norm for c in q)


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def bracket(samples: list, ns: int):
    """The samples (stamp, value) just before/at and after `ns`, or None."""
    lo = [s for s in samples if s[0] <= ns]
    hi = [s for s in samples if s[0] >= ns]
    if not lo or not hi:
        return None
    a, b = max(lo, key=lambda s: s[0]), min(hi, key=lambda s: s[0])
    t = 0.0 if b[0] == a[0] else (ns - a[0]) / (b[0] - a[0])
    return a[1], b[1], t


def lookup(tf: dict, parent: str, child: str, ns: int):
    """Interpolated (translation, rotation) of one link at ns, or None."""
    br = bracket(tf.get((parent, child), []), ns)
    if br is None:
        return None
    (p0, q0), (p1, q1), t = br
    return tuple(a + t * (b - a) for a, b in zip(p0, p1)), slerp(q0, q1, t)


def unwrap_layer(arr, n_expected: int) -> np.ndarray:
    """A Float32MultiArray of grid_map_ros as the buffer matrix (rows = x index)."""
    dims = arr.layout.dim
    assert len(dims) == 2 and arr.layout.data_offset == 0, "layout"
    data = np.asarray(arr.data, dtype=np.float32)
    if dims[0].label == "column_index":
        assert dims[1].label == "row_index"
        cols, rows = dims[0].size, dims[1].size
        assert dims[0].stride == rows * cols and dims[1].stride == rows, "column-major strides"
        buf = data.reshape(cols, rows).T
    else:
        assert dims[0].label == "row_index" and dims[1].label == "column_index"
        rows, cols = dims[0].size, dims[1].size
        assert dims[0].stride == rows * cols and dims[1].stride == cols, "row-major strides"
        buf = data.reshape(rows, cols)
    assert (rows, cols) == (n_expected, n_expected), f"size {rows} x {cols}"
    return buf


def dem_from_window(elev: np.ndarray, cx: float, cy: float, res: float, x, y, z, yaw) -> tuple[np.ndarray, np.ndarray]:
    """The importer's rule: heights (20, 5) and validity from one unwrapped elevation window."""
    n = elev.shape[0]
    half = n * res / 2
    r = np.arange(20)[:, None, None]
    c = np.arange(5)[None, :, None]
    dx = np.array([-0.025, -0.025, 0.025, 0.025])[None, None, :]
    dy = np.array([-0.025, 0.025, -0.025, 0.025])[None, None, :]
    fx = -0.6 + 0.1 * (r + 0.5) + dx
    fy = (2.0 - c) * 0.1 + dy
    s, co = math.sin(yaw), math.cos(yaw)
    wx, wy = x + co * fx - s * fy, y + s * fx + co * fy
    i = np.floor((cx + half - wx) / res).astype(int)
    j = np.floor((cy + half - wy) / res).astype(int)
    inside = (i >= 0) & (i < n) & (j >= 0) & (j < n)
    vals = np.where(inside, elev[np.clip(i, 0, n - 1), np.clip(j, 0, n - 1)].astype(np.float64), np.nan)
    count = (~np.isnan(vals)).sum(axis=2)
    mean = np.nansum(vals, axis=2) / np.maximum(count, 1)
    return (mean - z).astype(np.float32), count >= 2


def read_back(a, damaged: int | None = None) -> tuple[list, object]:
    """(topic, msgtype, recv_ns, message, connection) of every message, with a
    typestore built from the definitions stored in the recording. Message
    `damaged` of the map topic (--damaged-map) must fail to deserialize: its
    message is None."""
    from rosbags.typesys import get_types_from_msg as parse

    out = []
    on_map_topic = 0

    def decode(conn, raw, deserialize):
        nonlocal on_map_topic
        if conn.topic != a.map_topic:
            return deserialize(raw, conn.msgtype)
        k, on_map_topic = on_map_topic, on_map_topic + 1
        if k != damaged:
            return deserialize(raw, conn.msgtype)
        try:
            deserialize(raw, conn.msgtype)
        except Exception:  # noqa: BLE001 - any failure to deserialize is what is expected
            return None
        raise AssertionError(f"map message {k} was cut to {len(raw)} bytes but deserializes")

    if a.format == "ros1":
        from rosbags.rosbag1 import Reader

        ts = get_typestore(Stores.EMPTY)
        with Reader(a.out) as r:
            for conn in r.connections:
                assert conn.msgtype in ROS1_MD5, conn.msgtype
                assert conn.digest == ROS1_MD5[conn.msgtype], f"{conn.topic}: MD5 {conn.digest}"
                types = parse(conn.msgdef.data, conn.msgtype)
                ts.register(types)
                got = ts.generate_msgdef(conn.msgtype)[1]
                assert got == conn.digest, f"{conn.msgtype}: stored definition hashes to {got}"
            for conn, t, raw in r.messages():
                out.append((conn.topic, conn.msgtype, t, decode(conn, raw, ts.deserialize_ros1), conn))
    else:
        from rosbags.rosbag2 import Reader

        ts = get_typestore(Stores.EMPTY)
        with Reader(a.out) as r:
            for conn in r.connections:
                ts.register(parse(conn.msgdef.data, conn.msgtype))
            for conn, t, raw in r.messages():
                out.append((conn.topic, conn.msgtype, t, decode(conn, raw, ts.deserialize_cdr), conn))
    return out, ts


def verify(a, rows: list[MapRow], maps: np.ndarray, n: int, expected: dict, planned: list[Planned]) -> str:
    damaged = expected["damaged"]
    msgs, _ = read_back(a, damaged[0] if damaged else None)
    assert len(msgs) == len(planned), f"{len(msgs)} messages read, {len(planned)} written"
    recv = [m[2] for m in msgs]
    assert recv == sorted(recv) == [p.recv_ns for p in planned], "receive times or their order"
    by_topic: dict[str, list] = {}
    for topic, msgtype, t, msg, _ in msgs:
        by_topic.setdefault(topic, []).append((msgtype, t, msg))
    counts = {k: len(v) for k, v in by_topic.items()}
    want = {a.map_topic: len(expected["maps"]), "/tf": expected["tf"], "/tf_static": 1, "/joint_states": expected["joints"]}
    assert counts == want, f"messages per topic {counts}, expected {want}"

    # TF samples per link and joint samples per name, by header stamp.
    stamp = lambda h: h.stamp.sec * NS + h.stamp.nanosec  # noqa: E731
    tf: dict = {}
    for msgtype, t, msg in by_topic["/tf"]:
        assert msgtype == TF and len(msg.transforms) == 1
        for tr in msg.transforms:
            s = stamp(tr.header)
            late = TF_LATE_NS if a.tf_late else 0
            assert t == s + late, "TF receive time"
            v, q = tr.transform.translation, tr.transform.rotation
            tf.setdefault((tr.header.frame_id, tr.child_frame_id), []).append((s, ((v.x, v.y, v.z), (q.x, q.y, q.z, q.w))))
    assert set(tf) == {("odom", "base_footprint"), ("base_footprint", "base_link")}, set(tf)
    static = by_topic["/tf_static"][0][2].transforms
    assert [(s.header.frame_id, s.child_frame_id) for s in static] == [("base_link", "camera_link")]
    joints: dict = {}
    for msgtype, t, msg in by_topic["/joint_states"]:
        assert t == stamp(msg.header) and len(msg.name) == 6
        for name, pos in zip(msg.name, msg.position):
            joints.setdefault(name, []).append((stamp(msg.header), float(pos)))

    real = None
    real_path = a.dir / "real.npy"
    if real_path.is_file():
        real = np.load(real_path, mmap_mode="r")
        assert len(real) == len(maps), f"{real_path}: {len(real)} records, {len(maps)} maps"
    maps_read = {}
    for msgtype, t, msg in by_topic[a.map_topic]:
        assert msgtype == GRID_MAP
        if msg is None:  # the --damaged-map message
            continue
        header = msg.info.header if a.format == "ros1" else msg.header
        maps_read.setdefault(stamp(header), []).append((t, msg, header))
    worst = {"xy": 0.0, "z": 0.0, "angle": 0.0, "flipper": 0.0, "dem": 0.0}
    cells = 0
    for ns, recv_ns, m, k in expected["maps"]:
        if damaged and ns == damaged[1]:
            assert ns not in maps_read, "the damaged map was read"
            continue
        (t, msg, header), *rest = maps_read[ns]
        assert not rest, f"two maps stamped {ns}"
        assert t == recv_ns, f"map {m.index}: received at {t}, planned {recv_ns}"
        info = msg.info
        assert header.frame_id == "odom"
        assert (info.resolution, info.length_x, info.length_y) == (m.resolution, round(n * m.resolution, 9), round(n * m.resolution, 9))
        p, q = info.pose.position, info.pose.orientation
        assert (p.x, p.y, p.z, q.x, q.y, q.z, q.w) == (m.center_x, m.center_y, 0.0, 0.0, 0.0, 0.0, 1.0)
        assert list(msg.layers) == ["elevation", "variance"] and list(msg.basic_layers) == ["elevation"]
        assert (msg.outer_start_index, msg.inner_start_index) == ((7 * k) % n, (3 * k) % n), f"map {m.index}: start index"
        layers = []
        for arr in msg.data:
            buf = unwrap_layer(arr, n)
            s0, s1 = msg.outer_start_index, msg.inner_start_index
            layers.append(np.roll(buf, (-s0, -s1), axis=(0, 1)))
        got = np.stack(layers)
        assert np.array_equal(got.view(np.uint32), window(maps, m.index, n).view(np.uint32)), f"map {m.index}: values"
        # The pose from TF and joints at the map's stamp.
        odom = lookup(tf, "odom", "base_footprint", ns)
        body = lookup(tf, "base_footprint", "base_link", ns)
        if ns < min(s for s, _ in tf[("odom", "base_footprint")]):
            assert odom is None and body is None, "the extra map has no TF"
            continue
        (x, y, _), q_odom = odom
        (_, _, z), q_body = body
        # odom -> base_link, as an importer looks it up.
        yaw, about_y = quat_to_yaw_pitch(quat_mul(q_odom, q_body))
        pitch = -about_y
        flippers = []
        for name in a.flippers:
            (v0, v1, tt) = bracket(joints[name], ns)
            flippers.append(v0 + tt * (v1 - v0))
        worst["xy"] = max(worst["xy"], abs(x - m.x), abs(y - m.y))
        worst["z"] = max(worst["z"], abs(z - m.z))
        worst["angle"] = max(worst["angle"], abs(yaw - m.yaw), abs(pitch - m.pitch))
        worst["flipper"] = max([worst["flipper"]] + [abs(f - g) for f, g in zip(flippers, m.flippers)])
        if real is not None:
            heights, valid = dem_from_window(got[0], p.x, p.y, info.resolution, x, y, z, yaw)
            rec = np.asarray(real[m.index])
            assert np.array_equal(valid, rec[:20, :, 1] > 0), f"map {m.index}: validity differs from real.npy"
            if valid.any():
                worst["dem"] = max(worst["dem"], float(np.abs(heights - rec[:20, :, 0])[valid].max()))
            cells += int(valid.sum())
            att = np.array([pitch, *flippers], dtype=np.float32)
            assert np.abs(att - rec[20, :, 0]).max() <= 1e-6, f"map {m.index}: attitude {att} vs {rec[20, :, 0]}"
    assert worst["xy"] < 1e-9 and worst["z"] < 1e-9 and worst["angle"] < 1e-9 and worst["flipper"] < 1e-9, worst
    assert worst["dem"] <= 1e-5, worst
    dem = f", {cells} valid DEM cells rebuilt as real.npy (max error {worst['dem']:.1e} m)" if real is not None else ""
    cut = (
        f" (map message {damaged[0]}, cut to {damaged[2]} of {damaged[3]} bytes, fails to deserialize as expected: "
        "skipped in the checks)"
        if damaged
        else ""
    )
    return (
        f"verified {len(msgs)} messages{cut}: maps bit-exact, pose from TF within {max(worst['xy'], worst['z']):.1e} m "
        f"and {worst['angle']:.1e} rad, flippers within {worst['flipper']:.1e} rad{dem}"
    )


def output_file(a) -> Path:
    return a.out if a.format == "ros1" else a.out / f"{a.out.name}.{a.format}"


def main(argv: list[str] | None = None) -> int:
    a = parse_args(argv)
    try:
        if a.out.exists() or a.out.is_symlink():
            raise BadInput(f"{a.out} exists already; not overwriting")
        if not a.out.parent.is_dir():
            raise BadInput(f"{a.out.parent} is not a folder")
        rows, maps, n = read_maps(a.dir, a.sequences, a.pad_to, a.crop)
        ts = make_typestore(a.format)
        if a.loop_for is None:
            planned, expected = plan(a, rows, maps, n, Messages(ts, a.format))
        else:
            expected = {"messages": 0, "maps": 0, "tf": 0, "joints": 0}
            planned = plan_loop(a, rows, maps, n, Messages(ts, a.format), expected)
    except BadInput as e:
        log(str(e))
        return 2
    try:
        (write_ros1 if a.format == "ros1" else write_mcap)(a, ts, planned)
        size = sum(f.stat().st_size for f in ([a.out] if a.out.is_file() else a.out.iterdir()))
        runs = sorted({m.sequence for m in rows})
        looped = f"{expected['maps']} maps: {len(rows)} of {len(runs)} run(s) over and over for {a.loop_for} s" if a.loop_for else ""
        log(
            f"wrote {expected['messages'] if looped else len(planned)} messages ({looped or f'{len(rows)} maps of {len(runs)} run(s)'}"
            f"{' + 1 without TF' if a.extra_map_without_tf else ''}"
            f"{f', {n} x {n} cells' if a.pad_to is not None or a.crop is not None else ''}"
            f"{f', map message {a.damaged_map} cut short' if a.damaged_map is not None else ''}, "
            f"{expected['tf'] + 1} TF, {expected['joints']} joint states) to {output_file(a)} "
            f"({a.format}, compression {a.compression}, {size / 1e6:.1f} MB)"
        )
        if a.verify:
            log(verify(a, rows, maps, n, expected, planned))
    except BaseException as e:
        if a.out.is_dir() and not a.out.is_symlink():
            shutil.rmtree(a.out, ignore_errors=True)
        elif a.out.exists():
            a.out.unlink()
        if isinstance(e, AssertionError):
            log(f"verification failed, {a.out} removed: {e}")
            return 1
        raise
    return 0


if __name__ == "__main__":
    sys.exit(main())
