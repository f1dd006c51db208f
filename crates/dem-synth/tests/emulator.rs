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

/// The map's memory: driving 1.5 m over flat ground, the rows the robot has
/// passed keep what the camera saw of them; with `memory` off each DEM is
/// its own frame's points, so the rows behind the camera's near view (its
/// lowest ray meets the ground about 0.4 m ahead of C) are missing; in a
/// run's first frame the two are the same.
#[test]
fn the_map_s_memory_keeps_the_rows_behind_the_view() {
    let w = world(Terrain::Flat, Shape::Flat);
    let forgetful = cfg(Stages { memory: false, ..Stages::default() });
    let behind = 0..row_of(0.3);
    let kept = drive(&cfg(Stages::default()), &w, -1.5, 61);
    let alone = drive(&forgetful, &w, -1.5, 61);
    let cells = behind.len() * COLS;
    assert!(valid_in_rows(&kept, behind.clone()) * 4 >= cells * 3, "the passed rows are kept:\n{kept:?}");
    assert_eq!(valid_in_rows(&alone, behind), 0, "without memory the rows behind are seen:\n{alone:?}");
    // A run's first frame has no past: the memory changes nothing there.
    let first = drive(&forgetful, &w, -0.5, 1);
    assert_eq!(drive(&cfg(Stages::default()), &w, -0.5, 1), first);
    assert_eq!(valid_in_rows(&first, 0..row_of(0.3)), 0, "the near view:\n{first:?}");
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

// ---- The motion stages: drift, latency, extrinsic, vibration ----

use dem_synth::run::{drive as drive_path, simulate, Step, Trajectory};

/// The six sensor stages, plus the motion stages named.
fn with(drift: bool, latency: bool, extrinsic: bool, vibration: bool) -> RunConfig {
    cfg(Stages { drift, latency, extrinsic, vibration, ..Stages::sensor_only() })
}

/// Drive straight along x from `from` to `to` at `speed` (a step every
/// 0.4 s), measured with sensor seed `seed`.
fn run_on(cfg: &RunConfig, w: &World, from: f64, to: f64, speed: f64, seed: u64) -> Vec<Step> {
    let traj = Trajectory { x_start: from, x_end: to, y_start: 0.0, speed, yaw0: 0.0, wobble: (0.0, 0.0, 0.0) };
    drive_path(cfg, w, &traj, Some(ChaCha8Rng::seed_from_u64(seed)))
}

/// Least-squares slope of valid heights over their rows' x (m per m).
fn slope(d: &Dem) -> f64 {
    let pts: Vec<(f64, f64)> = (0..GRID_ROWS)
        .flat_map(|r| (0..COLS).map(move |c| (r, c)))
        .filter(|&(r, c)| d.is_valid(r, c))
        .map(|(r, c)| (row_center_x(r), d.height(r, c) as f64))
        .collect();
    assert!(pts.len() > 30, "{} valid cells", pts.len());
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

#[test]
fn a_camera_pitched_off_its_mount_tilts_flat_ground_by_the_tangent() {
    let w = world(Terrain::Flat, Shape::Flat);
    let c = with(false, false, true, false);
    let pose = Pose::rest_on(&w, 0.0, 0.0, 0.0);
    let frame = |pitch_deg: f64| {
        let mut s = Sensor::new(&c, -3.0, 3.0, ChaCha8Rng::seed_from_u64(5));
        s.set_mount_error(pitch_deg.to_radians(), 0.0);
        slope(&s.measure(&w, &pose))
    };
    let level = frame(0.0);
    assert!(level.abs() < 0.003, "no error: slope {level}");
    for e in [1.0f64, -1.0, 2.0] {
        // Truly pitched up by e, registered as nominal: the map turns the
        // ground down by e about the camera, heights fall by tan(e) per metre.
        let want = -e.to_radians().tan();
        let got = frame(e) - level;
        eprintln!("mount pitch error {e} deg: slope {got}, -tan {want}");
        assert!((got - want).abs() < 0.2 * want.abs(), "error {e} deg: slope {got}, tan {want}");
    }
    // The per-run draw: sd 0.5 degree by default, fixed for the run.
    let s = Sensor::new(&c, -3.0, 3.0, ChaCha8Rng::seed_from_u64(5));
    let (p, r) = s.mount_error();
    assert!(p != 0.0 && r != 0.0 && p.abs() < 3.0 * c.extrinsic * 2.0 && r.abs() < 3.0 * c.extrinsic * 2.0);
}

/// Where a rising edge crosses mid-height in a DEM (m ahead of C), mean
/// over the columns that show it, interpolated between row centres.
fn edge_at(d: &Dem, mid: f32) -> Option<f64> {
    let xs: Vec<f64> = (0..COLS)
        .filter_map(|c| {
            (0..GRID_ROWS - 1).find_map(|r| {
                let ok = d.is_valid(r, c) && d.is_valid(r + 1, c);
                let (a, b) = (d.height(r, c), d.height(r + 1, c));
                (ok && a < mid && b >= mid).then(|| row_center_x(r) + 0.1 * ((mid - a) / (b - a)) as f64)
            })
        })
        .collect();
    (!xs.is_empty()).then(|| xs.iter().sum::<f64>() / xs.len() as f64)
}

#[test]
fn latency_shows_a_stair_edge_ahead_by_speed_times_latency() {
    let rise = 0.17;
    let w = world(Terrain::StairsUp, Shape::Stairs { x0: 0.0, rise, run: 0.3, steps: 5 });
    let (speed, latency) = (0.25, 0.8);
    let mid = (-0.07 + rise / 2.0) as f32;
    let offset = |c: &RunConfig| {
        let steps = run_on(c, &w, -1.3, 0.5, speed, 9);
        let d: Vec<f64> = steps
            .iter()
            .filter(|s| (-1.05..-0.45).contains(&s.pose.x))
            .map(|s| edge_at(s.measured.as_ref().unwrap(), mid).unwrap() - edge_at(&s.sim, mid).unwrap())
            .collect();
        assert!(d.len() >= 5, "{} steps", d.len());
        d.iter().sum::<f64>() / d.len() as f64
    };
    let now = offset(&with(false, false, false, false));
    let mut c = with(false, true, false, false);
    c.latency = latency;
    let late = offset(&c);
    let want = speed * latency;
    assert!(now.abs() < 0.05, "without latency the edge sits {now} m from the sim's");
    eprintln!("edge offset against sim: {now} m without latency, {late} m with");
    assert!((late - now - want).abs() < 0.04, "latency {latency} s at {speed} m/s: edge ahead by {}, v L = {want}", late - now);
    // The attitude row is the current pose's.
    let steps = run_on(&c, &w, -1.3, 0.5, speed, 9);
    assert!(steps.iter().all(|s| s.measured.as_ref().unwrap().attitude() == s.sim.attitude()));
}

/// Mean |measured - sim| over the cells valid in both, rows `rows`.
fn disagreement(steps: &[Step], rows: std::ops::Range<usize>) -> (f64, usize) {
    let (mut sum, mut n) = (0.0, 0);
    for s in steps {
        let m = s.measured.as_ref().unwrap();
        for r in rows.clone() {
            for c in 0..COLS {
                if m.is_valid(r, c) {
                    sum += (m.height(r, c) - s.sim.height(r, c)).abs() as f64;
                    n += 1;
                }
            }
        }
    }
    (sum / n as f64, n)
}

#[test]
fn drift_blurs_the_rows_seen_earlier_on_stairs_and_pallets() {
    let behind = 0..row_of(0.0);
    for terrain in [Terrain::StairsUp, Terrain::StairsDown, Terrain::Pallet] {
        let (mut off, mut on) = (0.0, 0.0);
        for index in 0..4 {
            let run = |c: &RunConfig| disagreement(&simulate(c, index, terrain, true).steps, behind.clone()).0;
            off += run(&with(false, false, false, false));
            on += run(&with(true, false, false, false));
        }
        eprintln!("{terrain:?}: rows behind disagree with sim by {on} with drift, {off} without");
        assert!(on > 1.2 * off, "{terrain:?}: rows behind disagree with sim by {on} with drift, {off} without");
    }
}

#[test]
fn a_constant_drift_changes_nothing() {
    let w = world(Terrain::StairsUp, Shape::Stairs { x0: 0.5, rise: 0.17, run: 0.3, steps: 5 });
    let base = with(false, false, false, false);
    let mut c = with(true, false, false, false);
    c.drift = dem_synth::DriftConfig { horizontal: 0.0, vertical: 0.0, yaw: 0.0, initial: [0.1, -0.05, 0.03, 0.0], ..c.drift };
    let (a, b) = (run_on(&base, &w, -1.0, 1.5, 0.2, 4), run_on(&c, &w, -1.0, 1.5, 0.2, 4));
    let mut worst = 0f32;
    for (x, y) in a.iter().zip(&b) {
        let (x, y) = (x.measured.as_ref().unwrap(), y.measured.as_ref().unwrap());
        for r in 0..GRID_ROWS {
            for col in 0..COLS {
                assert_eq!(x.is_valid(r, col), y.is_valid(r, col));
                if x.is_valid(r, col) {
                    worst = worst.max((x.height(r, col) - y.height(r, col)).abs());
                }
            }
        }
    }
    assert!(worst < 1e-5, "a constant pose error moved heights by {worst}");
    // The cut pose carries the constant error.
    let (p, q) = (a[3].map_pose.unwrap(), b[3].map_pose.unwrap());
    assert!((q.x - p.x - 0.1).abs() < 1e-12 && (q.z - p.z - 0.03).abs() < 1e-12);
}

/// RMS of (measured with `c` - measured with the six stages) over cells
/// valid in both, over the steps whose pose x is in `span`.
fn spread(c: &RunConfig, w: &World, span: std::ops::Range<f64>) -> f64 {
    let base = run_on(&with(false, false, false, false), w, -1.0, 2.0, 0.2, 11);
    let shaken = run_on(c, w, -1.0, 2.0, 0.2, 11);
    let (mut sum, mut n) = (0.0, 0);
    for (a, b) in base.iter().zip(&shaken).filter(|(a, _)| span.contains(&a.pose.x)) {
        let (a, b) = (a.measured.as_ref().unwrap(), b.measured.as_ref().unwrap());
        for r in 0..GRID_ROWS {
            for col in 0..COLS {
                if a.is_valid(r, col) && b.is_valid(r, col) {
                    sum += ((a.height(r, col) - b.height(r, col)) as f64).powi(2);
                    n += 1;
                }
            }
        }
    }
    assert!(n > 200, "{n} cells");
    (sum / n as f64).sqrt()
}

#[test]
fn vibration_shakes_the_map_more_on_stair_edges_than_on_flat_ground() {
    let flat = world(Terrain::Flat, Shape::Flat);
    let stairs = world(Terrain::StairsUp, Shape::Stairs { x0: 0.0, rise: 0.17, run: 0.3, steps: 8 });
    let shaken = with(false, false, false, true);
    let on_flat = spread(&shaken, &flat, 0.3..1.6);
    let on_stairs = spread(&shaken, &stairs, 0.3..1.6);
    assert!(on_flat > 0.0, "vibration changed nothing on flat ground");
    assert!(on_stairs > 2.0 * on_flat, "height spread {on_stairs} on stairs, {on_flat} on flat ground");
    // The edge rule, not the stairs' shape alone: with the flat sd on the
    // stairs too the spread is smaller.
    let mut even = shaken.clone();
    even.vibration.per_edge = 0.0;
    let flat_rule = spread(&even, &stairs, 0.3..1.6);
    eprintln!("vibration spread: flat {on_flat}, stairs {on_stairs}, stairs with the flat sd {flat_rule}");
    assert!(on_stairs > 1.25 * flat_rule, "edge rule {on_stairs}, flat sd on stairs {flat_rule}");
}
