//! One run: a robot drives across one obstacle; every step gives the exact
//! sim DEM and, for measured runs, the DEM the emulated sensor + mapping give.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::camera::Hit;
use super::camera::{observe_tilted, CameraConfig, Stages};
use super::elevation_map::{ElevationMap, MapConfig, MapWindow};
use super::motion::{edge_under_tracks, registration, vibration_sd, CameraError, Drift, DriftConfig, VibrationConfig, SLIP_EDGE};
use super::pose::Pose;
use super::terrain::World;
use dem_core::format::{col_center_y, empty_dem, row_center_x, Dem, DemCells, Terrain, COLS, GRID_ROWS};

/// Everything a run needs besides its index.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// Base seed of the data set.
    pub seed: u64,
    /// Time between DEMs (s).
    pub dt: f64,
    /// Dark patches per square metre.
    pub dark_patch_density: f64,
    /// The camera.
    pub camera: CameraConfig,
    /// The elevation map.
    pub map: MapConfig,
    /// Emulator stages on/off.
    pub stages: Stages,
    /// Pose drift of the `drift` stage.
    pub drift: DriftConfig,
    /// Latency of the `latency` stage (s).
    pub latency: f64,
    /// Sd of the camera mount's pitch and roll errors (rad), drawn once
    /// per run, of the `extrinsic` stage.
    pub extrinsic: f64,
    /// The body's pitch and roll noise of the `vibration` stage.
    pub vibration: VibrationConfig,
    /// Keep the map window after every measured frame ([`Step::map`], for
    /// `dem-synth --emit-maps`). It only reads the map: no random draws,
    /// the DEMs are the same either way.
    pub emit_maps: bool,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            seed: 0,
            dt: 0.4,
            dark_patch_density: 0.4,
            camera: CameraConfig::default(),
            map: MapConfig::default(),
            stages: Stages::default(),
            drift: DriftConfig::default(),
            latency: 0.15,
            extrinsic: 0.5f64.to_radians(),
            vibration: VibrationConfig::default(),
            emit_maps: false,
        }
    }
}

/// One step of a run.
#[derive(Debug, Clone)]
pub struct Step {
    /// Exact DEM at this pose.
    pub sim: Dem,
    /// Emulated measured DEM (measured runs only).
    pub measured: Option<Dem>,
    /// The map window right after this frame's fusion (measured runs with
    /// [`RunConfig::emit_maps`] only).
    pub map: Option<MapWindow>,
    /// The pose the measured DEM was cut around (measured runs only): x,
    /// y, z and yaw of the pose the map believed at the frame (with drift
    /// and latency, not the true current one), pitch and flippers of the
    /// current pose (the attitude row).
    pub map_pose: Option<Pose>,
    /// The robot's pose.
    pub pose: Pose,
    /// Seconds since the run started.
    pub time: f64,
}

/// The steps of one run and its terrain.
#[derive(Debug, Clone)]
pub struct Run {
    /// Terrain class of the run.
    pub terrain: Terrain,
    /// The steps, in time order.
    pub steps: Vec<Step>,
}

/// The exact DEM at `pose`: terrain heights at the cell centres, relative to C.
pub fn sim_dem(world: &World, pose: &Pose) -> Dem {
    let mut d = empty_dem();
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (x, y) = pose.to_world(row_center_x(r), col_center_y(c));
            d.set_valid(r, c, (world.height(x, y) - pose.z) as f32);
        }
    }
    d.set_attitude(attitude(pose));
    d
}

fn attitude(pose: &Pose) -> [f32; 5] {
    let f = pose.flippers;
    [pose.pitch as f32, f[0] as f32, f[1] as f32, f[2] as f32, f[3] as f32]
}

