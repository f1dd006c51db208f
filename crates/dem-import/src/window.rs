//! The contract's 20 x 5 window of 10 cm cells, resampled from a map.
//!
//! The window lies in the robot's heading frame: centred on C, x along the
//! robot's heading projected on the ground, y to its left (pitch and roll do
//! not tilt it; row 20 records the pitch). For DEM cell (r, c), an s x s
//! grid of points spaced evenly inside the cell (s = max(2, round(0.1 m /
//! map resolution)): at 5 cm the four quarter centres) is looked up in the
//! map. The cell is valid when at least `min_valid` of the points fall on
//! valid map cells (finite elevation, and variance at most `max_variance`
//! when that is given); its height is the mean of their elevations minus
//! C's height. This is the rule of `dem-synth`'s emulator
//! (`ElevationMap::dem`), so importing its maps gives its measured DEMs.

use dem_core::format::{col_center_y, empty_dem, row_center_x, Dem, DemCells, CELL, COLS, GRID_ROWS};

use crate::geometry::Transform;
use crate::msg::GridMap;

/// How map cells become DEM cells.
#[derive(Clone, Debug, PartialEq)]
pub struct Resampling {
    /// Layer with the heights.
    pub layer: String,
    /// Layer with the height variance, used with `max_variance`.
    pub variance_layer: String,
    /// Map cells with a larger variance count as missing (m^2).
    pub max_variance: Option<f64>,
    /// Share of a DEM cell's sample points that must be valid.
    pub min_valid: f64,
}

impl Default for Resampling {
    fn default() -> Self {
        Resampling { layer: "elevation".into(), variance_layer: "variance".into(), max_variance: None, min_valid: 0.5 }
    }
}

/// Sample points per DEM cell edge for a map of `resolution`.
pub fn samples_per_edge(resolution: f64) -> usize {
    ((CELL / resolution).round() as usize).clamp(2, 64)
}

