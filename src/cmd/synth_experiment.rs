//! `odocal synth experiment`: the whole odometry experiment of source A with known truth —
//! a run manifest, per recording a 200 ms tick log and a ceiling video (or, with
//! `--frames none`, the camera trajectory taken from the truth), and the truth itself.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use odocal_core::Pose2;
use odocal_dataset::manifest::{Manifest, ManifestRow};
use odocal_dataset::oracle::{OracleFile, OracleRun};
use odocal_dataset::WheelGeometry;
use odocal_synth::board::CalibScene;
use odocal_synth::robot::{
    simulate_recording, CameraTiming, RobotSimConfig, RunTruth, SimulatedRecording, TruthTrack,
};
use odocal_synth::scene::{render_video as render_scene_video, SceneConfig, VideoFormat};
use rayon::prelude::*;
use serde::Serialize;

use crate::output::{count, progress, write_atomic, write_json};

/// What stands for the camera.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Frames {
    /// Render ceiling videos (tracked later by `odocal dataset`).
    Video,
    /// No video: the true trajectory at the camera's frame times (with its clock offset and
    /// the configured mm-level noise) is written as the camera trajectory.
    None,
}

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Number of runs.
    #[arg(long, default_value_t = 131)]
    pub runs: usize,
    /// Random seed (same seed, same bytes).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Camera source: rendered videos or trajectories from the truth.
    #[arg(long, value_enum, default_value_t = Frames::Video)]
    pub frames: Frames,
    /// Runs per recording: more than 1 puts several runs, separated by stops and carrying the
    /// robot back, in one log and one video (`odocal dataset` splits them by motion).
    #[arg(long, default_value_t = 1)]
    pub runs_per_recording: usize,
    /// Simulator configuration JSON ("format": "odocal.robotsim/1"; absent fields take defaults).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// With --frames video, do not also write the calibration views (calib/), e.g. when
    /// `odocal synth calib` has already written them (same camera, any seed works).
    #[arg(long)]
    pub no_calib_views: bool,
}

/// Truth of one recording, as written to truth/experiment.json.
#[derive(Serialize)]
struct RecordingTruth {
    id: String,
    clock_offset_s: f64,
    camera_end_s: f64,
    runs: Vec<NamedRun>,
}

#[derive(Serialize)]
struct NamedRun {
    run_id: String,
    #[serde(flatten)]
    truth: RunTruth,
}

#[derive(Serialize)]
struct ExperimentTruth<'a> {
    format: &'static str,
    seed: u64,
    frames: Frames,
    runs: usize,
    runs_per_recording: usize,
    config: &'a RobotSimConfig,
    recordings: Vec<RecordingTruth>,
}

/// Renders the ceiling video of one recording to `path` (MJPG AVI): frame k
/// at camera time k / fps, the robot at its true floor pose, seen by the same
/// camera as `synth calib` renders.
pub fn render_video(
    rec: &SimulatedRecording,
    camera: &CameraTiming,
    path: &Path,
    seed: u64,
) -> anyhow::Result<()> {
    let times = rec.frame_times(camera.fps);
    let trajectory: Vec<(f64, Pose2)> = times
        .iter()
        .filter_map(|&t| rec.pose_at_camera_time(t).map(|p| (t, p)))
        .collect();
    if trajectory.len() != times.len() {
        bail!(
            "--frames video renders one run per recording (the robot is carried between runs); \
             use --runs-per-recording 1 or --frames none"
        );
    }
    render_scene_video(
        path,
        VideoFormat::Avi,
        &SceneConfig::default(),
        &trajectory,
        camera.fps,
        seed,
    )?;
    Ok(())
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.runs == 0 {
        bail!("--runs must be at least 1");
    }
    if args.runs_per_recording == 0 {
        bail!("--runs-per-recording must be at least 1");
    }
    let cfg = match &args.config {
        Some(p) => RobotSimConfig::read(p)?,
        None => RobotSimConfig::default(),
    };
    let per = args.runs_per_recording;
    if args.frames == Frames::Video && per > 1 {
        bail!("--frames video renders one run per recording: use --runs-per-recording 1 or --frames none");
    }
    let n_rec = args.runs.div_ceil(per);
    let out = &args.out;
    std::fs::create_dir_all(out.join("runs"))
        .with_context(|| format!("cannot create {}", out.display()))?;
    std::fs::create_dir_all(out.join("truth"))
        .with_context(|| format!("cannot create {}", out.display()))?;
    let bar = progress(n_rec as u64, "simulate");
    let results: Vec<anyhow::Result<(ManifestRow, RecordingTruth, Vec<OracleRun>)>> = (0..n_rec)
        .into_par_iter()
        .map(|r| {
            let res = one_recording(&args, &cfg, r, per);
            bar.inc(1);
            res
        })
        .collect();
    bar.finish_and_clear();
    let mut rows = Vec::with_capacity(n_rec);
    let mut truths = Vec::with_capacity(n_rec);
    let mut oracle = Vec::with_capacity(args.runs);
    for res in results {
        let (row, truth, orc) = res?;
        rows.push(row);
        truths.push(truth);
        oracle.extend(orc);
    }
    if args.frames == Frames::Video && !args.no_calib_views {
        // The calibration views of the same camera, so the videos can be tracked.
        crate::cmd::synth_calib::write_calib_set(
            &out.join("calib"),
            &CalibScene::default(),
            args.seed,
        )?;
    }
    let manifest = Manifest::new(rows, out);
    write_atomic(
        &out.join("manifest.json"),
        format!("{}\n", manifest.to_json()).as_bytes(),
    )?;
    write_json(
        &out.join("truth").join("oracle.json"),
        &OracleFile::new(oracle),
    )?;
    write_json(&out.join("truth").join("simulator.json"), &cfg)?;
    write_json(
        &out.join("truth").join("experiment.json"),
        &ExperimentTruth {
            format: "odocal.experiment-truth/1",
            seed: args.seed,
            frames: args.frames,
            runs: args.runs,
            runs_per_recording: per,
            config: &cfg,
            recordings: truths,
        },
    )?;
    println!(
        "synth experiment: {} in {} (seed {}, frames {}) -> {}",
        count(args.runs, "run"),
        count(n_rec, "recording"),
        args.seed,
        match args.frames {
            Frames::Video => "video",
            Frames::None => "none",
        },
        out.join("manifest.json").display()
    );
    Ok(())
}

