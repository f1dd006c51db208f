//! The robot's motion as the sensor suffers it: where the camera truly is
//! and looks, and where the elevation map believes it is.
//!
//! Four stages of the emulator act here, each through the rays, the poses
//! or the map, never on the DEM:
//!
//! - `drift`: the pose the map believes is the true pose plus an error
//!   ([`Drift`]) that walks at random per metre travelled, faster while the
//!   tracks ride on edges ([`edge_under_tracks`]).
//! - `latency`: the frame handed out at time t was taken L seconds earlier
//!   (run.rs rests the robot at the trajectory point L seconds back).
//! - `extrinsic`: the camera's true pitch and roll on its mount differ from
//!   the nominal ones, fixed per run ([`CameraError::mount_pitch`]).
//! - `vibration`: per frame the body's true pitch and roll differ from the
//!   estimated attitude ([`CameraError::body_pitch`]), more on edges
//!   ([`vibration_sd`]).
//!
//! Rays are cast from the true camera ([`camera_pose`] with the errors);
//! the map registers each hit as the point at the same place in the camera
//! frame of the believed camera ([`registration`]).

use super::camera_config::CameraConfig;
use super::pose::{track_profile, Pose};
use super::terrain::World;

/// A 3x3 rotation, rows first.
pub type Mat3 = [[f64; 3]; 3];

/// A rigid transform p -> r p + t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    /// Rotation.
    pub r: Mat3,
    /// Translation.
    pub t: [f64; 3],
}

fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    m
}

fn mul_v(a: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| a[i][0] * v[0] + a[i][1] * v[1] + a[i][2] * v[2])
}

fn transpose(a: &Mat3) -> Mat3 {
    [0, 1, 2].map(|i| [a[0][i], a[1][i], a[2][i]])
}

/// Rotation about z by `a` (yaw, counter-clockwise).
pub fn rot_z(a: f64) -> Mat3 {
    let (s, c) = a.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// Pitch by `a`, nose up positive: x turns toward +z (the pose's convention).
pub fn rot_pitch(a: f64) -> Mat3 {
    let (s, c) = a.sin_cos();
    [[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]
}

/// Roll by `a` about x, right-handed: the left side (+y) goes up.
pub fn rot_roll(a: f64) -> Mat3 {
    let (s, c) = a.sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
}

impl Rigid {
    /// The transform of a point.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let q = mul_v(&self.r, p);
        [q[0] + self.t[0], q[1] + self.t[1], q[2] + self.t[2]]
    }

    /// The rotation alone (a direction).
    pub fn turn(&self, d: [f64; 3]) -> [f64; 3] {
        mul_v(&self.r, d)
    }

    /// `self` after `other`: p -> self(other(p)).
    pub fn then_from(&self, other: &Rigid) -> Rigid {
        Rigid { r: mul(&self.r, &other.r), t: self.apply(other.t) }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Rigid {
        let r = transpose(&self.r);
        let t = mul_v(&r, self.t);
        Rigid { r, t: [-t[0], -t[1], -t[2]] }
    }
}

/// Errors of the camera's orientation (rad): the body's true pitch and roll
/// against the estimated attitude (vibration), the mount's true pitch and
/// roll against the nominal extrinsics (extrinsic). Zero: the nominal camera.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CameraError {
    /// True body pitch minus the estimated (nose up positive).
    pub body_pitch: f64,
    /// True body roll (the estimate has none; left side up positive).
    pub body_roll: f64,
    /// True mount pitch minus the nominal (optical axis up positive).
    pub mount_pitch: f64,
    /// True mount roll minus the nominal.
    pub mount_roll: f64,
}

impl CameraError {
    /// True when every error is exactly zero.
    pub fn is_zero(&self) -> bool {
        *self == CameraError::default()
    }
}

/// World from camera frame (x the optical axis, y left, z up in the image)
/// of a robot at `pose` whose camera has the errors `err`: the body at C
/// turned by yaw, pitch + body_pitch and body_roll; the camera at
/// (forward, 0, height) in the body, tilted down by the mount's tilt less
/// mount_pitch, rolled by mount_roll.
pub fn camera_pose(pose: &Pose, cfg: &CameraConfig, err: &CameraError) -> Rigid {
    let body = Rigid {
        r: mul(&mul(&rot_z(pose.yaw), &rot_pitch(pose.pitch + err.body_pitch)), &rot_roll(err.body_roll)),
        t: [pose.x, pose.y, pose.z],
    };
    let mount = Rigid {
        r: mul(&rot_pitch(err.mount_pitch - cfg.tilt_deg.to_radians()), &rot_roll(err.mount_roll)),
        t: [cfg.forward, 0.0, cfg.height],
    };
    body.then_from(&mount)
}

/// Where the map puts a point the true camera measured: the same place in
/// the camera frame, seen from the camera the map believes in (the
/// believed pose, the estimated attitude, the nominal mount). World to
/// world: believed camera after the inverse of the true one.
pub fn registration(truth: &Pose, err: &CameraError, believed: &Pose, cfg: &CameraConfig) -> Rigid {
    let true_cam = camera_pose(truth, cfg, err);
    let map_cam = camera_pose(believed, cfg, &CameraError::default());
    map_cam.then_from(&true_cam.inverse())
}

/// The largest height step (m) between neighbouring terrain samples 1 cm
/// apart along the tracks' footprint (0.7 m long, the highest point across
/// the gauge, as [`Pose::rest_on`] samples it): a stair edge or the edge of
/// a pallet or of its boards under the tracks; 0 on flat ground, below
/// 1 cm on ramps and rubble.
pub fn edge_under_tracks(world: &World, pose: &Pose) -> f64 {
    track_profile(world, pose).windows(2).map(|w| (w[1].1 - w[0].1).abs()).fold(0.0, f64::max)
}

/// Height step under the tracks (m) above which they ride on an edge: the
/// drift's slip factor applies.
pub const SLIP_EDGE: f64 = 0.03;

/// Pose drift: a random walk per metre travelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftConfig {
    /// Horizontal sigma, each of x and y (m per sqrt(m) travelled).
    pub horizontal: f64,
    /// Vertical sigma (m per sqrt(m)).
    pub vertical: f64,
    /// Yaw sigma (rad per sqrt(m)).
    pub yaw: f64,
    /// Factor on the sigmas while the tracks ride on an edge
    /// ([`edge_under_tracks`] above [`SLIP_EDGE`]).
    pub slip: f64,
    /// The error at the first frame (x, y, z, yaw); zero in dem-synth.
    pub initial: [f64; 4],
}

