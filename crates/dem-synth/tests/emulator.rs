//! Physical properties of the sensor emulator, on hand-built worlds: the
//! effects the thesis saw in real DEMs must come out of the physics.

use dem_core::format::{row_center_x, Dem, DemCells, Terrain, COLS, GRID_ROWS};
use dem_synth::camera::{observe, CameraConfig, Stages};
use dem_synth::pose::Pose;
use dem_synth::run::{sim_dem, RunConfig, Sensor};
use dem_synth::terrain::{Shape, World, PALLET_GAP_HEIGHT, PALLET_HEIGHT};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn world(terrain: Terrain, shape: Shape) -> World {
    World { terrain, shape, dark_patches: vec![] }
}

fn cfg(stages: Stages) -> RunConfig {
    RunConfig { stages, ..RunConfig::default() }
}

/// Drive from x = `from` forward in steps of 2.5 cm for `frames` frames and
/// return the last measured DEM.
fn drive(cfg: &RunConfig, w: &World, from: f64, frames: usize) -> Dem {
    let mut sensor = Sensor::new(cfg, from - 3.0, from + 6.0, ChaCha8Rng::seed_from_u64(7));
    let mut last = None;
    for k in 0..frames {
        let pose = Pose::rest_on(w, from + 0.025 * k as f64, 0.0, 0.0);
        last = Some(sensor.measure(w, &pose));
    }
    last.expect("at least one frame")
}

fn row_of(x: f64) -> usize {
    ((x + 0.6) / 0.1).floor() as usize
}

fn valid_in_rows(d: &Dem, rows: std::ops::Range<usize>) -> usize {
    rows.flat_map(|r| (0..COLS).map(move |c| (r, c))).filter(|&(r, c)| d.is_valid(r, c)).count()
}

#[test]
fn a_pallet_leaves_a_shadow_behind_it() {
    // A 0.4 m pallet whose far edge is at x = 0.9 ahead of the final pose;
    // the camera (0.52 m over the ground, 0.15 m ahead of C) cannot see the
    // ground from 0.9 m to about 1.19 m behind it.
    let w = world(Terrain::Pallet, Shape::Pallet { x0: 0.5, y0: 0.0, length: 0.4, width: 2.0, board: 0.1, gap: 0.04 });
    let (from, frames) = (-0.25, 11); // ends at x = 0
    let shadow = row_of(0.95)..row_of(1.15);
    let seen = drive(&cfg(Stages::default()), &w, from, frames);
    let unoccluded = drive(&cfg(Stages { occlusion: false, ..Stages::default() }), &w, from, frames);
    let cells = shadow.len() * COLS;
    assert!(valid_in_rows(&seen, shadow.clone()) * 4 <= cells, "shadow rows mostly seen:\n{seen:?}");
    assert!(valid_in_rows(&unoccluded, shadow.clone()) * 4 >= cells * 3, "without occlusion the shadow is seen");
    // The ground beyond the shadow is seen again.
    assert!(valid_in_rows(&seen, row_of(1.25)..GRID_ROWS) * 2 >= (GRID_ROWS - row_of(1.25)) * COLS);
}

#[test]
fn stairs_down_leave_a_blind_band_past_the_edge() {
    let w = world(Terrain::StairsDown, Shape::Stairs { x0: 0.6, rise: -0.17, run: 0.3, steps: 6 });
    let band = row_of(0.62)..row_of(0.72);
    let seen = drive(&cfg(Stages::default()), &w, -0.25, 11);
    let unoccluded = drive(&cfg(Stages { occlusion: false, ..Stages::default() }), &w, -0.25, 11);
    let cells = band.len() * COLS;
    assert!(valid_in_rows(&seen, band.clone()) * 2 <= cells, "band mostly seen:\n{seen:?}");
    assert!(valid_in_rows(&unoccluded, band.clone()) * 4 >= cells * 3);
    // Before the edge the landing is seen.
    assert!(valid_in_rows(&seen, row_of(0.3)..row_of(0.55)) * 4 >= 3 * (row_of(0.55) - row_of(0.3)) * COLS);
}

