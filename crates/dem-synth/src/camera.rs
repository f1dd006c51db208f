//! A RealSense-like depth camera on the robot, ray-cast into the height field.
//!
//! Each frame casts one ray per depth pixel (the pixel position jittered
//! inside the pixel, so successive frames sample between each other) and
//! returns the points it measured with their height variance. The stages of
//! [`Stages`] switch the physical effects on and off one by one:
//!
//! - `fov`: only pixel rays within the field of view and the depth cutoffs
//!   (0.35 to 3.0 m) measure; off, the camera casts the same rays without
//!   the cutoffs and also looks, from where it is and at any range, at every
//!   5 cm cell of the DEM footprint outside their cone, so the cells in view
//!   get the same points with the stage on or off.
//! - `occlusion`: a ray stops at the first surface it meets; off, it passes
//!   through and measures every surface it crosses downward, so terrain
//!   behind a pallet or below a stair edge is seen too.
//! - `noise`: range noise sigma_r = a + b (z - c)^2 along the ray (z the depth
//!   along the optical axis; ZR300 defaults of elevation_mapping) and lateral
//!   noise sigma_l = l z across it.
//! - `smoothing`: stereo matching averages depth over a correlation window:
//!   the range is the mean over the pixel ray and two rays half a window
//!   above and below it, which turns step edges and kinks into ramps; where
//!   the window straddles a depth jump the matcher's consistency check
//!   rejects the pixel, which widens shadows and blind bands.
//! - `dropout`: dark or reflective patches of the world return nothing.
//!
//! The height variance handed to the map is the vertical part of the point's
//! covariance: var_z = sigma_r^2 d_z^2 + sigma_l^2 (1 - d_z^2), d the unit ray.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

pub use super::camera_config::CameraConfig;
use super::motion::{camera_pose, CameraError, Mat3};
use super::pose::Pose;
use super::terrain::World;
use dem_core::format::{col_center_y, row_center_x, COLS, GRID_ROWS};

/// Which physical effects the emulator applies (all on by default).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stages {
    /// Field of view and depth cutoffs.
    pub fov: bool,
    /// First surface hides what lies behind it.
    pub occlusion: bool,
    /// Range and lateral noise.
    pub noise: bool,
    /// Stereo window averaging (edges to ramps, flying pixels).
    pub smoothing: bool,
    /// Dark patches return nothing.
    pub dropout: bool,
    /// Map cells whose variance stays above the maximum become holes.
    pub holes: bool,
    /// The map believes a pose that drifts from the true one per metre
    /// travelled (see [`motion`](super::motion)).
    pub drift: bool,
    /// The DEM handed out is that of the frame taken a latency earlier.
    pub latency: bool,
    /// The camera's true pitch and roll on its mount differ from the nominal.
    pub extrinsic: bool,
    /// The body's true pitch and roll differ from the estimate every frame.
    pub vibration: bool,
    /// The map keeps its cells from one frame to the next (off: each DEM
    /// is the fusion of its own frame's points alone).
    pub memory: bool,
}

impl Default for Stages {
    fn default() -> Self {
        Stages {
            fov: true,
            occlusion: true,
            noise: true,
            smoothing: true,
            dropout: true,
            holes: true,
            drift: true,
            latency: true,
            extrinsic: true,
            vibration: true,
            memory: true,
        }
    }
}

impl Stages {
    /// The six sensor stages on, the four motion stages (drift, latency,
    /// extrinsic, vibration) off: the emulator as `testdata/` was made.
    pub fn sensor_only() -> Self {
        Stages { drift: false, latency: false, extrinsic: false, vibration: false, ..Stages::default() }
    }
}

/// A measured point with the variance of its height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// World x.
    pub x: f64,
    /// World y.
    pub y: f64,
    /// World z.
    pub z: f64,
    /// Variance of z (m^2).
    pub var: f64,
}

/// March step along a ray (m): below the narrowest pallet gap.
const STEP: f64 = 0.012;