impl Default for DriftConfig {
    fn default() -> Self {
        DriftConfig { horizontal: 0.02, vertical: 0.005, yaw: 0.6f64.to_radians(), slip: 3.0, initial: [0.0; 4] }
    }
}

/// The believed-pose error of one run (world x, y, z and yaw).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drift {
    /// Current error (x, y, z, yaw).
    pub error: [f64; 4],
}

impl Drift {
    /// One step of the walk over `ds` metres travelled, with `slip` (1 on
    /// even ground) and four standard normal draws `n`: each component
    /// moves by sigma * slip * sqrt(ds) * n.
    pub fn advance(&mut self, cfg: &DriftConfig, ds: f64, slip: f64, n: [f64; 4]) {
        let s = slip * ds.max(0.0).sqrt();
        let sig = [cfg.horizontal, cfg.horizontal, cfg.vertical, cfg.yaw];
        for k in 0..4 {
            self.error[k] += sig[k] * s * n[k];
        }
    }

    /// The pose the map believes: `truth` with the error added to x, y, z
    /// and yaw (attitude and flippers are proprioceptive: unchanged).
    pub fn believed(&self, truth: &Pose) -> Pose {
        let e = self.error;
        Pose { x: truth.x + e[0], y: truth.y + e[1], z: truth.z + e[2], yaw: truth.yaw + e[3], ..*truth }
    }
}

/// Vibration: the sd of the body's pitch and roll against the estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VibrationConfig {
    /// Sd on even ground (rad).
    pub flat: f64,
    /// Extra sd per metre of height step under the tracks (rad per m).
    pub per_edge: f64,
}

impl Default for VibrationConfig {
    fn default() -> Self {
        VibrationConfig { flat: 0.1f64.to_radians(), per_edge: 4f64.to_radians() }
    }
}

/// The sd (rad) of the body's pitch and roll errors with a height step of
/// `edge` metres under the tracks: flat + per_edge * edge.
pub fn vibration_sd(cfg: &VibrationConfig, edge: f64) -> f64 {
    cfg.flat + cfg.per_edge * edge
}

