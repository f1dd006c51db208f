//! dem-import: robot recordings (ROS 1 bags, ROS 2 MCAP and SQLite) of grid_map
//! elevation maps into the contract's DEM streams.
//!
//! Per recording, two passes over the file, each in bounded memory:
//! 1. the transforms (`/tf`, `/tf_static`) and joint states, which are
//!    small, into a [`tf::TfBuffer`] and a [`tf::JointTrack`]; so a map that
//!    arrives before the transform it needs still finds it;
//! 2. the maps: each is decoded in place ([`msg::GridMap`]), the robot's
//!    pose at the map's stamp looked up, and the 20 x 5 window resampled
//!    ([`window`]). Only the DEMs (840 bytes each) are kept.
//!
//! The DEMs are written in stamp order (recordings need not be) as
//! `OUT/<recording>.npy` with `OUT/<recording>_labels.csv`, each atomically.
//! A message that cannot be used is skipped and counted by kind, with a
//! warning naming the file, the topic and the message's index on its topic.

pub mod container;
pub mod geometry;
pub mod msg;
pub mod order;
pub mod tf;
pub mod window;
pub mod wire;

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use dem_core::format::{Dem, DemCells, Terrain};
use dem_core::{npy, output, table, DemError};
use rayon::prelude::*;

use container::{Event, StopError};
use order::{Imported, StampOrder};
use window::Resampling;

/// A validated request.
#[derive(Clone, Debug)]
pub struct ImportConfig {
    /// Recordings: `.bag`, `.mcap` or `.db3` files, or ROS 2 bag folders.
    pub recordings: Vec<PathBuf>,
    /// Output folder (created if missing).
    pub out: PathBuf,
    /// Topic of the maps; None: the recording's one GridMap topic.
    pub map_topic: Option<String>,
    /// How map cells become DEM cells.
    pub resampling: Resampling,
    /// The robot's frame: C, the DEM's centre.
    pub frame: String,
    /// Topic of `sensor_msgs/JointState`.
    pub joint_topic: String,
    /// Joint names of the flippers: front-left, front-right, rear-left, rear-right.
    pub flippers: [String; 4],
    /// Keep a map only this many seconds after the last one kept.
    pub every: Option<f64>,
    /// Terrain written into the labels (empty when None).
    pub terrain: Option<Terrain>,
}

/// Why a message was not turned into a DEM.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SkipKind {
    /// The message (or a part of the file) could not be decoded.
    Damaged,
    /// No transform from the map's frame to the robot's at the map's stamp.
    NoTransform,
    /// The map has no layer of that name.
    NoLayer,
}

impl SkipKind {
    /// Words for the summary.
    pub fn as_str(self) -> &'static str {
        match self {
            SkipKind::Damaged => "damaged",
            SkipKind::NoTransform => "without a transform",
            SkipKind::NoLayer => "without the layer",
        }
    }
}

/// What became of one recording.
#[derive(Clone, Debug, Default)]
pub struct RecordingReport {
    /// The recording as given.
    pub recording: String,
    /// The NPY written (None when the recording could not be read at all).
    pub npy: Option<String>,
    /// Map messages on the map topic.
    pub maps: u64,
    /// DEMs written.
    pub dems: u64,
    /// Maps left out by `--every`.
    pub thinned: u64,
    /// Skipped messages (and file parts) by kind.
    pub skipped: BTreeMap<SkipKind, u64>,
    /// The recording could not be read at all: why.
    pub failed: Option<String>,
    /// The file broke off here (messages before it were imported).
    pub broken: Option<String>,
    /// Seconds from the first to the last DEM.
    pub span: f64,
    /// True when no joint states of the flippers were found (row 20 holds
    /// zeros for them).
    pub no_flippers: bool,
    /// `failed` is a defect of dem-import (a panic caught), not bad input.
    pub internal: bool,
}

impl RecordingReport {
    /// Messages or parts skipped, plus 1 for a broken or unreadable file.
    pub fn problems(&self) -> u64 {
        self.skipped.values().sum::<u64>() + u64::from(self.failed.is_some()) + u64::from(self.broken.is_some())
    }
}

/// The outputs of a recording: `OUT/<name>.npy` and `OUT/<name>_labels.csv`.
pub fn outputs_of(out: &Path, recording: &Path) -> (String, String) {
    let name = recording.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "recording".into());
    let name = if recording.is_dir() { recording.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or(name) } else { name };
    let p = |suffix: &str| out.join(format!("{name}{suffix}")).to_string_lossy().into_owned();
    (p(".npy"), p("_labels.csv"))
}

