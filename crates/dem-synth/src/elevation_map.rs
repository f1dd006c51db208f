//! A robot-centric elevation map in the manner of ETH's elevation_mapping:
//! 5 cm cells, each a 1D Kalman filter over height, resampled to the 10 cm
//! DEM of the contract.
//!
//! Fusion of a point z with variance s^2 into a cell (h, v):
//!
//! ```text
//! empty cell:              h = z, v = s^2
//! |z - h| / sqrt(v) <= 2.5: h = (v z + s^2 h) / (v + s^2), v = v s^2 / (v + s^2)
//! outlier, same frame:     keep the higher (lower points hide under tops)
//! outlier, older cell:     v += multi-height noise (the cell slowly gives way)
//! ```
//!
//! Every frame adds process noise to every cell (the robot's own pose is
//! uncertain) and forgets cells that leave the square window around the
//! robot: the map moves with it, so cells it never saw stay missing. A cell
//! whose variance is above the maximum is a hole.

use super::camera::Hit;
use super::pose::Pose;
use dem_core::format::{col_center_y, empty_dem, row_center_x, Dem, DemCells, COLS, GRID_ROWS};

/// Map parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct MapConfig {
    /// Cell edge (m).
    pub resolution: f64,
    /// Side of the square window around the robot (m).
    pub window: f64,
    /// Mahalanobis distance beyond which a point is an outlier.
    pub mahalanobis: f64,
    /// Variance added to a cell per outlier from a later frame (m^2).
    pub multi_height_noise: f64,
    /// Variance added to every cell per frame (m^2).
    pub process_noise: f64,
    /// Cells with a larger variance are holes (m^2).
    pub max_variance: f64,
    /// Map cells (of the 4 under a DEM cell) that must be valid.
    pub min_cells: usize,
}

impl Default for MapConfig {
    fn default() -> Self {
        MapConfig {
            resolution: 0.05,
            window: 4.0,
            mahalanobis: 2.5,
            multi_height_noise: 9e-7,
            process_noise: 4e-6,
            max_variance: 4e-4,
            min_cells: 2,
        }
    }
}

impl MapConfig {
    /// Side of the robot-centred window in cells (80 for 4 m at 5 cm).
    pub fn window_cells(&self) -> usize {
        (self.window / self.resolution).round() as usize
    }
}

#[derive(Clone, Copy)]
struct Cell {
    h: f64,
    var: f64,
    frame: u32,
}

const EMPTY: Cell = Cell { h: 0.0, var: f64::INFINITY, frame: 0 };

/// The robot-centred window of the map after a frame, as elevation_mapping
/// publishes it in a grid_map_msgs/GridMap (for `dem-synth --emit-maps`).
///
/// grid_map's conventions: the window is `cells` x `cells` map cells whose
/// edges are the map's own cell edges, centred on (`center_x`, `center_y`);
/// index (i, j) is grid_map's *unwrapped* index, i along -x and j along -y:
/// (0, 0) is the cell at the largest x and y, and cell (i, j) is centred at
/// `center + cells * resolution / 2 - resolution / 2 - (i, j) * resolution`.
/// A world point (x, y) lies in cell
/// `(floor((center_x + L/2 - x) / res), floor((center_y + L/2 - y) / res))`,
/// L = `cells * resolution`. It follows the robot without resampling: the
/// map cell holding the robot is (cells/2 - 1, cells/2 - 1), the window
/// spans the map cells from `cells / 2` below the robot's cell to
/// `cells / 2 - 1` above it along x and y, and cells beyond the emulator's
/// map are NaN in both layers.
#[derive(Debug, Clone, PartialEq)]
pub struct MapWindow {
    /// World x of the window's centre (m).
    pub center_x: f64,
    /// World y of the window's centre (m).
    pub center_y: f64,
    /// Cell edge (m).
    pub resolution: f64,
    /// Cells along each side.
    pub cells: usize,
    /// World z (m) by unwrapped index, `[i * cells + j]`; NaN where the map
    /// has no valid height (never seen, outside the map, or with the `holes`
    /// stage on, a variance above the maximum): exactly the cells the DEM
    /// resampling leaves out.
    pub elevation: Vec<f32>,
    /// Height variance (m^2), laid out as `elevation`; NaN where the cell
    /// was never seen (infinite variance) or lies outside the map.
    pub variance: Vec<f32>,
}