#[cfg(test)]
mod tests {
    use super::super::terrain::Shape;
    use super::*;
    use dem_core::format::Terrain;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < 1e-12)
    }

    fn pose() -> Pose {
        Pose { x: 1.0, y: -0.5, z: 0.3, yaw: 0.4, pitch: 0.1, flippers: [0.0; 4] }
    }

    #[test]
    fn rotations_turn_the_right_way() {
        assert!(close(mul_v(&rot_z(std::f64::consts::FRAC_PI_2), [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0]));
        assert!(close(mul_v(&rot_pitch(std::f64::consts::FRAC_PI_2), [1.0, 0.0, 0.0]), [0.0, 0.0, 1.0]));
        assert!(close(mul_v(&rot_roll(std::f64::consts::FRAC_PI_2), [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]));
    }

    #[test]
    fn a_rigid_transform_and_its_inverse_cancel() {
        let a = Rigid { r: mul(&rot_z(0.3), &rot_pitch(-0.2)), t: [1.0, 2.0, 3.0] };
        let b = Rigid { r: rot_roll(0.7), t: [-0.5, 0.1, 0.0] };
        let p = [0.3, -1.2, 0.8];
        assert!(close(a.inverse().apply(a.apply(p)), p));
        assert!(close(a.then_from(&b).apply(p), a.apply(b.apply(p))));
    }

    #[test]
    fn camera_pose_without_errors_is_the_mount_on_the_pitched_yawed_body() {
        let cfg = CameraConfig::default();
        let p = pose();
        let cam = camera_pose(&p, &cfg, &CameraError::default());
        // Origin: (forward, height) pitched, then yawed, from C.
        let (sp, cp) = p.pitch.sin_cos();
        let (fx, fz) = (cfg.forward * cp - cfg.height * sp, cfg.forward * sp + cfg.height * cp);
        let (wx, wy) = p.to_world(fx, 0.0);
        assert!(close(cam.t, [wx, wy, p.z + fz]));
        // Optical axis: pitch - tilt below the horizon, along the yaw.
        let a = p.pitch - cfg.tilt_deg.to_radians();
        let d = cam.turn([1.0, 0.0, 0.0]);
        assert!(close(d, [a.cos() * p.yaw.cos(), a.cos() * p.yaw.sin(), a.sin()]));
        // A mount pitch error turns the axis up by as much.
        let up = camera_pose(&p, &cfg, &CameraError { mount_pitch: 0.01, ..CameraError::default() }).turn([1.0, 0.0, 0.0]);
        assert!((up[2].asin() - (a + 0.01)).abs() < 1e-12);
    }

    #[test]
    fn registration_is_the_identity_without_errors_and_tilts_with_a_mount_error() {
        let cfg = CameraConfig::default();
        let p = pose();
        let id = registration(&p, &CameraError::default(), &p, &cfg);
        assert!(close(id.apply([2.0, 0.3, -0.1]), [2.0, 0.3, -0.1]));
        // A camera truly pitched up by e: the map puts a point seen at
        // distance r along the axis lower by about r tan(e).
        let flat = Pose { yaw: 0.0, pitch: 0.0, ..p };
        let e = 0.01;
        let reg = registration(&flat, &CameraError { mount_pitch: e, ..CameraError::default() }, &flat, &cfg);
        let cam = camera_pose(&flat, &cfg, &CameraError { mount_pitch: e, ..CameraError::default() });
        let seen = cam.apply([2.0, 0.0, 0.0]);
        let put = reg.apply(seen);
        let ahead = ((seen[0] - cam.t[0]).powi(2) + (seen[1] - cam.t[1]).powi(2)).sqrt();
        assert!(((seen[2] - put[2]) - ahead * e.tan()).abs() < 2e-4, "{seen:?} {put:?}");
        // A pure position error moves every point by it.
        let off = Pose { x: p.x + 0.1, z: p.z - 0.02, ..p };
        let moved = registration(&p, &CameraError::default(), &off, &cfg).apply([2.0, 0.3, -0.1]);
        assert!(close(moved, [2.1, 0.3, -0.12]));
    }

    #[test]
    fn edges_under_the_tracks_are_stair_rises_and_none_on_flat_ground() {
        let stairs =
            World { terrain: Terrain::StairsUp, shape: Shape::Stairs { x0: 1.0, rise: 0.17, run: 0.3, steps: 6 }, dark_patches: vec![] };
        let flat = World { terrain: Terrain::Flat, shape: Shape::Flat, dark_patches: vec![] };
        let on = Pose::rest_on(&stairs, 1.5, 0.0, 0.0);
        assert!((edge_under_tracks(&stairs, &on) - 0.17).abs() < 1e-9);
        assert_eq!(edge_under_tracks(&flat, &Pose::rest_on(&flat, 0.0, 0.0, 0.0)), 0.0);
        // Far before the first step: no edge under the tracks.
        assert_eq!(edge_under_tracks(&stairs, &Pose::rest_on(&stairs, 0.0, 0.0, 0.0)), 0.0);
        let ramp = World { terrain: Terrain::Other, shape: Shape::Ramp { x0: 0.0, slope: 0.45, length: 2.0 }, dark_patches: vec![] };
        assert!(edge_under_tracks(&ramp, &Pose::rest_on(&ramp, 0.5, 0.0, 0.0)) < SLIP_EDGE);
    }

    #[test]
    fn drift_walks_by_sigma_sqrt_distance_and_slip() {
        let cfg = DriftConfig::default();
        let mut d = Drift { error: [0.0; 4] };
        d.advance(&cfg, 4.0, 1.0, [1.0, -1.0, 2.0, 0.5]);
        assert!((d.error[0] - 0.04).abs() < 1e-12 && (d.error[1] + 0.04).abs() < 1e-12);
        assert!((d.error[2] - 0.02).abs() < 1e-12 && (d.error[3] - cfg.yaw).abs() < 1e-12);
        d.advance(&cfg, 1.0, 3.0, [1.0, 0.0, 0.0, 0.0]);
        assert!((d.error[0] - 0.1).abs() < 1e-12);
        let b = d.believed(&pose());
        assert!((b.x - 1.1).abs() < 1e-12 && b.pitch == 0.1 && (b.z - 0.32).abs() < 1e-12);
    }

    #[test]
    fn vibration_grows_with_the_edge_under_the_tracks() {
        let cfg = VibrationConfig::default();
        assert_eq!(vibration_sd(&cfg, 0.0), cfg.flat);
        assert!((vibration_sd(&cfg, 0.17) - (0.1 + 4.0 * 0.17f64).to_radians()).abs() < 1e-12);
    }
}