#[test]
fn startup_frames_see_only_the_rows_ahead() {
    let w = world(Terrain::Flat, Shape::Flat);
    let first = drive(&cfg(Stages::default()), &w, 0.0, 1);
    // Behind C and just ahead of it were never in view.
    assert_eq!(valid_in_rows(&first, 0..row_of(0.3)), 0, "{first:?}");
    // Far rows are seen at once.
    assert!(valid_in_rows(&first, row_of(0.6)..GRID_ROWS) * 10 >= 9 * (GRID_ROWS - row_of(0.6)) * COLS);
    // After driving 1.2 m the rows behind C are filled from memory.
    let later = drive(&cfg(Stages::default()), &w, 0.0, 49);
    assert!(valid_in_rows(&later, 0..row_of(0.0)) * 10 >= 8 * row_of(0.0) * COLS, "{later:?}");
}

#[test]
fn height_noise_grows_with_range() {
    let w = world(Terrain::Flat, Shape::Flat);
    let pose = Pose::rest_on(&w, 0.0, 0.0, 0.0);
    let stages = Stages { smoothing: false, ..Stages::default() };
    let cam = CameraConfig { pixels_x: 96, pixels_y: 72, ..CameraConfig::default() };
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let hits = observe(&w, &pose, &cam, stages, &mut rng);
    let spread = |lo: f64, hi: f64| {
        let z: Vec<f64> = hits
            .iter()
            .filter(|h| {
                let r = ((h.x - 0.15).powi(2) + h.y.powi(2) + (h.z - 0.52).powi(2)).sqrt();
                (lo..hi).contains(&r)
            })
            .map(|h| h.z)
            .collect();
        assert!(z.len() > 50, "{} hits in {lo}..{hi}", z.len());
        let n = z.len() as f64;
        (z.iter().map(|v| v * v).sum::<f64>() / n).sqrt() // ground is z = 0
    };
    let (near, far) = (spread(0.6, 1.0), spread(2.0, 2.8));
    assert!(far > 2.0 * near, "near {near}, far {far}");
    // ... and matches the model's order of magnitude: a few mm near, cm far.
    assert!(near < 0.005 && far > 0.002, "near {near}, far {far}");
}

#[test]
fn sim_pallets_show_plank_stripes() {
    let w = world(Terrain::Pallet, Shape::Pallet { x0: 0.0, y0: 0.0, length: 1.2, width: 2.0, board: 0.1, gap: 0.05 });
    let pose = Pose::rest_on(&w, -0.2, 0.0, 0.0);
    let d = sim_dem(&w, &pose);
    let top = (PALLET_HEIGHT - pose.z) as f32;
    let gap = (PALLET_GAP_HEIGHT - pose.z) as f32;
    let rows: Vec<usize> = (0..GRID_ROWS).filter(|&r| (0.0..1.2).contains(&(pose.x + row_center_x(r)))).collect();
    let gaps = rows.iter().filter(|&&r| (d.height(r, 2) - gap).abs() < 1e-5).count();
    let tops = rows.iter().filter(|&&r| (d.height(r, 2) - top).abs() < 1e-5).count();
    assert!(gaps >= 2 && tops >= 4, "rows {rows:?}: {gaps} gap rows, {tops} top rows");
    // A stripe is a whole row: every column of a gap row is low.
    let r = *rows.iter().find(|&&r| (d.height(r, 2) - gap).abs() < 1e-5).unwrap();
    assert!((0..COLS).all(|c| (d.height(r, c) - gap).abs() < 1e-5));
}

#[test]
fn same_seed_gives_the_same_measured_dems() {
    let w = world(Terrain::StairsUp, Shape::Stairs { x0: 1.0, rise: 0.17, run: 0.3, steps: 5 });
    let a = drive(&cfg(Stages::default()), &w, 0.0, 5);
    let b = drive(&cfg(Stages::default()), &w, 0.0, 5);
    assert_eq!(a, b);
}