/// Ray parameters t where the ray `o + t d` crosses the terrain downward
/// (from above to below), up to `t_max`; only the first when `first_only`.
pub fn crossings(world: &World, o: [f64; 3], d: [f64; 3], t_max: f64, first_only: bool, out: &mut Vec<f64>) {
    out.clear();
    let above = |t: f64| o[2] + t * d[2] - world.height(o[0] + t * d[0], o[1] + t * d[1]);
    let mut t0 = 0.0;
    let mut f0 = above(0.0);
    while t0 < t_max {
        let t1 = (t0 + STEP).min(t_max);
        let f1 = above(t1);
        if f0 > 0.0 && f1 <= 0.0 {
            // Bisect to well below a millimetre.
            let (mut lo, mut hi) = (t0, t1);
            for _ in 0..8 {
                let mid = 0.5 * (lo + hi);
                if above(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            out.push(hi);
            if first_only {
                return;
            }
        }
        t0 = t1;
        f0 = f1;
    }
}

/// The camera of one frame: where it is and where it looks.
struct Frame {
    origin: [f64; 3],
    /// Optical axis pitch (rad, up positive) and yaw.
    pitch: f64,
    yaw: f64,
    /// World from camera rotation when the camera has orientation errors
    /// (roll makes pitch and yaw alone insufficient); None: pitch and yaw.
    rot: Option<Mat3>,
}

impl Frame {
    fn new(pose: &Pose, cfg: &CameraConfig) -> Frame {
        let (sp, cp) = pose.pitch.sin_cos();
        let fx = cfg.forward * cp - cfg.height * sp;
        let fz = cfg.forward * sp + cfg.height * cp;
        let (wx, wy) = pose.to_world(fx, 0.0);
        Frame { origin: [wx, wy, pose.z + fz], pitch: pose.pitch - cfg.tilt_deg.to_radians(), yaw: pose.yaw, rot: None }
    }

    /// The camera of a robot at `pose` with orientation errors `err`
    /// (exactly [`Frame::new`] when they are all zero).
    fn with_error(pose: &Pose, cfg: &CameraConfig, err: &CameraError) -> Frame {
        if err.is_zero() {
            return Frame::new(pose, cfg);
        }
        let cam = camera_pose(pose, cfg, err);
        Frame { origin: cam.t, pitch: 0.0, yaw: 0.0, rot: Some(cam.r) }
    }

    /// Unit world direction of a camera-frame direction (1, ty, tz), and
    /// the depth per unit range along it (cosine to the optical axis).
    fn ray(&self, ty: f64, tz: f64) -> ([f64; 3], f64) {
        let n = (1.0 + ty * ty + tz * tz).sqrt();
        let (x, y, z) = (1.0 / n, ty / n, tz / n);
        if let Some(r) = &self.rot {
            return ([0, 1, 2].map(|i| r[i][0] * x + r[i][1] * y + r[i][2] * z), 1.0 / n);
        }
        let (sp, cp) = self.pitch.sin_cos();
        let (x1, z1) = (x * cp - z * sp, x * sp + z * cp);
        let (sy, cy) = self.yaw.sin_cos();
        ([x1 * cy - y * sy, x1 * sy + y * cy, z1], 1.0 / n)
    }

    /// True when the unit world direction `d` lies in the pixel rays' cone:
    /// |ty| <= hx and |tz| <= hy in the camera frame ([`Frame::ray`] undone).
    fn in_view(&self, d: [f64; 3], hx: f64, hy: f64) -> bool {
        if let Some(r) = &self.rot {
            let [x, y, z] = [0, 1, 2].map(|i| r[0][i] * d[0] + r[1][i] * d[1] + r[2][i] * d[2]);
            return x > 0.0 && (y / x).abs() <= hx && (z / x).abs() <= hy;
        }
        let (sy, cy) = self.yaw.sin_cos();
        let (x1, y) = (cy * d[0] + sy * d[1], -sy * d[0] + cy * d[1]);
        let (sp, cp) = self.pitch.sin_cos();
        let (x, z) = (x1 * cp + d[2] * sp, -x1 * sp + d[2] * cp);
        x > 0.0 && (y / x).abs() <= hx && (z / x).abs() <= hy
    }
}

/// One frame of the camera at `pose`: the points it measured; hits that
/// only a switched-off stage lets through draw from another stream of the
/// same seed (see [`observe_with`]).
pub fn observe(world: &World, pose: &Pose, cfg: &CameraConfig, stages: Stages, rng: &mut ChaCha8Rng) -> Vec<Hit> {
    let mut aux = rng.clone();
    aux.set_stream(rng.get_stream() ^ (1 << 63));
    observe_with(world, pose, cfg, stages, rng, &mut aux)
}

/// One frame of the camera at `pose`: the points it measured.
///
/// Common random numbers across stages: `rng` gives the pixel jitter and
/// the noise of exactly the hits the full emulator (all stages on) would
/// measure, in the same order, whatever stages are off (with noise off,
/// those draws are made and discarded); a hit only a stage switched off
/// lets through (a second surface without occlusion, a pixel the stereo
/// check would reject, a dark patch) draws its noise from `aux`. So
/// switching one stage off changes only what that stage does: the other
/// pixels and their noise stay the same, and a paired comparison against
/// the full emulator shows that stage alone. With the field of view off the
/// pixel rays are cast all the same and the looks at the cells outside
/// their cone draw from `aux`, so this holds for it too.
pub fn observe_with(
    world: &World,
    pose: &Pose,
    cfg: &CameraConfig,
    stages: Stages,
    rng: &mut ChaCha8Rng,
    aux: &mut ChaCha8Rng,
) -> Vec<Hit> {
    observe_tilted(world, pose, &CameraError::default(), cfg, stages, rng, aux)
}

/// [`observe_with`] from a camera whose true orientation differs from the
/// nominal one at `pose` by `err` (body vibration, mount miscalibration):
/// the rays are cast from the true camera; the hits are where the rays
/// truly meet the world.
pub fn observe_tilted(
    world: &World,
    pose: &Pose,
    err: &CameraError,
    cfg: &CameraConfig,
    stages: Stages,
    rng: &mut ChaCha8Rng,
    aux: &mut ChaCha8Rng,
) -> Vec<Hit> {
    let frame = Frame::with_error(pose, cfg, err);
    let mut hits = Vec::new();
    let mut ts = Vec::new();
    let mut sub = Vec::new();
    let half_window = cfg.window_deg.to_radians() / 2.0;
    // The pixel rays of the field of view, within the depth cutoffs. With
    // the stage off they are cast all the same (without the cutoffs), so the
    // cells in view get the points (and the random draws) they get with it
    // on.
    let (hx, hy) = ((cfg.hfov_deg.to_radians() / 2.0).tan(), (cfg.vfov_deg.to_radians() / 2.0).tan());
    for j in 0..cfg.pixels_y {
        for i in 0..cfg.pixels_x {
            let ty = hx * (1.0 - 2.0 * (i as f64 + rng.gen::<f64>()) / cfg.pixels_x as f64);
            let tz = hy * (1.0 - 2.0 * (j as f64 + rng.gen::<f64>()) / cfg.pixels_y as f64);
            let (d, depth_per_t) = frame.ray(ty, tz);
            let t_max = cfg.range_max / depth_per_t;
            crossings(world, frame.origin, d, t_max, stages.occlusion, &mut ts);
            for (k, &t) in ts.iter().enumerate() {
                let mut t = t;
                // What the full emulator makes of this crossing: the
                // first surface, after the stereo window, in range and
                // not dark; only then it draws from `rng`.
                let window = (k == 0).then(|| stereo_window(world, &frame, ty, tz, half_window, t, t_max, &mut sub)).flatten();
                let full = window.is_some_and(|tm| {
                    let depth = tm * depth_per_t;
                    let p = [frame.origin[0] + tm * d[0], frame.origin[1] + tm * d[1]];
                    (cfg.range_min..=cfg.range_max).contains(&depth) && !world.is_dark(p[0], p[1])
                });
                if stages.smoothing && k == 0 {
                    match window {
                        Some(mean) => t = mean,
                        None => continue,
                    }
                }
                let depth = t * depth_per_t;
                if stages.fov && (depth < cfg.range_min || depth > cfg.range_max) {
                    continue;
                }
                let r = if full { &mut *rng } else { &mut *aux };
                push_hit(world, frame.origin, d, t, depth, cfg, stages, full, r, &mut hits);
            }
        }
    }
    if !stages.fov {
        // No field of view: look from the camera, at any range, at every map
        // cell of the DEM footprint (5 cm, jittered) outside the pixel rays'
        // cone. Its draws come from `aux`, so the next frame's pixel rays
        // are those of the full emulator too.
        let (x_back, y_left) = (row_center_x(0) - 0.075, col_center_y(0) + 0.075);
        for r in 0..GRID_ROWS * 2 + 2 {
            for c in 0..COLS * 2 + 2 {
                let (u, v): (f64, f64) = (aux.gen(), aux.gen());
                let fx = x_back + 0.05 * (r as f64 + u);
                let fy = y_left - 0.05 * (c as f64 + v);
                let (px, py) = pose.to_world(fx, fy);
                let p = [px, py, world.height(px, py)];
                let v = [p[0] - frame.origin[0], p[1] - frame.origin[1], p[2] - frame.origin[2]];
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                let d = [v[0] / len, v[1] / len, v[2] / len];
                if frame.in_view(d, hx, hy) {
                    continue;
                }
                crossings(world, frame.origin, d, len + 0.02, stages.occlusion, &mut ts);
                for (k, &t) in ts.iter().enumerate() {
                    let mut t = t;
                    if stages.smoothing && k == 0 {
                        // The same stereo window, tilted about the ray's own
                        // horizontal normal (there is no image plane here:
                        // cells behind the camera are looked at too).
                        let outer = tilted(d, half_window);
                        match window_mean(world, frame.origin, outer, t, 1.5 * len + 0.1, &mut sub) {
                            Some(mean) => t = mean,
                            None => continue,
                        }
                    }
                    push_hit(world, frame.origin, d, t, t, cfg, stages, false, aux, &mut hits);
                }
            }
        }
    }
    hits
}

/// Stereo block matching over a window: the pixel ray and two rays half a
/// window below and above it. On a locally planar surface inverse range is
/// linear across the window and the matcher returns the mean range, which
/// rounds edges and kinks (steps become ramps). Where the window straddles a
/// depth jump (the far edge of a pallet, a stair edge going down) its
/// consistency check fails and the pixel returns nothing: None.
#[allow(clippy::too_many_arguments)]
fn stereo_window(world: &World, frame: &Frame, ty: f64, tz: f64, half: f64, t: f64, t_max: f64, sub: &mut Vec<f64>) -> Option<f64> {
    let dirs = [-half, half].map(|dz| frame.ray(ty, tz + dz).0);
    window_mean(world, frame.origin, dirs, t, t_max, sub)
}

/// The unit ray `d` turned by -a and +a about its horizontal normal (down
/// and up in its own vertical plane): the outer rays of a stereo window
/// when there is no image plane to step in.
fn tilted(d: [f64; 3], a: f64) -> [[f64; 3]; 2] {
    let h = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1e-9);
    // u: in the vertical plane of d, perpendicular to it, pointing up.
    let u = [-d[0] * d[2] / h, -d[1] * d[2] / h, h];
    [-a, a].map(|s| {
        let (sn, cs) = s.sin_cos();
        [d[0] * cs + u[0] * sn, d[1] * cs + u[1] * sn, d[2] * cs + u[2] * sn]
    })
}

/// The matcher over the pixel ray (range `t`) and the two outer rays
/// `dirs`: their mean range, or None where inverse range departs from a
/// plane across the window by more than [`JUMP`] (consistency check).
fn window_mean(world: &World, origin: [f64; 3], dirs: [[f64; 3]; 2], t: f64, t_max: f64, sub: &mut Vec<f64>) -> Option<f64> {
    let mut outer = [0.0; 2];
    for (k, d) in dirs.into_iter().enumerate() {
        crossings(world, origin, d, t_max, true, sub);
        outer[k] = *sub.first()?;
    }
    let (a, b) = (1.0 / outer[0], 1.0 / outer[1]);
    if (2.0 / t - a - b).abs() > JUMP * (2.0 / t) {
        return None;
    }
    Some((outer[0] + t + outer[1]) / 3.0)
}

/// Relative departure of inverse range from a plane across the stereo
/// window beyond which the matcher rejects the pixel.
pub const JUMP: f64 = 0.03;

#[allow(clippy::too_many_arguments)]
fn push_hit(
    world: &World,
    o: [f64; 3],
    d: [f64; 3],
    t: f64,
    depth: f64,
    cfg: &CameraConfig,
    stages: Stages,
    draw_always: bool,
    rng: &mut ChaCha8Rng,
    hits: &mut Vec<Hit>,
) {
    let sigma_r = cfg.noise_a + cfg.noise_b * (depth - cfg.noise_c).powi(2);
    let sigma_l = cfg.noise_lateral * depth;
    let mut p = [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
    if stages.dropout && world.is_dark(p[0], p[1]) {
        return;
    }
    if !stages.noise && draw_always {
        // The draws the full emulator makes for this hit, discarded.
        for _ in 0..3 {
            let _: f64 = StandardNormal.sample(rng);
        }
    }
    if stages.noise {
        let nr: f64 = StandardNormal.sample(rng);
        let (n1, n2): (f64, f64) = (StandardNormal.sample(rng), StandardNormal.sample(rng));
        // e1: horizontal, across the ray; e2 = d x e1.
        let h = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1e-9);
        let e1 = [-d[1] / h, d[0] / h, 0.0];
        let e2 = [d[1] * e1[2] - d[2] * e1[1], d[2] * e1[0] - d[0] * e1[2], d[0] * e1[1] - d[1] * e1[0]];
        for k in 0..3 {
            p[k] += d[k] * sigma_r * nr + sigma_l * (e1[k] * n1 + e2[k] * n2);
        }
    }
    let var = sigma_r.powi(2) * d[2] * d[2] + sigma_l.powi(2) * (1.0 - d[2] * d[2]);
    hits.push(Hit { x: p[0], y: p[1], z: p[2], var });
}

#[cfg(test)]
mod tests {
    use super::super::terrain::Shape;
    use super::*;
    use dem_core::format::Terrain;

    fn world(shape: Shape) -> World {
        World { terrain: Terrain::Other, shape, dark_patches: vec![] }
    }

    #[test]
    fn a_ray_down_onto_flat_ground_crosses_once_at_its_height() {
        let w = world(Shape::Flat);
        let mut ts = vec![];
        crossings(&w, [0.0, 0.0, 0.5], [0.6, 0.0, -0.8], 3.0, false, &mut ts);
        assert_eq!(ts.len(), 1);
        assert!((ts[0] - 0.625).abs() < 1e-3, "{ts:?}");
    }

    #[test]
    fn without_occlusion_a_ray_sees_the_ground_behind_a_pallet() {
        let w = world(Shape::Pallet { x0: 1.0, y0: 0.0, length: 0.3, width: 2.0, board: 0.3, gap: 0.05 });
        // Grazing ray: 0.13 m up at the front face (x = 1.0), 0.019 m up at
        // the back (x = 1.3), the ground at x = 1.351.
        let (o, d) = ([0.0, 0.0, 0.5], {
            let v: [f64; 3] = [1.0, 0.0, -0.37];
            let n = (v[0] * v[0] + v[2] * v[2]).sqrt();
            [v[0] / n, 0.0, v[2] / n]
        });
        let mut first = vec![];
        crossings(&w, o, d, 3.0, true, &mut first);
        let mut all = vec![];
        crossings(&w, o, d, 3.0, false, &mut all);
        assert_eq!(first.len(), 1);
        assert_eq!(all.len(), 2);
        let x_far = o[0] + all[1] * d[0];
        assert!(x_far > 1.3, "{x_far}");
    }

    #[test]
    fn in_view_undoes_the_pixel_ray() {
        let pose = Pose { x: 1.0, y: -0.5, z: 0.07, yaw: 0.4, pitch: 0.1, flippers: [0.0; 4] };
        let f = Frame::new(&pose, &CameraConfig::default());
        let (hx, hy) = (0.5, 0.4);
        for (ty, tz, inside) in [(0.0, 0.0, true), (0.49, -0.39, true), (-0.49, 0.39, true), (0.51, 0.0, false), (0.0, -0.41, false)] {
            assert_eq!(f.in_view(f.ray(ty, tz).0, hx, hy), inside, "({ty}, {tz})");
        }
        let (d, _) = f.ray(0.0, 0.0);
        assert!(!f.in_view([-d[0], -d[1], -d[2]], hx, hy), "behind the camera");
    }

    #[test]
    fn a_camera_with_orientation_errors_casts_its_rays_turned() {
        let pose = Pose { x: 1.0, y: -0.5, z: 0.07, yaw: 0.4, pitch: 0.1, flippers: [0.0; 4] };
        let cfg = CameraConfig::default();
        let plain = Frame::new(&pose, &cfg);
        let zero = Frame::with_error(&pose, &cfg, &CameraError::default());
        assert!(zero.rot.is_none() && zero.origin == plain.origin);
        // A pitch error on the body alone is a frame at another pitch (but
        // the general path).
        let err = CameraError { body_pitch: 0.02, ..CameraError::default() };
        let turned = Frame::with_error(&pose, &cfg, &err);
        let same = Frame::new(&Pose { pitch: 0.12, ..pose }, &cfg);
        for (ty, tz) in [(0.0, 0.0), (0.3, -0.2), (-0.4, 0.35)] {
            let (a, b) = (turned.ray(ty, tz), same.ray(ty, tz));
            assert!((0..3).all(|k| (a.0[k] - b.0[k]).abs() < 1e-12) && a.1 == b.1);
            assert!(turned.in_view(a.0, 0.5, 0.4));
        }
        assert!((0..3).all(|k| (turned.origin[k] - same.origin[k]).abs() < 1e-12));
        // A roll tips the rays across: the left edge of the image goes up.
        let rolled = Frame::with_error(&pose, &cfg, &CameraError { mount_roll: 0.05, ..CameraError::default() });
        let (l, r) = (rolled.ray(0.4, 0.0).0, rolled.ray(-0.4, 0.0).0);
        assert!(l[2] > plain.ray(0.4, 0.0).0[2] && r[2] < plain.ray(-0.4, 0.0).0[2]);
        assert!(!rolled.in_view(rolled.ray(0.0, 0.0).0.map(|v| -v), 0.5, 0.4));
    }

    #[test]
    fn camera_looks_ahead_and_down_from_its_mount() {
        let pose = Pose { x: 0.0, y: 0.0, z: 0.07, yaw: 0.0, pitch: 0.0, flippers: [0.0; 4] };
        let cfg = CameraConfig::default();
        let f = Frame::new(&pose, &cfg);
        assert!((f.origin[2] - 0.52).abs() < 1e-12 && (f.origin[0] - 0.15).abs() < 1e-12);
        let (d, cos) = f.ray(0.0, 0.0);
        assert!((d[2] + cfg.tilt_deg.to_radians().sin()).abs() < 1e-12 && cos == 1.0);
    }
}
