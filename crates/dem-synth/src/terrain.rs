//! Terrain height fields of the synthetic world, in world metres.
//!
//! The robot drives along +x; every obstacle spans the full width of the
//! local map unless it is a pallet, which is finite in y. Ground level is
//! z = 0. Heights are exact, so the simulator's DEM samples them directly and
//! the sensor emulator ray-casts into them.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use dem_core::format::Terrain;

/// Height of a top deck board of a pallet (a EUR pallet is 0.144 m tall).
pub const PALLET_HEIGHT: f64 = 0.144;
/// Height seen through the gaps between top boards: the bottom deck boards.
pub const PALLET_GAP_HEIGHT: f64 = 0.022;

/// One run's terrain: a kind with its random parameters.
#[derive(Debug, Clone)]
pub struct World {
    /// The terrain class written to the labels.
    pub terrain: Terrain,
    /// The shape.
    pub shape: Shape,
    /// Dark or reflective patches (discs: x, y, radius) that return nothing.
    pub dark_patches: Vec<[f64; 3]>,
}

/// Shapes of terrain the world builds from.
#[derive(Debug, Clone)]
pub enum Shape {
    /// Level ground at z = 0.
    Flat,
    /// `steps` steps of `rise` (positive up, negative down) and `run`
    /// (tread depth), the first edge at `x0`.
    Stairs {
        /// First edge along x.
        x0: f64,
        /// Height change per step (negative: stairs down).
        rise: f64,
        /// Tread depth.
        run: f64,
        /// Number of steps.
        steps: u32,
    },
    /// A pallet from `x0` to `x0 + length`, centred at `y0`, `width` wide,
    /// its top deck made of boards across x with gaps between them.
    Pallet {
        /// Near edge along x.
        x0: f64,
        /// Centre across.
        y0: f64,
        /// Extent along x.
        length: f64,
        /// Extent along y.
        width: f64,
        /// Board width along x.
        board: f64,
        /// Gap between boards along x.
        gap: f64,
    },
    /// A ramp rising with `slope` from `x0` for `length`, then a plateau.
    Ramp {
        /// Foot of the ramp.
        x0: f64,
        /// Rise per metre.
        slope: f64,
        /// Run of the ramp.
        length: f64,
    },
    /// Rubble: Gaussian bumps (x, y, height, radius) on the ground.
    Rubble {
        /// The bumps.
        bumps: Vec<[f64; 4]>,
    },
}

impl World {
    /// Draw a world of class `terrain` whose obstacle starts near `x_obstacle`.
    pub fn random(terrain: Terrain, x_obstacle: f64, patch_density: f64, rng: &mut ChaCha8Rng) -> World {
        let shape = match terrain {
            Terrain::Flat => Shape::Flat,
            Terrain::StairsUp | Terrain::StairsDown => {
                let rise = rng.gen_range(0.14..0.20);
                Shape::Stairs {
                    x0: x_obstacle,
                    rise: if terrain == Terrain::StairsUp { rise } else { -rise },
                    run: rng.gen_range(0.25..0.33),
                    steps: rng.gen_range(4..9),
                }
            }
            Terrain::Pallet => {
                // EUR (1.2 x 0.8) or industrial (1.2 x 1.0) pallets, either way round.
                let (a, b) = if rng.gen_bool(0.5) { (1.2, 0.8) } else { (1.2, 1.0) };
                let (length, width) = if rng.gen_bool(0.5) { (a, b) } else { (b, a) };
                Shape::Pallet {
                    x0: x_obstacle,
                    y0: rng.gen_range(-0.2..0.2),
                    length,
                    width,
                    board: rng.gen_range(0.09..0.145),
                    gap: rng.gen_range(0.035..0.06),
                }
            }
            Terrain::Other => {
                if rng.gen_bool(0.5) {
                    Shape::Ramp { x0: x_obstacle, slope: rng.gen_range(0.15..0.45), length: rng.gen_range(0.8..2.0) }
                } else {
                    let n = rng.gen_range(8..20);
                    let bumps = (0..n)
                        .map(|_| {
                            [
                                x_obstacle + rng.gen_range(0.0..2.5),
                                rng.gen_range(-1.0..1.0),
                                rng.gen_range(0.03..0.15),
                                rng.gen_range(0.05..0.2),
                            ]
                        })
                        .collect();
                    Shape::Rubble { bumps }
                }
            }
        };
        let area = 8.0 * 4.0;
        let n = rng_poisson(patch_density * area, rng);
        let dark_patches =
            (0..n).map(|_| [x_obstacle + rng.gen_range(-4.0..4.0), rng.gen_range(-2.0..2.0), rng.gen_range(0.04..0.15)]).collect();
        World { terrain, shape, dark_patches }
    }