/// Check the request before any work: outputs distinct, none an input.
pub fn check(cfg: &ImportConfig) -> Result<(), DemError> {
    if cfg.recordings.is_empty() {
        return Err(DemError::Usage("no recordings given".into()));
    }
    if let Some(r) = cfg.recordings.iter().find(|r| !r.exists()) {
        return Err(DemError::Open { path: r.display().to_string(), source: std::io::ErrorKind::NotFound.into() });
    }
    // Created only once the inputs are there, and removed again when the
    // outputs are refused: a refused run leaves nothing behind.
    let created = first_missing(&cfg.out);
    let checked = std::fs::create_dir_all(&cfg.out)
        .map_err(|e| DemError::Usage(format!("cannot create the output folder {}: {e}", cfg.out.display())))
        .and_then(|()| check_outputs(cfg));
    if let (Err(_), Some(top)) = (&checked, &created) {
        remove_created(&cfg.out, top);
    }
    checked
}

/// The topmost folder on the way to `out` that does not exist yet (None
/// when `out` exists): what creating `out` would create.
pub fn first_missing(out: &Path) -> Option<PathBuf> {
    let mut top = None;
    let mut p = Some(out);
    while let Some(dir) = p.filter(|d| !d.as_os_str().is_empty() && !d.exists()) {
        top = Some(dir.to_path_buf());
        p = dir.parent();
    }
    top
}

/// Remove `out` and its parents up to `top`, each only when empty: the
/// folders a run that wrote nothing created.
pub fn remove_created(out: &Path, top: &Path) {
    let mut p = Some(out);
    while let Some(dir) = p {
        if std::fs::remove_dir(dir).is_err() || dir == top {
            break;
        }
        p = dir.parent();
    }
}

fn check_outputs(cfg: &ImportConfig) -> Result<(), DemError> {
    let mut outputs = Vec::new();
    let mut inputs = Vec::new();
    for r in &cfg.recordings {
        let (npy, labels) = outputs_of(&cfg.out, r);
        if outputs.contains(&npy) {
            return Err(DemError::Usage(format!(
                "two recordings would both write {npy}: rename one or import them into different folders"
            )));
        }
        outputs.push(npy);
        outputs.push(labels);
        if let Ok(files) = container::files_of(r) {
            inputs.extend(files.into_iter().map(|(_, p)| p.to_string_lossy().into_owned()));
        }
    }
    let ins: Vec<&str> = inputs.iter().map(String::as_str).collect();
    let outs: Vec<&str> = outputs.iter().map(String::as_str).collect();
    output::check_outputs(&ins, &outs)
}

/// Total bytes of the recordings' files (for a progress bar over both passes: twice this).
pub fn total_bytes(cfg: &ImportConfig) -> u64 {
    cfg.recordings
        .iter()
        .filter_map(|r| container::files_of(r).ok())
        .flatten()
        .filter_map(|(_, p)| std::fs::metadata(p).ok())
        .map(|m| m.len())
        .sum()
}

/// Import every recording (in parallel), calling `progress` with bytes read
/// (both passes) and `warn` with each warning line. Returns one report per
/// recording, in order. Err only for failures to write outputs.
pub fn import(cfg: &ImportConfig, progress: &(dyn Fn(u64) + Sync), warn: &(dyn Fn(&str) + Sync)) -> Result<Vec<RecordingReport>, DemError> {
    let done = AtomicU64::new(0);
    let tick = |n: u64| progress(done.fetch_add(n, Ordering::Relaxed) + n);
    cfg.recordings
        .par_iter()
        .enumerate()
        .map(|(seq, r)| {
            // A defect (a panic) costs its recording, not the batch.
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| import_one(cfg, r, seq as u64, &tick, warn))).unwrap_or_else(|panic| {
                let what = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                Ok(RecordingReport {
                    recording: r.display().to_string(),
                    failed: Some(format!("internal error, a defect of dem-import (please report it with this file): {what}")),
                    internal: true,
                    ..Default::default()
                })
            })
        })
        .collect()
}

/// Warnings per kind printed for one recording; the rest are counted only.
const WARNINGS_PER_KIND: u64 = 5;

struct Recording<'a> {
    name: String,
    report: RecordingReport,
    warn: &'a (dyn Fn(&str) + Sync),
}

