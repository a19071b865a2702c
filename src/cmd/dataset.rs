//! `odocal dataset`: builds the training set (dataset.json) from a run manifest — odometry
//! logs plus camera trajectories (or videos, tracked first).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use odocal_calib::CameraFile;
use odocal_dataset::build::{
    assemble, process_recording, samples_csv, BuildOptions, Recording, RunOutcome,
};
use odocal_dataset::{Manifest, ManifestRow, OdometryLog, RobotParams, Trajectory};
use odocal_tracker::{open_source, track_source, SourceOptions, TrackOptions};
use rayon::prelude::*;

use crate::output::{progress, write_atomic, write_json};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Run manifest (JSON "odocal.manifest/1" or CSV id,video,trajectory,odometry,speed_mps).
    #[arg(long)]
    pub manifest: PathBuf,
    /// Camera calibration (camera.json), needed for rows with a video.
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Output dataset.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the samples as CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Robot parameters JSON ("format": "odocal.robot/1"); default: the source's robot.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Shortest stop, seconds, that splits a recording into separate runs.
    #[arg(long, default_value_t = odocal_dataset::build::DEFAULT_MIN_GAP_S)]
    pub min_gap_s: f64,
}

/// Tracks the robot's tag through a run's video into its floor trajectory,
/// with the tracker's defaults (tag36h11 id 0, 8 cm, 8 cm above the floor).
pub fn trajectory_from_video(
    row: &ManifestRow,
    video: &Path,
    camera: &CameraFile,
) -> anyhow::Result<Trajectory> {
    let floor = camera
        .floor
        .as_ref()
        .map(|f| f.floor_to_camera)
        .with_context(|| {
            format!(
                "run \"{}\": the camera calibration has no floor plane (calibrate with --floor)",
                row.id
            )
        })?;
    let source = open_source(video, &SourceOptions::default())
        .with_context(|| format!("run \"{}\"", row.id))?;
    let result = track_source(
        source,
        &camera.camera,
        &floor,
        &TrackOptions::default(),
        &mut |_, _| Ok(()),
    )
    .with_context(|| format!("run \"{}\": tracking {}", row.id, video.display()))?;
    Ok(result.trajectory()?)
}

fn one_row(
    m: &Manifest,
    row: &ManifestRow,
    camera: Option<&CameraFile>,
    opts: &BuildOptions,
) -> anyhow::Result<Vec<RunOutcome>> {
    let log = OdometryLog::read_csv(&m.resolve(&row.odometry))?;
    let traj = match (&row.trajectory, &row.video) {
        (Some(t), _) => Trajectory::read_csv(&m.resolve(t))?,
        (None, Some(v)) => match camera {
            Some(c) => trajectory_from_video(row, &m.resolve(v), c)?,
            None => bail!(
                "run \"{}\" has a video: give the calibration with --camera camera.json",
                row.id
            ),
        },
        (None, None) => bail!("run \"{}\": no video and no trajectory", row.id),
    };
    let rec = Recording {
        id: &row.id,
        speed_mps: row.speed_mps,
        log: &log,
        camera: &traj,
    };
    Ok(process_recording(&rec, opts)?)
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.min_gap_s.is_finite() && args.min_gap_s > 0.0) {
        bail!("--min-gap-s must be a positive number of seconds");
    }
    let manifest = Manifest::read(&args.manifest)?;
    manifest.check_files()?;
    if manifest.runs.iter().any(|r| r.video.is_some()) {
        match &args.camera {
            None => {
                bail!("the manifest lists videos: give the calibration with --camera camera.json")
            }
            Some(c) if !c.is_file() => bail!("camera calibration {} does not exist", c.display()),
            _ => {}
        }
    }
    let camera = match &args.camera {
        Some(p) => Some(CameraFile::load(p)?),
        None => None,
    };
    let robot = match &args.robot {
        Some(p) => RobotParams::read(p)?,
        None => RobotParams::default(),
    };
    let opts = BuildOptions {
        robot,
        min_gap_s: args.min_gap_s,
        ..BuildOptions::default()
    };
    let bar = progress(manifest.runs.len() as u64, "dataset");
    let work = |row: &ManifestRow| {
        let r = one_row(&manifest, row, camera.as_ref(), &opts);
        bar.inc(1);
        r
    };
    // Tracking a video already uses every core (and rayon inside the frame
    // decoder), so videos go one after another; trajectories in parallel.
    let results: Vec<anyhow::Result<Vec<RunOutcome>>> = if camera.is_some() {
        manifest.runs.iter().map(work).collect()
    } else {
        manifest.runs.par_iter().map(work).collect()
    };
    bar.finish_and_clear();
    let mut outcomes = Vec::with_capacity(results.len());
    for r in results {
        outcomes.push(r?);
    }
    let ds = assemble(robot, outcomes);
    write_json(&args.out, &ds).with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(csv) = &args.csv {
        write_atomic(csv, samples_csv(&ds).as_bytes())?;
    }
    let s = &ds.summary;
    println!(
        "dataset: {} samples from {} runs in {} recordings ({} rejected) -> {}",
        ds.samples.len(),
        s.runs,
        s.recordings,
        ds.rejected.len(),
        args.out.display()
    );
    for r in &ds.rejected {
        println!("  rejected {}: {}", r.run_id, r.reason);
    }
    if !ds.samples.is_empty() {
        println!(
            "raw odometry end-point error: {:.2} % of path length (RMS {:.1} mm, mean path {:.3} m)",
            100.0 * s.raw_relative_error,
            1e3 * s.raw_rms_error_m,
            s.mean_path_length_m
        );
        println!(
            "largest alignment residual: {:.4} m/s",
            s.max_alignment_residual_mps
        );
    }
    Ok(())
}