/// The measuring side of a run: camera frames fused into the moving map.
pub struct Sensor<'a> {
    cfg: &'a RunConfig,
    map: ElevationMap,
    rng: ChaCha8Rng,
    /// Draws for hits only a switched-off stage lets through (see [`observe_with`](super::camera::observe_with)).
    aux: ChaCha8Rng,
    /// Draws of the drift's walk.
    drift_rng: ChaCha8Rng,
    /// Draws of the vibration.
    vibration_rng: ChaCha8Rng,
    drift: Drift,
    /// The camera mount's (pitch, roll) errors of this run.
    mount: (f64, f64),
    /// The true pose of the previous frame (for the distance travelled).
    last: Option<Pose>,
    /// The pose the last DEM was cut around.
    cut: Option<Pose>,
}

/// A stream of the same seed as `rng`, its stream number with bit `bit` flipped.
fn derived(rng: &ChaCha8Rng, bit: u32) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::from_seed(rng.get_seed());
    r.set_stream(rng.get_stream() ^ (1 << bit));
    r
}

impl<'a> Sensor<'a> {
    /// A sensor with an empty map over world x in `[x_min, x_max]`, |y| < 3 m.
    ///
    /// The motion stages draw from streams of their own (the sensor
    /// stream's number with bit 62, 61 or 60 flipped for drift, extrinsic
    /// and vibration), so they leave the camera's draws unchanged: with
    /// them off the DEMs are those of the six sensor stages alone, and
    /// switching one off changes that stage only.
    pub fn new(cfg: &'a RunConfig, x_min: f64, x_max: f64, rng: ChaCha8Rng) -> Self {
        let aux = derived(&rng, 63);
        let drift_rng = derived(&rng, 62);
        let mut extrinsic_rng = derived(&rng, 61);
        let vibration_rng = derived(&rng, 60);
        let mount = if cfg.stages.extrinsic {
            let (p, r): (f64, f64) = (StandardNormal.sample(&mut extrinsic_rng), StandardNormal.sample(&mut extrinsic_rng));
            (cfg.extrinsic * p, cfg.extrinsic * r)
        } else {
            (0.0, 0.0)
        };
        let drift = Drift { error: if cfg.stages.drift { cfg.drift.initial } else { [0.0; 4] } };
        Sensor {
            cfg,
            map: ElevationMap::new(cfg.map.clone(), x_min, x_max, -3.0, 3.0),
            rng,
            aux,
            drift_rng,
            vibration_rng,
            drift,
            mount,
            last: None,
            cut: None,
        }
    }

    /// The camera mount's (pitch, roll) errors of this run (rad).
    pub fn mount_error(&self) -> (f64, f64) {
        self.mount
    }

    /// Set the camera mount's (pitch, roll) errors (rad), as the extrinsic
    /// stage would have drawn them.
    pub fn set_mount_error(&mut self, pitch: f64, roll: f64) {
        self.mount = (pitch, roll);
    }

    /// The drift's current error (x, y, z, yaw).
    pub fn drift_error(&self) -> [f64; 4] {
        self.drift.error
    }

    /// One frame at `pose`: observe, fuse, and return the measured DEM.
    pub fn measure(&mut self, world: &World, pose: &Pose) -> Dem {
        self.measure_at(world, pose, pose)
    }

