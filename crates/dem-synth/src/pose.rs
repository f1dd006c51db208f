//! Where a tracked robot rests on the terrain: position, heading, pitch,
//! height of its centre C, and flipper angles.
//!
//! A rigid body under gravity rests on the upper convex hull of the terrain
//! under its tracks: the hull segment above C is the track line. Its slope
//! is the pitch; C sits [`C_ABOVE_TRACK`] above it (flat ground reads -0.07
//! in the DEM, as the contract says).

use super::terrain::World;

/// Height of C above the track contact line.
pub const C_ABOVE_TRACK: f64 = 0.07;
/// Track length (contact with the ground), centred on C.
pub const TRACK_LENGTH: f64 = 0.7;
/// Flipper length; the pivots sit at the track ends.
pub const FLIPPER_LENGTH: f64 = 0.35;
/// Half the distance between the two tracks.
pub const TRACK_HALF_GAUGE: f64 = 0.2;

/// A robot pose in the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Position of C along world x.
    pub x: f64,
    /// Position of C along world y.
    pub y: f64,
    /// Height of C.
    pub z: f64,
    /// Heading (rad, counter-clockwise from +x).
    pub yaw: f64,
    /// Pitch (rad, nose up positive).
    pub pitch: f64,
    /// Flipper angles front-left, front-right, rear-left, rear-right (rad,
    /// positive = tip raised above the track line).
    pub flippers: [f64; 4],
}

impl Pose {
    /// World (x, y) of a point given in the robot's yawed frame (x ahead, y left).
    pub fn to_world(&self, fx: f64, fy: f64) -> (f64, f64) {
        let (s, c) = self.yaw.sin_cos();
        (self.x + c * fx - s * fy, self.y + s * fx + c * fy)
    }

    /// Rest the robot at (x, y) with heading `yaw` on `world`.
    pub fn rest_on(world: &World, x: f64, y: f64, yaw: f64) -> Pose {
        let mut pose = Pose { x, y, z: 0.0, yaw, pitch: 0.0, flippers: [0.0; 4] };
        // Terrain profile under the tracks: highest point across the gauge.
        let half = TRACK_LENGTH / 2.0;
        let profile = track_profile(world, &pose);
        let hull = upper_hull(&profile);
        let seg = hull.windows(2).find(|w| w[0].0 <= 0.0 && w[1].0 >= 0.0).expect("hull spans C");
        let (a, b) = (seg[0], seg[1]);
        let slope = (b.1 - a.1) / (b.0 - a.0);
        let track_z = a.1 + slope * (0.0 - a.0);
        pose.pitch = slope.atan();
        pose.z = track_z + C_ABOVE_TRACK;
        // Flippers reach for the terrain ahead of the front pivot and behind
        // the rear one, as an operator (or a controller) sets them.
        let reach = |fx: f64, dir: f64| -> f64 {
            let tip = fx + dir * FLIPPER_LENGTH * 0.8;
            let (wx, wy) = pose.to_world(tip, 0.0);
            let pivot_z = track_z + slope * fx;
            let line_z = pivot_z + slope * (tip - fx);
            ((world.height(wx, wy) - line_z) / FLIPPER_LENGTH).clamp(-0.9, 0.9).asin()
        };
        let (front, rear) = (reach(half, 1.0), reach(-half, -1.0));
        pose.flippers = [front, front, rear, rear];
        pose
    }
}

/// Samples along the tracks' footprint under `pose`.
const TRACK_SAMPLES: usize = 71;

/// The terrain under the tracks: (x ahead of C, the highest point across the
/// gauge) at [`TRACK_SAMPLES`] points 1 cm apart along the track length,
/// from the rear end to the front (position and yaw of `pose` only).
pub fn track_profile(world: &World, pose: &Pose) -> Vec<(f64, f64)> {
    let n = TRACK_SAMPLES;
    let half = TRACK_LENGTH / 2.0;
    (0..n)
        .map(|i| {
            let fx = -half + TRACK_LENGTH * i as f64 / (n - 1) as f64;
            let h = [-TRACK_HALF_GAUGE, 0.0, TRACK_HALF_GAUGE]
                .iter()
                .map(|&fy| {
                    let (wx, wy) = pose.to_world(fx, fy);
                    world.height(wx, wy)
                })
                .fold(f64::MIN, f64::max);
            (fx, h)
        })
        .collect()
}

/// Upper convex hull of points sorted by x (Andrew's monotone chain).
fn upper_hull(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut hull: Vec<(f64, f64)> = Vec::with_capacity(points.len());
    for &p in points {
        while hull.len() >= 2 {
            let (o, a) = (hull[hull.len() - 2], hull[hull.len() - 1]);
            let cross = (a.0 - o.0) * (p.1 - o.1) - (a.1 - o.1) * (p.0 - o.0);
            if cross >= 0.0 {
                hull.pop();
            } else {
                break;
            }
        }
        hull.push(p);
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::super::terrain::{Shape, World};
    use super::*;
    use dem_core::format::Terrain;

    fn stairs(rise: f64) -> World {
        World { terrain: Terrain::StairsUp, shape: Shape::Stairs { x0: 1.0, rise, run: 0.3, steps: 6 }, dark_patches: vec![] }
    }

    #[test]
    fn flat_ground_puts_c_seven_cm_up_and_level() {
        let w = World { terrain: Terrain::Flat, shape: Shape::Flat, dark_patches: vec![] };
        let p = Pose::rest_on(&w, 0.0, 0.0, 0.3);
        assert!((p.z - C_ABOVE_TRACK).abs() < 1e-12 && p.pitch.abs() < 1e-12);
    }

    #[test]
    fn climbing_stairs_pitches_nose_up_along_the_nosings() {
        let p = Pose::rest_on(&stairs(0.17), 2.0, 0.0, 0.0);
        let expected = (0.17f64 / 0.3).atan();
        assert!((p.pitch - expected).abs() < 0.05, "{}", p.pitch);
        let down = Pose::rest_on(&stairs(-0.17), 2.0, 0.0, 0.0);
        assert!(down.pitch < -0.4);
    }

    #[test]
    fn far_from_the_stairs_the_robot_is_level() {
        let p = Pose::rest_on(&stairs(0.17), 0.0, 0.0, 0.0);
        assert!(p.pitch.abs() < 1e-12);
        // Front flippers reach up toward the first step only when it is near.
        let near = Pose::rest_on(&stairs(0.17), 0.55, 0.0, 0.0);
        assert!(near.flippers[0] > 0.1, "{:?}", near.flippers);
    }
}
