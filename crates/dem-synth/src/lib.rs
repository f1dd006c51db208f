//! dem-synth's library: the synthetic world the toolkit tests on, since the thesis's recordings
//! are not public: terrains, robot runs across them, the exact DEMs a
//! simulator gives (sim) and the DEMs a depth camera plus elevation mapping
//! give (measured), from a physical emulator whose stages can be switched off
//! one at a time.
//!
//! - [`terrain`]: height fields (flat, stairs, pallets of planks, other).
//! - [`pose`]: how the robot rests on the terrain (pitch, flippers).
//! - [`camera`]: the depth camera ray-cast into the height field.
//! - [`motion`]: the pose the map believes and the camera's true
//!   orientation (drift, extrinsic and vibration errors).
//! - [`elevation_map`]: Kalman fusion into a moving 5 cm map, resampled to
//!   the 10 cm DEM.
//! - [`run`]: one run across one obstacle.
//! - [`dataset`]: many runs in parallel, written as NPY and CSV files.

pub mod camera;
pub mod camera_config;
pub mod dataset;
pub mod elevation_map;
pub mod motion;
pub mod pose;
pub mod run;
pub mod terrain;

pub use camera::{CameraConfig, Stages};
pub use dataset::{generate, DatasetConfig, Summary};
pub use elevation_map::{MapConfig, MapWindow};
pub use motion::{DriftConfig, VibrationConfig};
pub use run::RunConfig;