impl Recording<'_> {
    fn skip(&mut self, kind: SkipKind, what: String) {
        let n = self.report.skipped.entry(kind).or_default();
        *n += 1;
        if *n <= WARNINGS_PER_KIND {
            (self.warn)(&format!("warning: {what}, skipped"));
        }
        if *n == WARNINGS_PER_KIND + 1 {
            (self.warn)(&format!("warning: {}: further messages {} are counted, not shown", self.name, kind.as_str()));
        }
    }
}

fn is_tf_topic(topic: &str) -> Option<bool> {
    match msg::strip_slash(topic) {
        "tf" => Some(false),
        "tf_static" => Some(true),
        _ => None,
    }
}

/// The index of this message on `topic` (the messages seen on it before), counted.
fn bump(seen: &mut HashMap<String, u64>, topic: &str) -> u64 {
    match seen.get_mut(topic) {
        Some(k) => {
            *k += 1;
            *k - 1
        }
        None => {
            seen.insert(topic.to_string(), 1);
            0
        }
    }
}

#[derive(serde::Serialize)]
struct LabelRow {
    index: u64,
    terrain: &'static str,
    x: f64,
    y: f64,
    yaw: f64,
    sequence: u64,
    time: f64,
}

fn import_one(
    cfg: &ImportConfig,
    path: &Path,
    seq: u64,
    tick: &(dyn Fn(u64) + Sync),
    warn: &(dyn Fn(&str) + Sync),
) -> Result<RecordingReport, DemError> {
    let name = path.display().to_string();
    let mut rec = Recording { name: name.clone(), report: RecordingReport { recording: name.clone(), ..Default::default() }, warn };
    let files = match container::files_of(path) {
        Ok(f) => f,
        Err(why) => {
            rec.report.failed = Some(why);
            return Ok(rec.report);
        }
    };

    // Pass 1: transforms, joints, and which topics hold maps.
    let mut tfs = tf::TfBuffer::default();
    let mut joints = tf::JointTrack::default();
    let mut map_topics: BTreeSet<String> = BTreeSet::new();
    let mut all_topics: BTreeMap<String, String> = BTreeMap::new();
    let joint_topic = msg::strip_slash(&cfg.joint_topic).to_string();
    let mut breaks: Vec<String> = Vec::new();
    for (kind, file) in &files {
        let fname = file.display().to_string();
        let mut seen: HashMap<String, u64> = HashMap::new();
        let mut last = 0;
        let result = container::read(
            *kind,
            file,
            &mut |e| match e {
                Event::Message { conn, data } => {
                    let index = bump(&mut seen, &conn.topic);
                    if index == 0 && !all_topics.contains_key(&conn.topic) {
                        all_topics.insert(conn.topic.clone(), conn.msg_type.clone());
                    }
                    let at = || format!("{fname}: topic {}, message {index}", conn.topic);
                    match conn.msg_type.as_str() {
                        "tf2_msgs/TFMessage" => {
                            if let Some(is_static) = is_tf_topic(&conn.topic) {
                                match msg::decode_tf(data, conn.encoding) {
                                    Ok(ts) => {
                                        for t in ts {
                                            if let Err(why) = tfs.insert(t, is_static) {
                                                rec.skip(SkipKind::Damaged, format!("{}: {why}", at()));
                                            }
                                        }
                                    }
                                    Err(why) => rec.skip(SkipKind::Damaged, format!("{}: {why}", at())),
                                }
                            }
                        }
                        "sensor_msgs/JointState" if msg::strip_slash(&conn.topic) == joint_topic => {
                            match msg::decode_joint_state(data, conn.encoding) {
                                Ok(mut js) => {
                                    // Only the flippers are looked up: the other joints are not kept.
                                    let kept = js.names.iter().zip(&js.positions).filter(|(n, _)| cfg.flippers.contains(n));
                                    (js.names, js.positions) = kept.map(|(n, p)| (n.clone(), *p)).unzip();
                                    for (name, p) in joints.insert(&js) {
                                        if cfg.flippers.contains(&name) {
                                            rec.skip(
                                                SkipKind::Damaged,
                                                format!("{}: flipper joint {name} at {} rad is not an angle", at(), msg::num(p)),
                                            );
                                        }
                                    }
                                }
                                Err(why) => rec.skip(SkipKind::Damaged, format!("{}: {why}", at())),
                            }
                        }
                        "grid_map_msgs/GridMap" if index == 0 => {
                            map_topics.insert(conn.topic.clone());
                        }
                        _ => {}
                    }
                }
                Event::Skipped { offset, reason } => rec.skip(SkipKind::Damaged, format!("{fname}: byte {offset}: {reason}")),
            },
            &mut |b| {
                tick(b - last);
                last = b;
            },
        );
        match result {
            Ok(()) => {}
            Err(StopError::Broken { offset, reason }) => {
                // Warned once the map topic is known; else it is why nothing was imported.
                breaks.push(format!("{fname}: byte {offset}: {reason}"));
            }
            Err(e) => {
                rec.report.failed = Some(format!("{fname}: {e}"));
                return Ok(rec.report);
            }
        }
    }
    tfs.finish();
    joints.finish();

    let topic = match pick_map_topic(cfg, &map_topics, &all_topics) {
        Ok(t) => t,
        Err(why) if !breaks.is_empty() => {
            rec.report.failed = Some(format!("{}; before it: {why}", breaks.join("; ")));
            return Ok(rec.report);
        }
        Err(why) => {
            rec.report.failed = Some(why);
            return Ok(rec.report);
        }
    };
    for what in &breaks {
        warn(&format!("warning: {what}; the messages before it are imported"));
    }
    rec.report.broken = breaks.pop();
    rec.report.no_flippers = !cfg.flippers.iter().any(|f| joints.has(f));

    // Pass 2: the maps.
    // Bounded whatever the recording's length: spilled in sorted runs past a cap.
    let mut dems: StampOrder<Imported> = StampOrder::new(&cfg.out);
    for (kind, file) in &files {
        let fname = file.display().to_string();
        let mut index = 0u64;
        let mut last = 0;
        // The break (if any) was reported in pass 1.
        let _ = container::read(
            *kind,
            file,
            &mut |e| {
                let Event::Message { conn, data } = e else { return };
                if conn.topic != topic {
                    return;
                }
                let k = index;
                index += 1;
                let at = || format!("{fname}: topic {topic}, message {k}");
                let map = match msg::GridMap::decode(data, conn.encoding) {
                    Ok(m) => m,
                    Err(why) => return rec.skip(SkipKind::Damaged, format!("{}: {why}", at())),
                };
                let base = match tfs.lookup(msg::strip_slash(map.frame), &cfg.frame, map.stamp) {
                    Ok(b) => b,
                    Err(why) => return rec.skip(SkipKind::NoTransform, format!("{}: {why}", at())),
                };
                let mut dem = match window::resample(&map, &base, &cfg.resampling) {
                    Ok(d) => d,
                    Err(why) => return rec.skip(SkipKind::NoLayer, format!("{}: {why}", at())),
                };
                let (yaw, pitch) = base.rotation.heading_and_pitch();
                let flipper = |k: usize| joints.at(&cfg.flippers[k], map.stamp).unwrap_or(0.0) as f32;
                dem.set_attitude([pitch as f32, flipper(0), flipper(1), flipper(2), flipper(3)]);
                if let Err(why) = usable(&dem) {
                    return rec.skip(SkipKind::Damaged, format!("{}: {why}", at()));
                }
                dems.push(Imported { stamp: map.stamp, dem, x: base.translation.x, y: base.translation.y, yaw });
            },
            &mut |b| {
                tick(b - last);
                last = b;
            },
        );
        rec.report.maps += index;
    }

    // In stamp order: --every keeps a DEM DT or more after the last kept;
    // label times count from the first.
    let terrain = cfg.terrain.map_or("", Terrain::as_str);
    let step = cfg.every.map(|every| (every * 1e9).round() as i64);
    let (npy_path, labels_path) = outputs_of(&cfg.out, path);
    let mut writer = npy::create(&npy_path)?;
    let mut labels = table::RowWriter::create(&labels_path)?;
    let (mut first, mut last, mut written) = (None::<i64>, 0i64, 0u64);
    let mut write_error: Option<DemError> = None;
    let sorted = dems.finish(&mut |d| {
        if step.is_some_and(|step| first.is_some() && d.stamp - last < step) {
            rec.report.thinned += 1;
            return Ok(());
        }
        let t0 = *first.get_or_insert(d.stamp);
        last = d.stamp;
        let row = LabelRow { index: written, terrain, x: d.x, y: d.y, yaw: d.yaw, sequence: seq, time: (d.stamp - t0) as f64 * 1e-9 };
        if let Err(e) = writer.write(std::slice::from_ref(&d.dem)).and_then(|()| labels.write(&row)) {
            write_error = Some(e);
            return Err(std::io::Error::other("output failed"));
        }
        written += 1;
        Ok(())
    });
    if let Some(e) = write_error {
        return Err(e);
    }
    sorted.map_err(|e| DemError::io(format!("{} (sorted runs of DEMs)", cfg.out.display()), e))?;
    writer.finish()?;
    labels.commit()?;
    rec.report.span = first.map_or(0.0, |f| (last - f) as f64 * 1e-9);
    rec.report.dems = written;
    rec.report.npy = Some(npy_path);
    Ok(rec.report)
}