fn one_recording(
    args: &Args,
    cfg: &RobotSimConfig,
    r: usize,
    per: usize,
) -> anyhow::Result<(ManifestRow, RecordingTruth, Vec<OracleRun>)> {
    let first = r * per;
    let last = (first + per).min(args.runs);
    let speeds: Vec<f64> = (first..last).map(|i| cfg.speed_of_run(i)).collect();
    let id = if per == 1 {
        format!("run{:03}", r + 1)
    } else {
        format!("rec{:03}", r + 1)
    };
    let rec = simulate_recording(cfg, &speeds, args.seed, r as u64)?;
    if rec.runs.len() != speeds.len() {
        bail!(
            "recording {id}: simulated {} of {} runs",
            rec.runs.len(),
            speeds.len()
        );
    }
    let log = rec.odometry_log()?;
    let odo_rel = format!("runs/{id}.odometry.csv");
    write_atomic(&args.out.join(&odo_rel), log.to_csv().as_bytes())?;
    let (video, trajectory) = match args.frames {
        Frames::None => {
            let traj = rec.camera_track(&cfg.camera, args.seed, (1u64 << 32) + r as u64)?;
            let rel = format!("runs/{id}.trajectory.csv");
            write_atomic(&args.out.join(&rel), traj.to_csv().as_bytes())?;
            (None, Some(rel))
        }
        Frames::Video => {
            let rel = format!("runs/{id}.avi");
            let seed = args.seed.wrapping_mul(1_000_003).wrapping_add(r as u64);
            render_video(&rec, &cfg.camera, &args.out.join(&rel), seed)?;
            (Some(rel), None)
        }
    };
    // True trajectory at 100 Hz on both clocks.
    let csv = TruthTrack::of_recording(&rec).to_csv();
    write_atomic(
        &args.out.join("truth").join(format!("{id}.true.csv")),
        csv.as_bytes(),
    )?;
    let names: Vec<String> = (0..rec.runs.len())
        .map(|j| {
            if per == 1 {
                id.clone()
            } else {
                format!("{id}.{}", j + 1)
            }
        })
        .collect();
    let oracle = rec
        .runs
        .iter()
        .zip(&names)
        .map(|(t, name)| OracleRun {
            run_id: name.clone(),
            geometry: WheelGeometry {
                left_wheel_diameter_m: t.effective.left_wheel_diameter_m,
                right_wheel_diameter_m: t.effective.right_wheel_diameter_m,
                wheel_base_m: t.effective.wheel_base_m,
            },
            true_end_m: [t.end_in_start_frame.x_m, t.end_in_start_frame.y_m],
            clock_offset_s: rec.clock_offset_s,
        })
        .collect();
    let row = ManifestRow {
        id: id.clone(),
        video,
        trajectory,
        odometry: odo_rel,
        speed_mps: if per == 1 { Some(speeds[0]) } else { None },
    };
    let truth = RecordingTruth {
        id,
        clock_offset_s: rec.clock_offset_s,
        camera_end_s: rec.camera_end_s,
        runs: rec
            .runs
            .iter()
            .zip(names)
            .map(|(t, run_id)| NamedRun { run_id, truth: *t })
            .collect(),
    };
    Ok((row, truth, oracle))
}