    /// One frame taken at `frame` (the true pose when the camera took it),
    /// handed out when the robot is at `now`: observe, fuse, and return the
    /// DEM cut around the pose the map believes at `frame`, with the
    /// attitude row of `now`.
    pub fn measure_at(&mut self, world: &World, frame: &Pose, now: &Pose) -> Dem {
        let stages = self.cfg.stages;
        let edge = if stages.drift || stages.vibration { edge_under_tracks(world, frame) } else { 0.0 };
        if stages.drift {
            if let Some(last) = self.last {
                let ds = ((frame.x - last.x).powi(2) + (frame.y - last.y).powi(2) + (frame.z - last.z).powi(2)).sqrt();
                let slip = if edge > SLIP_EDGE { self.cfg.drift.slip } else { 1.0 };
                let n: [f64; 4] = std::array::from_fn(|_| StandardNormal.sample(&mut self.drift_rng));
                self.drift.advance(&self.cfg.drift, ds, slip, n);
            }
        }
        self.last = Some(*frame);
        let mut err = CameraError { mount_pitch: self.mount.0, mount_roll: self.mount.1, ..CameraError::default() };
        if stages.vibration {
            let sd = vibration_sd(&self.cfg.vibration, edge);
            let (p, r): (f64, f64) = (StandardNormal.sample(&mut self.vibration_rng), StandardNormal.sample(&mut self.vibration_rng));
            (err.body_pitch, err.body_roll) = (sd * p, sd * r);
        }
        let believed = self.drift.believed(frame);
        let hits = observe_tilted(world, frame, &err, &self.cfg.camera, stages, &mut self.rng, &mut self.aux);
        if !stages.memory {
            self.map.forget();
        }
        self.map.begin_frame(&believed);
        if err.is_zero() && believed == *frame {
            for hit in &hits {
                self.map.fuse(hit);
            }
        } else {
            let reg = registration(frame, &err, &believed, &self.cfg.camera);
            for hit in &hits {
                let [x, y, z] = reg.apply([hit.x, hit.y, hit.z]);
                self.map.fuse(&Hit { x, y, z, var: hit.var });
            }
        }
        let mut d = self.map.dem(&believed, stages.holes);
        d.set_attitude(attitude(now));
        self.cut = Some(Pose { pitch: now.pitch, flippers: now.flippers, ..believed });
        d
    }

    /// The pose the last DEM was cut around (see [`Step::map_pose`]).
    pub fn cut_pose(&self) -> Option<Pose> {
        self.cut
    }

    /// The map window around `pose` as it stands (after [`measure`](Self::measure):
    /// the state that frame's DEM was resampled from when `pose` is
    /// [`cut_pose`](Self::cut_pose)).
    pub fn window(&self, pose: &Pose) -> MapWindow {
        self.map.window(pose, self.cfg.stages.holes)
    }
}

/// A run's path: the robot drives from `x_start` to `x_end` at `speed`,
/// its heading `yaw0` plus a wobble `a sin(w t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trajectory {
    /// Start along x (m).
    pub x_start: f64,
    /// The run ends past this x (m).
    pub x_end: f64,
    /// Start across (m).
    pub y_start: f64,
    /// Speed (m/s).
    pub speed: f64,
    /// Mean heading (rad).
    pub yaw0: f64,
    /// Heading wobble (amplitude rad, angular frequency rad/s, phase rad).
    pub wobble: (f64, f64, f64),
}

impl Trajectory {
    /// Heading at `time` s.
    pub fn yaw(&self, time: f64) -> f64 {
        self.yaw0 + self.wobble.0 * (self.wobble.1 * time + self.wobble.2).sin()
    }
}

/// Where the path was at time `s` (s), given its steps (time, x, y, yaw)
/// so far: between steps it runs straight along the earlier step's heading
/// at the run's speed (as the steps are made), its heading the wobble's at
/// `s`; before the start it is at the start.
pub fn point_at(traj: &Trajectory, steps: &[(f64, f64, f64, f64)], s: f64) -> (f64, f64, f64) {
    let Some(first) = steps.first() else { return (traj.x_start, traj.y_start, traj.yaw(0.0)) };
    if s <= first.0 {
        return (first.1, first.2, first.3);
    }
    let k = steps.partition_point(|st| st.0 <= s) - 1;
    let (t, x, y, yaw) = steps[k];
    let ds = traj.speed * (s - t);
    (x + ds * yaw.cos(), y + ds * yaw.sin(), traj.yaw(s))
}