fn pick_map_topic(cfg: &ImportConfig, map_topics: &BTreeSet<String>, all: &BTreeMap<String, String>) -> Result<String, String> {
    let listed = |m: &BTreeSet<String>| m.iter().cloned().collect::<Vec<_>>().join(", ");
    match &cfg.map_topic {
        Some(t) => {
            let found = map_topics.iter().find(|k| msg::strip_slash(k) == msg::strip_slash(t));
            match (found, all.iter().find(|(k, _)| msg::strip_slash(k) == msg::strip_slash(t))) {
                (Some(k), _) => Ok(k.clone()),
                (None, Some((_, ty))) => Err(format!("topic {t} holds {ty}, not grid_map_msgs/GridMap")),
                (None, None) if map_topics.is_empty() => Err(format!("no topic {t} and no grid_map_msgs/GridMap topic at all")),
                (None, None) => Err(format!("no topic {t} (GridMap topics: {})", listed(map_topics))),
            }
        }
        None => match map_topics.len() {
            1 => Ok(map_topics.iter().next().expect("one").clone()),
            0 => Err(format!(
                "no grid_map_msgs/GridMap topic (topics: {})",
                if all.is_empty() { "none".to_string() } else { all.keys().cloned().collect::<Vec<_>>().join(", ") }
            )),
            _ => Err(format!("several GridMap topics ({}): choose one with --map-topic", listed(map_topics))),
        },
    }
}