/// The map over a world rectangle.
pub struct ElevationMap {
    cfg: MapConfig,
    x0: f64,
    y0: f64,
    nx: usize,
    ny: usize,
    cells: Vec<Cell>,
    frame: u32,
}

impl ElevationMap {
    /// A map covering world x in `[x_min, x_max]`, y in `[y_min, y_max]`.
    pub fn new(cfg: MapConfig, x_min: f64, x_max: f64, y_min: f64, y_max: f64) -> Self {
        let nx = ((x_max - x_min) / cfg.resolution).ceil() as usize;
        let ny = ((y_max - y_min) / cfg.resolution).ceil() as usize;
        ElevationMap { cfg, x0: x_min, y0: y_min, nx, ny, cells: vec![EMPTY; nx * ny], frame: 0 }
    }

    fn index(&self, x: f64, y: f64) -> Option<usize> {
        let i = ((x - self.x0) / self.cfg.resolution).floor();
        let j = ((y - self.y0) / self.cfg.resolution).floor();
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny).then(|| i as usize * self.ny + j as usize)
    }

    /// Start a frame at `pose`: process noise, then forget what left the window.
    pub fn begin_frame(&mut self, pose: &Pose) {
        self.frame += 1;
        let half = self.cfg.window / 2.0;
        let (s, c) = pose.yaw.sin_cos();
        for i in 0..self.nx {
            let x = self.x0 + (i as f64 + 0.5) * self.cfg.resolution - pose.x;
            for j in 0..self.ny {
                let cell = &mut self.cells[i * self.ny + j];
                if cell.var.is_infinite() {
                    continue;
                }
                let y = self.y0 + (j as f64 + 0.5) * self.cfg.resolution - pose.y;
                let (fx, fy) = (c * x + s * y, -s * x + c * y);
                if fx.abs() > half || fy.abs() > half {
                    *cell = EMPTY;
                } else {
                    cell.var += self.cfg.process_noise;
                }
            }
        }
    }

    /// Forget every cell: the next frame's DEM is its own points alone (a
    /// map without memory).
    pub fn forget(&mut self) {
        self.cells.fill(EMPTY);
    }

    /// Fuse one measured point.
    pub fn fuse(&mut self, hit: &Hit) {
        let Some(k) = self.index(hit.x, hit.y) else { return };
        let frame = self.frame;
        let cfg = &self.cfg;
        let cell = &mut self.cells[k];
        if cell.var.is_infinite() {
            *cell = Cell { h: hit.z, var: hit.var, frame };
            return;
        }
        if (hit.z - cell.h).abs() / cell.var.sqrt() > cfg.mahalanobis {
            if cell.frame == frame {
                if hit.z > cell.h {
                    *cell = Cell { h: hit.z, var: hit.var, frame };
                }
            } else {
                cell.var += cfg.multi_height_noise;
            }
            return;
        }
        let v = cell.var;
        cell.h = (v * hit.z + hit.var * cell.h) / (v + hit.var);
        cell.var = v * hit.var / (v + hit.var);
        cell.frame = frame;
    }

    /// The map as elevation_mapping would publish it at `pose`: the
    /// [`MapConfig::window_cells`]-square window of world-fixed
    /// cells around the robot, laid out as grid_map's unwrapped index (see
    /// [`MapWindow`]). `holes` as for [`dem`](Self::dem): a cell whose
    /// variance is above the maximum has no elevation. Reads the map only.
    pub fn window(&self, pose: &Pose, holes: bool) -> MapWindow {
        let n = self.cfg.window_cells();
        let res = self.cfg.resolution;
        let half = (n / 2) as i64;
        let a0 = ((pose.x - self.x0) / res).floor() as i64 - half;
        let b0 = ((pose.y - self.y0) / res).floor() as i64 - half;
        let mut elevation = vec![f32::NAN; n * n];
        let mut variance = vec![f32::NAN; n * n];
        for i in 0..n {
            let a = a0 + (n - 1 - i) as i64;
            if a < 0 || a >= self.nx as i64 {
                continue;
            }
            for j in 0..n {
                let b = b0 + (n - 1 - j) as i64;
                if b < 0 || b >= self.ny as i64 {
                    continue;
                }
                let cell = self.cells[a as usize * self.ny + b as usize];
                if cell.var.is_infinite() {
                    continue;
                }
                variance[i * n + j] = cell.var as f32;
                if !holes || cell.var <= self.cfg.max_variance {
                    elevation[i * n + j] = cell.h as f32;
                }
            }
        }
        MapWindow {
            center_x: self.x0 + (a0 + half) as f64 * res,
            center_y: self.y0 + (b0 + half) as f64 * res,
            resolution: res,
            cells: n,
            elevation,
            variance,
        }
    }

    /// The 10 cm DEM around `pose`: each DEM cell is the mean of the map
    /// cells under its four quarter centres that are valid, when at least
    /// `min_cells` are; heights relative to C. `holes` applies the
    /// maximum-variance rule and the `min_cells` rule; without it one valid
    /// map cell of any variance is enough (a map that never leaves holes).
    pub fn dem(&self, pose: &Pose, holes: bool) -> Dem {
        let mut dem = empty_dem();
        let q = 0.25 * dem_core::format::CELL;
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                let (mut sum, mut n) = (0.0, 0);
                for (dx, dy) in [(-q, -q), (-q, q), (q, -q), (q, q)] {
                    let (x, y) = pose.to_world(row_center_x(r) + dx, col_center_y(c) + dy);
                    if let Some(k) = self.index(x, y) {
                        let cell = self.cells[k];
                        if cell.var.is_finite() && (!holes || cell.var <= self.cfg.max_variance) {
                            sum += cell.h;
                            n += 1;
                        }
                    }
                }
                if n >= if holes { self.cfg.min_cells } else { 1 } {
                    dem.set_valid(r, c, (sum / n as f64 - pose.z) as f32);
                }
            }
        }
        dem
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> Pose {
        Pose { x: 0.0, y: 0.0, z: 0.07, yaw: 0.0, pitch: 0.0, flippers: [0.0; 4] }
    }

    #[test]
    fn kalman_fusion_averages_by_inverse_variance() {
        let mut m = ElevationMap::new(MapConfig::default(), -1.0, 1.0, -1.0, 1.0);
        m.begin_frame(&pose());
        m.fuse(&Hit { x: 0.51, y: 0.01, z: 0.0, var: 1e-4 });
        m.fuse(&Hit { x: 0.52, y: 0.02, z: 0.01, var: 1e-4 });
        let c = m.cells[m.index(0.51, 0.01).unwrap()];
        assert!((c.h - 0.005).abs() < 1e-12 && (c.var - 5e-5).abs() < 1e-15);
    }

    #[test]
    fn higher_outlier_in_the_same_frame_wins_lower_is_ignored() {
        let mut m = ElevationMap::new(MapConfig::default(), -1.0, 1.0, -1.0, 1.0);
        m.begin_frame(&pose());
        m.fuse(&Hit { x: 0.5, y: 0.0, z: 0.0, var: 1e-6 });
        m.fuse(&Hit { x: 0.5, y: 0.0, z: 0.15, var: 1e-6 });
        m.fuse(&Hit { x: 0.5, y: 0.0, z: -0.1, var: 1e-6 });
        assert_eq!(m.cells[m.index(0.5, 0.0).unwrap()].h, 0.15);
    }

    #[test]
    fn cells_leaving_the_window_are_forgotten() {
        let mut m = ElevationMap::new(MapConfig::default(), -5.0, 5.0, -1.0, 1.0);
        m.begin_frame(&pose());
        m.fuse(&Hit { x: -1.5, y: 0.0, z: 0.0, var: 1e-6 });
        let mut p = pose();
        p.x = 1.0;
        m.begin_frame(&p);
        assert!(m.cells[m.index(-1.5, 0.0).unwrap()].var.is_infinite());
    }

    #[test]
    fn window_follows_grid_map_s_unwrapped_index_on_the_map_s_cell_edges() {
        // A map over x in [-1, 2], y in [-1, 1]: the window runs past its ends.
        let cfg = MapConfig { max_variance: 1e-4, ..MapConfig::default() };
        let mut m = ElevationMap::new(cfg, -1.0, 2.0, -1.0, 1.0);
        let mut p = pose();
        (p.x, p.y) = (0.512, -0.033);
        m.begin_frame(&p);
        m.fuse(&Hit { x: 0.63, y: 0.21, z: 0.25, var: 1e-6 });
        m.fuse(&Hit { x: 0.33, y: -0.41, z: -0.5, var: 2e-4 });
        let w = m.window(&p, true);
        assert_eq!((w.cells, w.resolution), (80, 0.05));
        // The robot's map cell is a = floor(1.512 / 0.05) = 30, b = floor(0.967 / 0.05) = 19:
        // the window spans a = -10..70, b = -21..59, centred on the edge of cells 30 and 29.
        assert!((w.center_x - 0.5).abs() < 1e-12 && (w.center_y - -0.05).abs() < 1e-12, "{} {}", w.center_x, w.center_y);
        let at = |x: f64, y: f64| {
            let i = ((w.center_x + 2.0 - x) / w.resolution).floor() as usize;
            let j = ((w.center_y + 2.0 - y) / w.resolution).floor() as usize;
            (i, j, w.elevation[i * 80 + j], w.variance[i * 80 + j])
        };
        // (0.63, 0.21): map cell (32, 24) -> i = 69 - 32 = 37, j = 58 - 24 = 34.
        assert_eq!(at(0.63, 0.21), (37, 34, 0.25, 1e-6));
        // Variance above the maximum: seen (variance) but no elevation with holes on.
        let (i, j, h, v) = at(0.33, -0.41);
        assert!(h.is_nan() && v == 2e-4 && (i, j) == (43, 47), "{i} {j} {h} {v}");
        assert_eq!(m.window(&p, false).elevation[i * 80 + j], -0.5);
        // Unseen and outside the map (x < -1 is a < 0: i >= 70): NaN in both layers.
        assert!(at(0.0, 0.0).2.is_nan() && at(0.0, 0.0).3.is_nan());
        let outside = at(-1.2, 0.0);
        assert!(outside.0 >= 70 && outside.2.is_nan() && outside.3.is_nan());
        assert_eq!(w.elevation.iter().filter(|h| !h.is_nan()).count(), 1);
        assert_eq!(w.variance.iter().filter(|v| !v.is_nan()).count(), 2);
        // The grid_map centre of the unwrapped cell holds the cell.
        let (ci, cj) = (37.0, 34.0);
        let (cx, cy) = (w.center_x + 2.0 - 0.025 - ci * 0.05, w.center_y + 2.0 - 0.025 - cj * 0.05);
        assert_eq!(m.index(cx, cy), m.index(0.63, 0.21));
    }

    #[test]
    fn dem_needs_two_of_four_map_cells_and_reads_relative_to_c() {
        let mut m = ElevationMap::new(MapConfig::default(), -1.0, 2.0, -1.0, 1.0);
        m.begin_frame(&pose());
        // Row 10 spans x in [0.4, 0.5), column 2 y in [-0.05, 0.05).
        m.fuse(&Hit { x: 0.42, y: 0.02, z: 0.0, var: 1e-6 });
        assert!(!m.dem(&pose(), true).is_valid(10, 2));
        m.fuse(&Hit { x: 0.47, y: -0.03, z: 0.0, var: 1e-6 });
        let d = m.dem(&pose(), true);
        assert!(d.is_valid(10, 2));
        assert!((d.height(10, 2) + 0.07).abs() < 1e-6);
    }
}