/// Simulate run `index` of terrain `terrain`; measure it when `measured`.
///
/// The world and trajectory come from random stream 2 * index and the
/// sensor from stream 2 * index + 1, so a run's sim DEMs are the same
/// whether or not it is measured and whatever stages are on.
pub fn simulate(cfg: &RunConfig, index: u64, terrain: Terrain, measured: bool) -> Run {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    rng.set_stream(2 * index);
    let mut sensor_rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    sensor_rng.set_stream(2 * index + 1);

    let world = World::random(terrain, 0.0, cfg.dark_patch_density, &mut rng);
    let x_start = -rng.gen_range(1.6..2.6);
    let x_end = world.obstacle_end(0.0) + rng.gen_range(0.4..1.0);
    let speed = rng.gen_range(0.15..0.3);
    let y_start = rng.gen_range(-0.1..0.1);
    let yaw0 = rng.gen_range(-0.08..0.08);
    let wobble: (f64, f64, f64) = (rng.gen_range(0.0..0.04), rng.gen_range(0.1..0.5), rng.gen_range(0.0..6.3));
    let traj = Trajectory { x_start, x_end, y_start, speed, yaw0, wobble };
    let steps = drive(cfg, &world, &traj, measured.then_some(sensor_rng));
    Run { terrain, steps }
}

/// Drive `traj` on `world`: a step every `cfg.dt`; measured with a sensor
/// drawing from `sensor_rng` when given.
///
/// With the latency stage on, the camera frame of the step at time t is
/// taken at the trajectory point `cfg.latency` s earlier (the robot rested
/// there; the run's start before it began), and the DEM is cut around that
/// older pose; the attitude row is the current pose's.
pub fn drive(cfg: &RunConfig, world: &World, traj: &Trajectory, sensor_rng: Option<ChaCha8Rng>) -> Vec<Step> {
    let mut sensor = sensor_rng.map(|r| Sensor::new(cfg, traj.x_start - 3.0, traj.x_end + 3.0, r));
    let delayed = cfg.stages.latency && cfg.latency > 0.0;
    let mut path: Vec<(f64, f64, f64, f64)> = Vec::new();
    let mut steps = Vec::new();
    let (mut x, mut y, mut time): (f64, f64, f64) = (traj.x_start, traj.y_start, 0.0);
    while x <= traj.x_end {
        let yaw = traj.yaw(time);
        let pose = Pose::rest_on(world, x, y, yaw);
        let sim = sim_dem(world, &pose);
        path.push((time, x, y, yaw));
        let measured = sensor.as_mut().map(|s| {
            if delayed {
                let (fx, fy, fyaw) = point_at(traj, &path, time - cfg.latency);
                s.measure_at(world, &Pose::rest_on(world, fx, fy, fyaw), &pose)
            } else {
                s.measure(world, &pose)
            }
        });
        let map_pose = sensor.as_ref().and_then(Sensor::cut_pose);
        let map = sensor.as_ref().filter(|_| cfg.emit_maps).map(|s| s.window(&map_pose.expect("a measured step")));
        steps.push(Step { sim, measured, map, map_pose, pose, time });
        let ds = traj.speed * cfg.dt;
        x += ds * yaw.cos();
        y += ds * yaw.sin();
        time += cfg.dt;
    }
    steps
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_at_runs_back_along_the_steps_and_stops_at_the_start() {
        let traj = Trajectory { x_start: -1.0, x_end: 1.0, y_start: 0.0, speed: 0.2, yaw0: 0.1, wobble: (0.0, 0.0, 0.0) };
        let steps = [(0.0, -1.0, 0.0, 0.1), (0.4, -1.0 + 0.08 * 0.1f64.cos(), 0.08 * 0.1f64.sin(), 0.1)];
        let (x, y, yaw) = point_at(&traj, &steps, 0.55);
        assert!((x - (steps[1].1 + 0.03 * 0.1f64.cos())).abs() < 1e-12 && (y - (steps[1].2 + 0.03 * 0.1f64.sin())).abs() < 1e-12);
        assert_eq!(yaw, 0.1);
        assert_eq!(point_at(&traj, &steps, 0.4), (steps[1].1, steps[1].2, 0.1));
        assert_eq!(point_at(&traj, &steps, -0.15), (-1.0, 0.0, 0.1));
        // Between the steps, on the straight line of the first.
        let (x, _, _) = point_at(&traj, &steps, 0.2);
        assert!((x - (-1.0 + 0.04 * 0.1f64.cos())).abs() < 1e-12);
    }
}
