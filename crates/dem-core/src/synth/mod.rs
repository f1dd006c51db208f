//! The synthetic world: terrains, trajectories, sim DEMs and the sensor emulator.
