//! The three message types dem-import reads, decoded from either
//! serialization ([`crate::wire`]):
//!
//! - `grid_map_msgs/GridMap` (ROS 1: the stamp and frame in `info.header`;
//!   ROS 2: a top-level `header` before `info`), see [`GridMap`];
//! - `tf2_msgs/TFMessage` (on `/tf` and `/tf_static`);
//! - `sensor_msgs/JointState`.

use crate::geometry::{Quat, Transform, Vec3};
use crate::wire::{ArrayAt, Encoding, Result, Wire, WireError};

/// The largest coordinate (m) a transform or a map position may have: beyond
/// any frame on Earth (UTM northings reach 1e7 m), so a larger one is a
/// damaged message, refused before it can become an infinite DEM value.
pub const MAX_COORDINATE: f64 = 1e9;

/// A number for a message: as written when it is short, else in `{:e}`
/// form (`1e300`, not 301 digits).
pub fn num<T: std::fmt::Display + std::fmt::LowerExp>(v: T) -> String {
    let plain = format!("{v}");
    if plain.len() <= 12 {
        plain
    } else {
        format!("{v:e}")
    }
}

/// Err naming `what` when `v` (x, y, z) is not finite or beyond [`MAX_COORDINATE`].
fn check_position(v: Vec3, what: &str) -> Result<()> {
    for (axis, x) in [("x", v.x), ("y", v.y), ("z", v.z)] {
        if !(x.is_finite() && x.abs() <= MAX_COORDINATE) {
            return Err(WireError(format!("{what} {axis} = {} m is not a position (at most {} m)", num(x), num(MAX_COORDINATE))));
        }
    }
    Ok(())
}

/// Storage order of a grid_map layer (`Float32MultiArray.layout.dim[0].label`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    /// Eigen's default: `data[col * rows + row]` (label `column_index`).
    ColumnMajor,
    /// `data[row * cols + col]` (label `row_index`).
    RowMajor,
}

/// One layer of a map: where its floats lie and how they are ordered.
#[derive(Clone, Copy, Debug)]
pub struct Layer {
    data: ArrayAt,
    offset: usize,
    storage: Storage,
}

/// A `grid_map_msgs/GridMap`, its layers left in the message buffer.
///
/// Geometry (grid_map's conventions): the map is `rows x cols` cells of
/// `resolution` metres, centred at `center` in `frame`; the *unwrapped*
/// index (i, j) grows from the map's +x, +y corner towards -x, -y, and is
/// stored at buffer index ((i + outer_start) mod rows, (j + inner_start) mod cols).
pub struct GridMap<'a> {
    buf: &'a [u8],
    /// Header stamp, ns.
    pub stamp: i64,
    /// The frame the map's position is given in.
    pub frame: &'a str,
    /// Cell edge, m.
    pub resolution: f64,
    /// Cells along x.
    pub rows: usize,
    /// Cells along y.
    pub cols: usize,
    /// Map centre in `frame`.
    pub center: Vec3,
    /// Yaw of the map's axes in `frame` (grid_map writes 0).
    pub yaw: f64,
    /// Layer names, in message order.
    pub layers: Vec<&'a str>,
    layer_data: Vec<Layer>,
    outer_start: usize,
    inner_start: usize,
}

fn pose(w: &mut Wire<'_>) -> Result<(Vec3, Quat)> {
    let p = Vec3::new(w.f64("pose.position.x")?, w.f64("pose.position.y")?, w.f64("pose.position.z")?);
    let q = Quat { x: w.f64("orientation.x")?, y: w.f64("orientation.y")?, z: w.f64("orientation.z")?, w: w.f64("orientation.w")? };
    Ok((p, q))
}

