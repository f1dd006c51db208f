//! dem-import: robot recordings into DEM streams.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use dem_core::cli::{self, value};
use dem_core::{DemError, Terrain};
use dem_import::window::Resampling;
use dem_import::{import, summary, ImportConfig};

/// Import robot recordings, ROS 1 bags (.bag) and ROS 2 bags (.mcap or
/// SQLite .db3 files, or bag folders), in which elevation mapping published
/// grid_map_msgs/GridMap messages, into the DEM contract: for each map, the
/// robot's pose at the map's stamp from TF (the chain from the map's frame
/// to --frame, interpolated), the 20 x 5 window of 10 cm cells in the
/// robot's heading frame resampled from the map's cells, heights relative
/// to C, and pitch and the four flipper angles (from --joint-topic) in row
/// 20. Writes OUT/<recording>.npy and OUT/<recording>_labels.csv
/// (index,terrain,x,y,yaw,sequence,time) per recording, in stamp order, and
/// prints a summary per recording on stderr.
///
/// A damaged message, a map without a transform, a file that breaks off: the
/// message (or the rest of the file) is skipped with a warning naming the
/// file, the topic and the message's index on it, and counted; the exit
/// status is then 1 unless --keep-going.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-import --out dems/ field/*.bag
  dem-import --map-topic /elevation_mapping/elevation_map --frame base_link \\
      --every 0.4 --terrain stairs-up --out dems/ stairs_2024-05-01.mcap
  # a folder of recordings, then one stream of all their DEMs:
  dem-import --out dems/ --keep-going recordings/*.bag && dem-cat dems/*.npy -o real.npy
  dem-render dems/run1.npy --start 40 --count 24 -o run1.png"
)]
struct Args {
    /// Recordings: .bag, .mcap or .db3 files, or ROS 2 bag folders (of .mcap or .db3 files).
    #[arg(required = true)]
    recordings: Vec<PathBuf>,
    /// Output folder (created if missing).
    #[arg(long, short = 'o')]
    out: PathBuf,
    /// Topic of the grid_map_msgs/GridMap messages (default: the
    /// recording's only GridMap topic).
    #[arg(long)]
    map_topic: Option<String>,
    /// Map layer with the heights.
    #[arg(long, default_value = "elevation")]
    layer: String,
    /// The robot's frame: C, the centre of the DEM.
    #[arg(long, default_value = "base_link")]
    frame: String,
    /// Topic of sensor_msgs/JointState with the flipper joints.
    #[arg(long, default_value = "/joint_states")]
    joint_topic: String,
    /// Flipper joint names: front-left, front-right, rear-left, rear-right.
    #[arg(
        long,
        value_name = "FL,FR,RL,RR",
        value_delimiter = ',',
        default_value = "front_left_flipper_j,front_right_flipper_j,rear_left_flipper_j,rear_right_flipper_j"
    )]
    flippers: Vec<String>,
    /// Keep a map only DT seconds or more after the last one kept.
    #[arg(long, value_name = "DT", value_parser = value::positive::<f64>)]
    every: Option<f64>,
    /// Terrain for the labels' terrain column (empty without it).
    #[arg(long)]
    terrain: Option<Terrain>,
    /// Map cells with a larger variance (layer --variance-layer) are missing (m^2).
    #[arg(long, value_parser = value::positive::<f64>)]
    max_variance: Option<f64>,
    /// Map layer with the height variance, for --max-variance.
    #[arg(long, default_value = "variance")]
    variance_layer: String,
    /// Share of a DEM cell's sample points (at a 5 cm map: its 4 quarter
    /// centres) that must fall on valid map cells.
    #[arg(long = "min-valid-points", value_name = "SHARE", default_value_t = 0.5, value_parser = value::fraction::<f64>)]
    min_valid: f64,
    /// Exit 0 even when messages or recordings were skipped.
    #[arg(long)]
    keep_going: bool,
    /// Worker threads, 1 to 1024 (default: all cores; recordings run in
    /// parallel, one per thread).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        if a.min_valid <= 0.0 {
            return Err(cli::usage("--min-valid-points must be > 0"));
        }
        if let Some(n) = a.threads {
            // One recording per thread: more threads than recordings would idle.
            let n = (n as usize).min(a.recordings.len()).max(1);
            rayon::ThreadPoolBuilder::new().num_threads(n).build_global()?;
        }
        let flippers: [String; 4] = a.flippers.try_into().map_err(|_| cli::usage("--flippers takes four joint names"))?;
        let cfg = ImportConfig {
            recordings: a.recordings,
            out: a.out,
            map_topic: a.map_topic,
            resampling: Resampling {
                layer: a.layer,
                variance_layer: a.variance_layer,
                max_variance: a.max_variance,
                min_valid: a.min_valid,
            },
            frame: a.frame,
            joint_topic: a.joint_topic,
            flippers,
            every: a.every,
            terrain: a.terrain,
        };
        let created = dem_import::first_missing(&cfg.out);
        dem_import::check(&cfg)?;
        let bar = cli::progress(2 * dem_import::total_bytes(&cfg), "bytes");
        let reports = import(&cfg, &|b| bar.set_position(b), &|line| bar.suspend(|| cli::log(line)))?;
        bar.finish_and_clear();
        // A recording that could not be read at all (not a recording, no
        // such --map-topic) is bad input: exit 2, after the others are
        // written; a run that wrote nothing leaves no output folder.
        let failed = reports.iter().filter(|r| r.failed.is_some()).count();
        if let (Some(top), true) = (&created, reports.iter().all(|r| r.npy.is_none())) {
            dem_import::remove_created(&cfg.out, top);
        }
        if failed == 1 && reports.len() == 1 && !a.keep_going && !reports[0].internal {
            // One line: the summary is the error.
            return Err(DemError::Usage(summary(&reports[0])).into());
        }
        for r in &reports {
            cli::log(summary(r));
        }
        let bad = reports.iter().filter(|r| r.problems() > 0).count();
        let dems: u64 = reports.iter().map(|r| r.dems).sum();
        if reports.len() > 1 {
            cli::log(format_args!("{dems} DEMs from {} recordings", reports.len()));
        }
        if reports.iter().any(|r| r.internal) {
            anyhow::bail!("a defect of dem-import stopped a recording (see above)");
        }
        if a.keep_going {
            return Ok(());
        }
        if failed > 0 {
            let what = format!("{failed} of {} recordings could not be imported (see above; --keep-going accepts that)", reports.len());
            return Err(DemError::Usage(what).into());
        }
        if bad > 0 {
            anyhow::bail!("{bad} of {} recordings had skipped messages (see above; --keep-going accepts that)", reports.len());
        }
        Ok(())
    })
}
