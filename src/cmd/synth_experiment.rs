//! `odocal synth experiment`: the whole odometry experiment with known truth —
//! a run manifest, per recording a 200 ms tick log and a ceiling video (or, with
//! `--frames none`, the camera trajectory taken from the truth), and the truth itself.

use std::path::PathBuf;

use odocal_synth::board::CalibScene;
use odocal_synth::experiment::{self, simulate_experiment, ExperimentSettings};
use odocal_synth::robot::{PathKind, RobotSimConfig};

use crate::cmd::synth_track::CameraArgs;
use crate::output::{commit, count, progress, synth_out_dir};

/// What stands for the camera.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frames {
    /// Render ceiling videos (tracked later by `odocal dataset`).
    Video,
    /// No video: the true trajectory at the camera's frame times (with its clock offset and
    /// the configured mm-level noise) is written as the camera trajectory.
    None,
}

/// The paths the robot drives.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Paths {
    /// The reference experiment: straight runs of about 1.5 m.
    Straight,
    /// One random waypoint tour per recording: turns in place, straight legs and arcs.
    Tours,
    /// Borenstein's UMBMark: a square per recording, clockwise and counter-clockwise
    /// alternately (odd recordings clockwise).
    Umbmark,
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
    /// The paths driven (tours and squares: one per recording, with --frames none).
    #[arg(long, value_enum, default_value_t = Paths::Straight)]
    pub paths: Paths,
    /// Side of the UMBMark square, metres.
    #[arg(long, default_value_t = 4.0)]
    pub square_m: f64,
    /// Speed on the UMBMark square's sides, m/s.
    #[arg(long, default_value_t = 0.5)]
    pub square_speed: f64,
    /// Legs per random tour.
    #[arg(long, default_value_t = 10)]
    pub tour_legs: usize,
    /// Side of the square the tour's waypoints lie in, metres.
    #[arg(long, default_value_t = 3.0)]
    pub tour_area_m: f64,
    /// Simulator configuration JSON ("format": "odocal.robotsim/1"; absent fields take defaults).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// With --frames video, do not also write the calibration views (calib/), e.g. when
    /// `odocal synth calib` has already written them (same camera, any seed works).
    #[arg(long)]
    pub no_calib_views: bool,
    /// Container of the videos: avi (MJPG) or mp4 (H.264) [default: avi; mp4 with
    /// --realistic or --bitrate-kbps].
    #[arg(long)]
    pub video: Option<String>,
    /// A realistic camera for the videos (the camera's truth per frame goes to
    /// truth/<id>.frames.csv).
    #[command(flatten)]
    pub camera: CameraArgs,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    super::synth_count_at_most(args.runs, "--runs", 10_000, "runs of an experiment")?;
    super::synth_count_at_most(args.tour_legs, "--tour-legs", 1_000, "legs of a tour")?;
    let config = match &args.config {
        Some(p) => RobotSimConfig::read(p)?,
        None => RobotSimConfig::default(),
    };
    let frames = match args.frames {
        Frames::Video => experiment::Frames::Video,
        Frames::None => experiment::Frames::None,
    };
    let video = args.camera.format(args.video.as_deref())?;
    let (exposure_s, effects) = args.camera.effects(video);
    let settings = ExperimentSettings {
        video,
        exposure_s,
        effects,
        paths: match args.paths {
            Paths::Straight => PathKind::Straight,
            Paths::Tours => PathKind::Tours,
            Paths::Umbmark => PathKind::Umbmark,
        },
        square_side_m: args.square_m,
        square_speed_mps: args.square_speed,
        tour_legs: args.tour_legs,
        tour_area_m: args.tour_area_m,
        ..ExperimentSettings::straight(
            args.runs,
            args.seed,
            frames,
            args.runs_per_recording,
            config,
        )
    };
    // Everything is written into a staged folder that replaces the outputs in --out only when
    // the whole experiment has been simulated.
    let out = synth_out_dir(&args.out, "--out")?;
    let n_rec = args.runs.div_ceil(args.runs_per_recording.max(1));
    let bar = progress(n_rec as u64, "simulate");
    let summary = simulate_experiment(&out, &settings, &|| bar.inc(1))?;
    bar.finish_and_clear();
    if args.frames == Frames::Video && !args.no_calib_views {
        // The calibration views of the same camera, so the videos can be tracked.
        crate::cmd::synth_calib::write_calib_set(
            &out.join("calib"),
            &CalibScene::default(),
            args.seed,
        )?;
    }
    commit()?;
    say!(
        "synth experiment: {} in {} (seed {}, frames {}) -> {}",
        count(
            args.runs,
            match args.paths {
                Paths::Straight => "run",
                Paths::Tours => "tour",
                Paths::Umbmark => "UMBMark square",
            }
        ),
        count(summary.recordings, "recording"),
        args.seed,
        match args.frames {
            Frames::Video => "video",
            Frames::None => "none",
        },
        args.out.join(&summary.manifest).display()
    );
    Ok(())
}