/// The DEM grid (rows 0..20) of `map` around `base` (the robot's pose in
/// the map's frame); the attitude row is left for the caller. Err names a
/// missing layer.
pub fn resample(map: &GridMap<'_>, base: &Transform, cfg: &Resampling) -> Result<Dem, String> {
    let layers = || map.layers.join(", ");
    let heights = map.layer_named(&cfg.layer).ok_or_else(|| format!("no layer {:?} (the map has: {})", cfg.layer, layers()))?;
    let variance = match cfg.max_variance {
        Some(_) => Some(
            map.layer_named(&cfg.variance_layer)
                .ok_or_else(|| format!("no layer {:?} for --max-variance (the map has: {})", cfg.variance_layer, layers()))?,
        ),
        None => None,
    };
    let (yaw, _) = base.rotation.heading_and_pitch();
    let (sin, cos) = yaw.sin_cos();
    let (bx, by, bz) = (base.translation.x, base.translation.y, base.translation.z);
    let s = samples_per_edge(map.resolution);
    let need = ((cfg.min_valid * (s * s) as f64).ceil() as usize).max(1);
    let offsets: Vec<f64> = (0..s).map(|k| ((k as f64 + 0.5) / s as f64 - 0.5) * CELL).collect();
    let mut dem = empty_dem();
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (cx, cy) = (row_center_x(r), col_center_y(c));
            let (mut sum, mut n) = (0.0f64, 0usize);
            for &dx in &offsets {
                for &dy in &offsets {
                    let (fx, fy) = (cx + dx, cy + dy);
                    let (x, y) = (bx + cos * fx - sin * fy, by + sin * fx + cos * fy);
                    let Some(h) = map.at(&heights, x, y) else { continue };
                    if !h.is_finite() {
                        continue;
                    }
                    if let (Some(v), Some(max)) = (variance, cfg.max_variance) {
                        match map.at(&v, x, y) {
                            Some(var) if var.is_finite() && f64::from(var) <= max => {}
                            _ => continue,
                        }
                    }
                    sum += f64::from(h);
                    n += 1;
                }
            }
            if n >= need {
                dem.set_valid(r, c, (sum / n as f64 - bz) as f32);
            }
        }
    }
    Ok(dem)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Quat, Vec3};
    use crate::wire::Encoding;

    /// A ROS 1 GridMap of one layer "elevation" (column-major), `rows x cols`
    /// cells of 5 cm centred at (cx, cy), value f(i, j) at unwrapped (i, j),
    /// with buffer start (s0, s1).
    pub(crate) fn map_bytes(rows: usize, cols: usize, cx: f64, cy: f64, start: (usize, usize), f: impl Fn(usize, usize) -> f32) -> Vec<u8> {
        let res = 0.05;
        let mut b = Vec::new();
        let s = |b: &mut Vec<u8>, t: &str| {
            b.extend((t.len() as u32).to_le_bytes());
            b.extend(t.as_bytes());
        };
        b.extend(7u32.to_le_bytes()); // seq
        b.extend(100u32.to_le_bytes()); // sec
        b.extend(0u32.to_le_bytes()); // nsec
        s(&mut b, "odom");
        for v in [res, rows as f64 * res, cols as f64 * res, cx, cy, 0.0, 0.0, 0.0, 0.0, 1.0] {
            b.extend(v.to_le_bytes());
        }
        b.extend(1u32.to_le_bytes());
        s(&mut b, "elevation");
        b.extend(0u32.to_le_bytes()); // basic layers
        b.extend(1u32.to_le_bytes()); // data arrays
        b.extend(2u32.to_le_bytes());
        s(&mut b, "column_index");
        b.extend((cols as u32).to_le_bytes());
        b.extend(((rows * cols) as u32).to_le_bytes());
        s(&mut b, "row_index");
        b.extend((rows as u32).to_le_bytes());
        b.extend((rows as u32).to_le_bytes());
        b.extend(0u32.to_le_bytes()); // data_offset
        b.extend(((rows * cols) as u32).to_le_bytes());
        let mut data = vec![0f32; rows * cols];
        for i in 0..rows {
            for j in 0..cols {
                let (bi, bj) = ((i + start.0) % rows, (j + start.1) % cols);
                data[bj * rows + bi] = f(i, j);
            }
        }
        for v in data {
            b.extend(v.to_le_bytes());
        }
        b.extend((start.0 as u16).to_le_bytes());
        b.extend((start.1 as u16).to_le_bytes());
        b
    }

    #[test]
    fn a_wrapped_map_reads_at_grid_map_positions() {
        // 40 x 40 cells centred at (1, 2); unwrapped (i, j) holds i * 100 + j.
        let b = map_bytes(40, 40, 1.0, 2.0, (13, 29), |i, j| (i * 100 + j) as f32);
        let m = GridMap::decode(&b, Encoding::Ros1).unwrap();
        let l = m.layer_named("elevation").unwrap();
        // Cell (0, 0) is the +x, +y corner: x in (1.95, 2.0], y in (2.95, 3.0].
        assert_eq!(m.at(&l, 1.99, 2.99), Some(0.0));
        assert_eq!(m.at(&l, 1.99 - 0.05 * 3.0, 2.99 - 0.05 * 5.0), Some(305.0));
        assert_eq!(m.at(&l, 0.01, 1.01), Some(3939.0));
        assert_eq!(m.at(&l, 2.01, 2.0), None);
    }

    #[test]
    fn flat_ground_reads_minus_c_and_holes_follow_the_share_rule() {
        // Ground at z = 0 except NaN for x > 1.0 in the map (ahead of row 15).
        let b = map_bytes(80, 80, 0.0, 0.0, (5, 7), |i, _| if 2.0 - 0.05 * (i as f64 + 0.5) > 1.0 { f32::NAN } else { 0.0 });
        let m = GridMap::decode(&b, Encoding::Ros1).unwrap();
        let base = Transform { translation: Vec3::new(0.0, 0.0, 0.07), rotation: Quat::IDENTITY };
        let d = resample(&m, &base, &Resampling::default()).unwrap();
        assert!((d.height(0, 0) + 0.07).abs() < 1e-7 && d.is_valid(15, 2));
        assert!(!d.is_valid(16, 2) && !d.is_valid(19, 4));
        let e = resample(&m, &base, &Resampling { layer: "height".into(), ..Resampling::default() }).unwrap_err();
        assert!(e.contains("no layer \"height\"") && e.contains("elevation"), "{e}");
    }
}