impl<'a> GridMap<'a> {
    /// Decode the map's geometry and locate its layers.
    ///
    /// The two ROS generations put the header in different places (ROS 1:
    /// `info.header`; ROS 2: a top-level `header` before `info`), but on the
    /// wire both come first, before `info.resolution`: only the header's own
    /// form differs (ROS 1's has a `seq`), and that follows the encoding.
    pub fn decode(buf: &'a [u8], encoding: Encoding) -> Result<Self> {
        let mut w = Wire::new(buf, encoding)?;
        let (stamp, frame) = w.header()?;
        let resolution = w.f64("info.resolution")?;
        let length_x = w.f64("info.length_x")?;
        let length_y = w.f64("info.length_y")?;
        let (center, q) = pose(&mut w)?;
        if !(resolution.is_finite() && resolution > 0.0 && length_x.is_finite() && length_y.is_finite()) {
            return Err(WireError(format!(
                "info: resolution {} and lengths {} x {} are not a map",
                num(resolution),
                num(length_x),
                num(length_y)
            )));
        }
        let rows = (length_x / resolution).round();
        let cols = (length_y / resolution).round();
        if !(1.0..=65536.0).contains(&rows) || !(1.0..=65536.0).contains(&cols) {
            return Err(WireError(format!(
                "info: lengths {} x {} m at resolution {} m are {} x {} cells (1 to 65536 a side)",
                num(length_x),
                num(length_y),
                num(resolution),
                num(rows),
                num(cols)
            )));
        }
        check_position(center, "info.pose.position")?;
        // grid_map writes the identity; a zero quaternion reads as no
        // rotation, as grid_map (which ignores the orientation) reads it.
        if ![q.x, q.y, q.z, q.w].iter().all(|v| v.is_finite()) {
            return Err(WireError(format!(
                "info.pose.orientation ({}, {}, {}, {}) is not a rotation",
                num(q.x),
                num(q.y),
                num(q.z),
                num(q.w)
            )));
        }
        let (rows, cols) = (rows as usize, cols as usize);
        let layers = w.strings("layers")?;
        w.strings("basic_layers")?;
        let n = w.count(12, "data")?;
        if n != layers.len() {
            return Err(WireError(format!("{} layer names but {n} data arrays", layers.len())));
        }
        let mut layer_data = Vec::with_capacity(n);
        for name in &layers {
            layer_data.push(Self::layer(&mut w, name, rows, cols)?);
        }
        let outer_start = w.u16("outer_start_index")? as usize;
        let inner_start = w.u16("inner_start_index")? as usize;
        if outer_start >= rows || inner_start >= cols {
            return Err(WireError(format!("start index ({outer_start}, {inner_start}) outside a {rows} x {cols} map")));
        }
        let yaw = q.yaw_of_x_axis();
        Ok(GridMap { buf, stamp, frame, resolution, rows, cols, center, yaw, layers, layer_data, outer_start, inner_start })
    }

    fn layer(w: &mut Wire<'a>, name: &str, rows: usize, cols: usize) -> Result<Layer> {
        let what = |f: &str| format!("layer {name}: {f}");
        let dims = w.count(12, &what("layout.dim"))?;
        let mut labels = Vec::with_capacity(dims);
        let mut sizes = Vec::with_capacity(dims);
        for _ in 0..dims {
            labels.push(w.string(&what("dim.label"))?);
            sizes.push(w.u32(&what("dim.size"))? as usize);
            w.u32(&what("dim.stride"))?;
        }
        let offset = w.u32(&what("layout.data_offset"))? as usize;
        let data = w.f32_array(&what("data"))?;
        let storage = match (dims, labels.first().copied()) {
            (2, Some("column_index")) => Storage::ColumnMajor,
            (2, Some("row_index")) => Storage::RowMajor,
            _ => return Err(WireError(format!("layer {name}: layout {labels:?} is not grid_map's (column_index/row_index)"))),
        };
        let (outer, inner) = match storage {
            Storage::ColumnMajor => (cols, rows),
            Storage::RowMajor => (rows, cols),
        };
        if sizes != [outer, inner] {
            return Err(WireError(format!("layer {name}: layout {sizes:?} does not fit a {rows} x {cols} map")));
        }
        let cells = rows * cols;
        if data.len < cells {
            return Err(WireError(format!("layer {name}: {} floats for {rows} x {cols} = {cells} cells", data.len)));
        }
        if offset > data.len - cells {
            return Err(WireError(format!(
                "layer {name}: layout.data_offset {offset} is out of range: {cells} cells from there need {} floats, the layer has {} (grid_map writes 0)",
                offset + cells,
                data.len
            )));
        }
        Ok(Layer { data, offset, storage })
    }