/// Heights further than this above or below the robot (m) are no terrain
/// around it: a damaged map or transform.
pub const MAX_HEIGHT: f32 = 1e5;

/// Err naming the first value of `dem` that is not finite or, for a
/// height, beyond [`MAX_HEIGHT`]: such a DEM is not written (the
/// contract allows no infinity).
fn usable(dem: &Dem) -> Result<(), String> {
    use dem_core::format::{COLS, GRID_ROWS};
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let h = dem.height(r, c);
            if dem.is_valid(r, c) && !(h.is_finite() && h.abs() <= MAX_HEIGHT) {
                return Err(format!(
                    "height {} m at DEM row {r}, column {c} (the map's height minus the robot's z) is beyond {} m",
                    msg::num(h),
                    msg::num(f64::from(MAX_HEIGHT))
                ));
            }
        }
    }
    match dem.attitude().iter().position(|a| !a.is_finite()) {
        Some(k) => Err(format!("attitude value {k} of row 20 is {}", dem.attitude()[k])),
        None => Ok(()),
    }
}

/// The one-line summary of a report.
pub fn summary(r: &RecordingReport) -> String {
    if let Some(why) = &r.failed {
        let why = why.strip_prefix(&format!("{}: ", r.recording)).unwrap_or(why);
        return format!("{}: not imported: {why}", r.recording);
    }
    let mut s = format!("{}: {} maps -> {} DEMs in {}", r.recording, r.maps, r.dems, r.npy.as_deref().unwrap_or("-"));
    s.push_str(&format!(" ({:.1} s)", r.span));
    if r.thinned > 0 {
        s.push_str(&format!(", {} left out by --every", r.thinned));
    }
    let skipped: u64 = r.skipped.values().sum();
    if skipped > 0 {
        let parts: Vec<String> = r.skipped.iter().map(|(k, n)| format!("{n} {}", k.as_str())).collect();
        s.push_str(&format!(", {skipped} skipped: {}", parts.join(", ")));
    }
    if r.broken.is_some() {
        s.push_str(", the file breaks off");
    }
    if r.no_flippers && r.dems > 0 {
        s.push_str(", no flipper joint states (zeros in row 20)");
    }
    s
}
