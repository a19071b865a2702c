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
    /// Side of the UMBMark square, metres (--paths umbmark) [default: 4].
    #[arg(long)]
    pub square_m: Option<f64>,
    /// Speed on the UMBMark square's sides, m/s (--paths umbmark) [default: 0.5].
    #[arg(long)]
    pub square_speed: Option<f64>,
    /// Legs per random tour (--paths tours) [default: 10].
    #[arg(long)]
    pub tour_legs: Option<usize>,
    /// Side of the square the tour's waypoints lie in, metres (--paths tours) [default: 3].
    #[arg(long)]
    pub tour_area_m: Option<f64>,
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
    if let Some(why) = unused_option(&args) {
        anyhow::bail!("{why}");
    }
    let tour_legs = args.tour_legs.unwrap_or(10);
    super::synth_count_at_most(tour_legs, "--tour-legs", 1_000, "legs of a tour")?;
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
        square_side_m: args.square_m.unwrap_or(4.0),
        square_speed_mps: args.square_speed.unwrap_or(0.5),
        tour_legs,
        tour_area_m: args.tour_area_m.unwrap_or(3.0),
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

/// The first option given that the experiment's other choices leave unused, as what to do:
/// a `--square-m` with straight runs, or a camera option with no video, would otherwise be
/// ignored, and the experiment written without what was asked for.
fn unused_option(args: &Args) -> Option<String> {
    let c = &args.camera;
    let path_options: [(&str, bool, Paths); 5] = [
        ("--square-m", args.square_m.is_some(), Paths::Umbmark),
        (
            "--square-speed",
            args.square_speed.is_some(),
            Paths::Umbmark,
        ),
        ("--tour-legs", args.tour_legs.is_some(), Paths::Tours),
        ("--tour-area-m", args.tour_area_m.is_some(), Paths::Tours),
        (
            "--runs-per-recording",
            args.runs_per_recording != 1,
            Paths::Straight,
        ),
    ];
    let path_name = |p: Paths| match p {
        Paths::Straight => "straight",
        Paths::Tours => "tours",
        Paths::Umbmark => "umbmark",
    };
    if let Some((flag, _, needs)) = path_options
        .into_iter()
        .find(|(_, given, needs)| *given && *needs != args.paths)
    {
        return Some(format!(
            "{flag} applies to --paths {} only, not {}: give --paths {0}, or leave {flag} out",
            path_name(needs),
            path_name(args.paths)
        ));
    }
    if args.frames == Frames::None {
        let video_options = [
            ("--no-calib-views", args.no_calib_views),
            ("--video", args.video.is_some()),
            ("--exposure-ms", c.exposure_ms.is_some()),
            ("--rolling-shutter-ms", c.rolling_shutter_ms.is_some()),
            ("--flicker-hz", c.flicker_hz.is_some()),
            ("--flicker-depth", c.flicker_depth.is_some()),
            ("--auto-exposure", c.auto_exposure.is_some()),
            ("--vignetting", c.vignetting.is_some()),
            ("--gradient", c.gradient.is_some()),
            ("--tone-gamma", c.tone_gamma.is_some()),
            ("--paper-tag", c.paper_tag),
            ("--paper-contrast", c.paper_contrast.is_some()),
            ("--paper-gloss", c.paper_gloss.is_some()),
            ("--occlusion-s", c.occlusion_s.is_some()),
            ("--drop-rate", c.drop_rate.is_some()),
            ("--bitrate-kbps", c.bitrate_kbps.is_some()),
            ("--realistic", c.realistic),
        ];
        if let Some((flag, _)) = video_options.into_iter().find(|(_, given)| *given) {
            return Some(format!(
                "{flag} is an option of the videos, and --frames none renders none: give --frames video, or leave {flag} out"
            ));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    fn unused(cli: &[&str]) -> Option<String> {
        let args = ["synth", "--out", "x"].iter().chain(cli);
        unused_option(&Cli::try_parse_from(args).expect("arguments").args)
    }

    #[test]
    fn options_the_paths_or_frames_leave_unused_are_named() {
        assert_eq!(
            unused(&["--square-m", "2"]).as_deref(),
            Some("--square-m applies to --paths umbmark only, not straight: give --paths umbmark, or leave --square-m out")
        );
        assert!(unused(&["--paths", "umbmark", "--tour-legs", "4"])
            .is_some_and(|w| w.starts_with("--tour-legs applies to --paths tours only")));
        assert!(unused(&["--paths", "tours", "--runs-per-recording", "3"])
            .is_some_and(|w| w.starts_with("--runs-per-recording applies to --paths straight")));
        assert!(unused(&["--frames", "none", "--realistic"])
            .is_some_and(|w| w.starts_with("--realistic is an option of the videos")));
        assert_eq!(unused(&["--paths", "umbmark", "--square-m", "2"]), None);
        assert_eq!(
            unused(&["--paths", "tours", "--tour-legs", "4", "--frames", "none"]),
            None
        );
        assert_eq!(unused(&["--realistic", "--runs-per-recording", "3"]), None);
    }
}
