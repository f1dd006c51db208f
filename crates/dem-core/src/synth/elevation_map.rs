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
use crate::format::{col_center_y, empty_dem, row_center_x, Dem, DemCells, COLS, GRID_ROWS};

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

#[derive(Clone, Copy)]
struct Cell {
    h: f64,
    var: f64,
    frame: u32,
}

const EMPTY: Cell = Cell { h: 0.0, var: f64::INFINITY, frame: 0 };

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
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .then(|| i as usize * self.ny + j as usize)
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

    /// The 10 cm DEM around `pose`: each DEM cell is the mean of the map
    /// cells under its four quarter centres that are valid, when at least
    /// `min_cells` are; heights relative to C. `holes` applies the
    /// maximum-variance rule and the `min_cells` rule; without it one valid
    /// map cell of any variance is enough (a map that never leaves holes).
    pub fn dem(&self, pose: &Pose, holes: bool) -> Dem {
        let mut dem = empty_dem();
        let q = 0.25 * crate::format::CELL;
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