    /// The layer called `name`.
    pub fn layer_named(&self, name: &str) -> Option<Layer> {
        self.layers.iter().position(|l| *l == name).map(|k| self.layer_data[k])
    }

    /// The value of `layer` at map-frame point (x, y), or None outside the map.
    /// grid_map's getIndexFromPosition: i = floor((cx + lx/2 - x) / res).
    #[inline]
    pub fn at(&self, layer: &Layer, x: f64, y: f64) -> Option<f32> {
        let (dx, dy) = (x - self.center.x, y - self.center.y);
        let (dx, dy) = if self.yaw == 0.0 {
            (dx, dy)
        } else {
            let (s, c) = self.yaw.sin_cos();
            (c * dx + s * dy, -s * dx + c * dy)
        };
        let lx = self.rows as f64 * self.resolution;
        let ly = self.cols as f64 * self.resolution;
        let i = ((0.5 * lx - dx) / self.resolution).floor();
        let j = ((0.5 * ly - dy) / self.resolution).floor();
        if !(i >= 0.0 && j >= 0.0 && i < self.rows as f64 && j < self.cols as f64) {
            return None;
        }
        let bi = (i as usize + self.outer_start) % self.rows;
        let bj = (j as usize + self.inner_start) % self.cols;
        let k = match layer.storage {
            Storage::ColumnMajor => bj * self.rows + bi,
            Storage::RowMajor => bi * self.cols + bj,
        };
        Some(layer.data.f32(self.buf, layer.offset + k))
    }
}

/// One `geometry_msgs/TransformStamped` of a TF message.
#[derive(Clone, Debug, PartialEq)]
pub struct StampedTransform {
    /// Stamp, ns.
    pub stamp: i64,
    /// Parent frame.
    pub parent: String,
    /// Child frame.
    pub child: String,
    /// Child pose in the parent frame.
    pub transform: Transform,
}

/// Decode a `tf2_msgs/TFMessage`.
pub fn decode_tf(buf: &[u8], encoding: Encoding) -> Result<Vec<StampedTransform>> {
    let mut w = Wire::new(buf, encoding)?;
    let n = w.count(60, "transforms")?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let (stamp, parent) = w.header()?;
        let child = w.string("child_frame_id")?;
        let t = Vec3::new(w.f64("translation.x")?, w.f64("translation.y")?, w.f64("translation.z")?);
        let q = Quat { x: w.f64("rotation.x")?, y: w.f64("rotation.y")?, z: w.f64("rotation.z")?, w: w.f64("rotation.w")? };
        let q = q.normalized().ok_or_else(|| WireError(format!("transform {parent} -> {child}: rotation is not a quaternion")))?;
        check_position(t, &format!("transform {parent} -> {child}: translation"))?;
        out.push(StampedTransform {
            stamp,
            parent: strip_slash(parent).to_string(),
            child: strip_slash(child).to_string(),
            transform: Transform { translation: t, rotation: q },
        });
    }
    Ok(out)
}

/// tf2 frame ids have no leading slash; ROS 1 recordings often have one.
pub fn strip_slash(frame: &str) -> &str {
    frame.strip_prefix('/').unwrap_or(frame)
}

/// A `sensor_msgs/JointState`: stamp, names and positions.
#[derive(Clone, Debug, PartialEq)]
pub struct JointState {
    /// Stamp, ns.
    pub stamp: i64,
    /// Joint names.
    pub names: Vec<String>,
    /// Joint positions (rad for revolute joints), one per name.
    pub positions: Vec<f64>,
}

/// Decode a `sensor_msgs/JointState`.
pub fn decode_joint_state(buf: &[u8], encoding: Encoding) -> Result<JointState> {
    let mut w = Wire::new(buf, encoding)?;
    let (stamp, _) = w.header()?;
    let names: Vec<String> = w.strings("name")?.into_iter().map(str::to_string).collect();
    let positions = w.f64_array("position")?;
    if positions.len() != names.len() {
        return Err(WireError(format!("{} joint names but {} positions", names.len(), positions.len())));
    }
    Ok(JointState { stamp, names, positions })
}
