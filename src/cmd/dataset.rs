//! `odocal dataset`: builds the training set (dataset.json) from a run manifest — odometry
//! logs plus camera trajectories (or videos, tracked first).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use odocal_calib::CameraFile;
use odocal_dataset::build::{
    assemble, process_recording, samples_csv, BuildOptions, Recording, RunOutcome,
};
use odocal_dataset::oracle::OracleFile;
use odocal_dataset::{Manifest, ManifestRow, OdometryLog, RobotParams, Trajectory};
use odocal_tracker::{open_source, track_source, SourceOptions, TrackOptions};
use rayon::prelude::*;

use crate::output::{count, progress, write_atomic, write_json};

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
    /// Truth of a synthetic experiment (truth/oracle.json from `odocal synth experiment`):
    /// also print the targets' and clock offsets' errors against it.
    #[arg(long)]
    pub truth: Option<PathBuf>,
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
    // A wrong truth file is found before the work, not after the dataset is written.
    let oracle = args.truth.as_deref().map(OracleFile::read).transpose()?;
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
    let results: Vec<anyhow::Result<Vec<RunOutcome>>> = if camera.is_some() {
        // Videos are tracked on plain threads, one video per core at a time
        // (each tracker also runs a decoder thread of its own, so tracking
        // never waits on a busy rayon pool).
        let threads = std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
            .min(manifest.runs.len().max(1));
        let next = std::sync::atomic::AtomicUsize::new(0);
        let mut slots: Vec<Option<anyhow::Result<Vec<RunOutcome>>>> =
            (0..manifest.runs.len()).map(|_| None).collect();
        let done = std::sync::Mutex::new(&mut slots);
        std::thread::scope(|scope| {
            for _ in 0..threads {
                scope.spawn(|| loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(row) = manifest.runs.get(i) else {
                        break;
                    };
                    let r = work(row);
                    done.lock().unwrap_or_else(|e| e.into_inner())[i] = Some(r);
                });
            }
        });
        slots
            .into_iter()
            .zip(&manifest.runs)
            .map(|(r, row)| {
                r.unwrap_or_else(|| Err(anyhow::anyhow!("run \"{}\" was not processed", row.id)))
            })
            .collect()
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
        "dataset: {} from {} in {} ({} rejected) -> {}",
        count(ds.samples.len(), "sample"),
        count(s.runs, "run"),
        count(s.recordings, "recording"),
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
    if let (Some(path), Some(oracle)) = (&args.truth, &oracle) {
        let (mut target, mut offset) = (Vec::new(), Vec::new());
        for sample in &ds.samples {
            let t = oracle.get(&sample.run_id).with_context(|| {
                format!(
                    "{}: no truth for run \"{}\"; is this the experiment's truth/oracle.json?",
                    path.display(),
                    sample.run_id
                )
            })?;
            target.push(
                (sample.target_m[0] - t.true_end_m[0]).hypot(sample.target_m[1] - t.true_end_m[1]),
            );
            offset.push((sample.clock_offset_s - t.clock_offset_s).abs());
        }
        if !target.is_empty() {
            let rms = |v: &[f64]| (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt();
            let max = |v: &[f64]| v.iter().fold(0.0f64, |m, e| m.max(*e));
            println!(
                "against the truth: end-point targets RMS {:.2} mm (max {:.2} mm), clock offsets RMS {:.2} ms (max {:.2} ms) over {} samples",
                1e3 * rms(&target),
                1e3 * max(&target),
                1e3 * rms(&offset),
                1e3 * max(&offset),
                target.len()
            );
        }
    }
    Ok(())
}