    /// Height of the terrain at (x, y).
    pub fn height(&self, x: f64, y: f64) -> f64 {
        match &self.shape {
            Shape::Flat => 0.0,
            Shape::Stairs { x0, rise, run, steps } => {
                if x < *x0 {
                    0.0
                } else {
                    let k = (((x - x0) / run).floor() as u32 + 1).min(*steps);
                    rise * k as f64
                }
            }
            Shape::Pallet { x0, y0, length, width, board, gap } => {
                if x < *x0 || x >= x0 + length || (y - y0).abs() > width / 2.0 {
                    0.0
                } else {
                    // Boards start at the near edge: board, gap, board, ...;
                    // the far edge is always a board.
                    let u = (x - x0) % (board + gap);
                    if u < *board || x0 + length - x < *board {
                        PALLET_HEIGHT
                    } else {
                        PALLET_GAP_HEIGHT
                    }
                }
            }
            Shape::Ramp { x0, slope, length } => slope * (x - x0).clamp(0.0, *length),
            Shape::Rubble { bumps } => bumps
                .iter()
                .map(|[bx, by, h, r]| {
                    let d2 = (x - bx).powi(2) + (y - by).powi(2);
                    h * (-d2 / (2.0 * r * r)).exp()
                })
                .fold(0.0, f64::max),
        }
    }

    /// Where the obstacle ends along x (the run drives past it).
    pub fn obstacle_end(&self, x_obstacle: f64) -> f64 {
        match &self.shape {
            Shape::Flat => x_obstacle + 1.0,
            Shape::Stairs { run, steps, .. } => x_obstacle + run * *steps as f64,
            Shape::Pallet { length, .. } => x_obstacle + length,
            Shape::Ramp { length, .. } => x_obstacle + length,
            Shape::Rubble { .. } => x_obstacle + 2.5,
        }
    }

    /// True when (x, y) lies on a dark or reflective patch.
    pub fn is_dark(&self, x: f64, y: f64) -> bool {
        self.dark_patches.iter().any(|[px, py, r]| (x - px).powi(2) + (y - py).powi(2) < r * r)
    }
}

/// Poisson draw by inversion (small means only).
fn rng_poisson(mean: f64, rng: &mut ChaCha8Rng) -> usize {
    let (l, mut k, mut p) = ((-mean).exp(), 0, 1.0);
    loop {
        p *= rng.gen::<f64>();
        if p <= l || k > 10_000 {
            return k;
        }
        k += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world(shape: Shape) -> World {
        World { terrain: Terrain::Other, shape, dark_patches: vec![] }
    }

    #[test]
    fn stairs_count_steps_from_the_first_edge() {
        let w = world(Shape::Stairs { x0: 1.0, rise: 0.17, run: 0.3, steps: 3 });
        assert_eq!(w.height(0.99, 0.0), 0.0);
        assert!((w.height(1.0, 0.0) - 0.17).abs() < 1e-12);
        assert!((w.height(1.31, 0.0) - 0.34).abs() < 1e-12);
        assert!((w.height(9.0, 0.0) - 0.51).abs() < 1e-12);
    }

    #[test]
    fn pallet_top_has_gaps_between_boards() {
        let w = world(Shape::Pallet { x0: 1.0, y0: 0.0, length: 1.2, width: 0.8, board: 0.1, gap: 0.05 });
        assert_eq!(w.height(1.05, 0.0), PALLET_HEIGHT);
        assert_eq!(w.height(1.12, 0.0), PALLET_GAP_HEIGHT);
        assert_eq!(w.height(2.15, 0.0), PALLET_HEIGHT); // far edge board
        assert_eq!(w.height(1.05, 0.5), 0.0); // beside the pallet
        assert_eq!(w.height(2.3, 0.0), 0.0);
    }
}
