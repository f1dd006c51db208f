//! One run: a robot drives across one obstacle; every step gives the exact
//! sim DEM and, for measured runs, the DEM the emulated sensor + mapping give.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::camera::{observe_with, CameraConfig, Stages};
use super::elevation_map::{ElevationMap, MapConfig, MapWindow};
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
    /// Draws for hits only a switched-off stage lets through (see [`observe_with`]).
    aux: ChaCha8Rng,
}

impl<'a> Sensor<'a> {
    /// A sensor with an empty map over world x in `[x_min, x_max]`, |y| < 3 m.
    pub fn new(cfg: &'a RunConfig, x_min: f64, x_max: f64, rng: ChaCha8Rng) -> Self {
        let mut aux = ChaCha8Rng::from_seed(rng.get_seed());
        aux.set_stream(rng.get_stream() ^ (1 << 63));
        Sensor { cfg, map: ElevationMap::new(cfg.map.clone(), x_min, x_max, -3.0, 3.0), rng, aux }
    }

    /// One frame at `pose`: observe, fuse, and return the measured DEM.
    pub fn measure(&mut self, world: &World, pose: &Pose) -> Dem {
        self.map.begin_frame(pose);
        for hit in observe_with(world, pose, &self.cfg.camera, self.cfg.stages, &mut self.rng, &mut self.aux) {
            self.map.fuse(&hit);
        }
        let mut d = self.map.dem(pose, self.cfg.stages.holes);
        d.set_attitude(attitude(pose));
        d
    }

    /// The map window around `pose` as it stands (after [`measure`](Self::measure):
    /// the state that frame's DEM was resampled from).
    pub fn window(&self, pose: &Pose) -> MapWindow {
        self.map.window(pose, self.cfg.stages.holes)
    }
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
    let mut y = rng.gen_range(-0.1..0.1);
    let yaw0 = rng.gen_range(-0.08..0.08);
    let wobble: (f64, f64, f64) = (rng.gen_range(0.0..0.04), rng.gen_range(0.1..0.5), rng.gen_range(0.0..6.3));

    let mut sensor = measured.then(|| Sensor::new(cfg, x_start - 3.0, x_end + 3.0, sensor_rng));
    let mut steps = Vec::new();
    let (mut x, mut time): (f64, f64) = (x_start, 0.0);
    while x <= x_end {
        let yaw = yaw0 + wobble.0 * (wobble.1 * time + wobble.2).sin();
        let pose = Pose::rest_on(&world, x, y, yaw);
        let sim = sim_dem(&world, &pose);
        let measured = sensor.as_mut().map(|s| s.measure(&world, &pose));
        let map = sensor.as_ref().filter(|_| cfg.emit_maps).map(|s| s.window(&pose));
        steps.push(Step { sim, measured, map, pose, time });
        let ds = speed * cfg.dt;
        x += ds * yaw.cos();
        y += ds * yaw.sin();
        time += cfg.dt;
    }
    Run { terrain, steps }
}
