//! `odocal dataset`: builds the training set (dataset.json) from a run manifest — odometry
//! logs plus camera trajectories (or videos, tracked first).

use std::path::{Path, PathBuf};

use anyhow::bail;
use odocal_calib::CameraFile;
use odocal_dataset::build::{samples_csv, BuildOptions};
use odocal_dataset::oracle::OracleFile;
use odocal_dataset::{
    build_from_manifest, errors_against_truth, Layout, Manifest, ManifestRow, RobotParams,
    Trajectory, VideoTracker, WindowOptions,
};
use odocal_tracker::{track_video, TrackOptions};

use crate::output::{
    check_output_file, check_output_not_input, commit, count, progress, write_atomic, write_json,
};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Run manifest (JSON "odocal.manifest/1" or CSV id,video,trajectory,odometry,speed_mps); each odometry log is `t,left_ticks,right_ticks` (cumulative encoder counts) or `t,v_left,v_right` (wheel speeds, m/s), t in seconds on the robot clock.
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
    /// What a sample is: `runs`, the straight runs of the reference experiment (18 inputs), or
    /// `windows`, windows of any motion (curves, turns, squares) for a path corrector.
    #[arg(long, value_enum, default_value_t = LayoutArg::Runs)]
    pub layout: LayoutArg,
    /// With --layout windows: window length, seconds (a whole number of log periods;
    /// default 10).
    #[arg(long)]
    pub window_s: Option<f64>,
    /// With --layout windows: time between window starts, seconds (default 5).
    #[arg(long)]
    pub window_stride_s: Option<f64>,
    /// Truth of a synthetic experiment (truth/oracle.json from `odocal synth experiment`):
    /// also print the targets' and clock offsets' errors against it.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// The tag on the robot in the manifest's videos, as `odocal track` takes it. A manifest of
    /// trajectory files only takes --tag-offset and --tag-yaw as where the files' point and
    /// heading sit on the robot (a motion-capture body), and takes them off every file.
    #[command(flatten)]
    pub tag: super::tag::TagArgs,
}

/// What one sample of the dataset is.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutArg {
    /// One straight run (the reference experiment's 18 inputs).
    Runs,
    /// A window of any motion.
    Windows,
}

/// Prints what the dataset holds: samples, rejected runs with reasons, raw odometry's error.
/// Each recording whose robot clock rate was told apart from the camera's, and by how much.
fn print_clock_rates(ds: &odocal_dataset::Dataset) {
    let mut seen = std::collections::HashSet::new();
    for smp in &ds.samples {
        let Some(rate) = smp.clock_rate else { continue };
        if seen.insert(smp.recording_id.as_str()) {
            // Robot seconds per camera second: a clock running fast stamps more of them.
            let fast = 1.0 / rate - 1.0;
            say!(
                "  {}: the robot's clock runs {:.3} % {} against the camera's ({:.0} ppm); its times are mapped onto the camera's at that rate",
                smp.recording_id,
                100.0 * fast.abs(),
                if fast > 0.0 { "fast" } else { "slow" },
                1e6 * fast.abs()
            );
        }
    }
}

fn print_summary(ds: &odocal_dataset::Dataset, out: &Path) {
    let s = &ds.summary;
    if ds.is_windows() {
        say!(
            "dataset: {} from {} ({} rejected) -> {}",
            count(ds.samples.len(), "window"),
            count(s.recordings, "recording"),
            ds.rejected.len(),
            out.display()
        );
        print_clock_rates(ds);
        print_rejected(&ds.rejected, out);
        if !ds.samples.is_empty() {
            say!(
                "raw odometry window end-point error: {:.2} % of wheel travel (RMS {:.1} mm, mean travel {:.3} m)",
                100.0 * s.raw_relative_error,
                1e3 * s.raw_rms_error_m,
                s.mean_path_length_m
            );
        }
        return;
    }
    say!(
        "dataset: {} from {} in {} ({} rejected) -> {}",
        count(ds.samples.len(), "sample"),
        count(s.runs, "run"),
        count(s.recordings, "recording"),
        ds.rejected.len(),
        out.display()
    );
    print_clock_rates(ds);
    print_rejected(&ds.rejected, out);
    if !ds.samples.is_empty() {
        say!(
            "raw odometry end-point error: {:.2} % of path length (RMS {:.1} mm, mean path {:.3} m)",
            100.0 * s.raw_relative_error,
            1e3 * s.raw_rms_error_m,
            s.mean_path_length_m
        );
        say!(
            "largest alignment residual: {:.4} m/s",
            s.max_alignment_residual_mps
        );
    }
}

/// Rejections shown in full per kind of reason; the rest of a kind are counted on one line.
const REJECTIONS_SHOWN_PER_KIND: usize = 3;

/// The rejected runs, each kind of reason (the same words, other figures) shown
/// [`REJECTIONS_SHOWN_PER_KIND`] times and the rest counted: twenty logs of another robot
/// are one finding, not twenty lines. Every reason stays in the dataset file.
fn print_rejected(rejected: &[odocal_dataset::RejectedRun], out: &Path) {
    let mut kinds: Vec<(String, Vec<&odocal_dataset::RejectedRun>)> = Vec::new();
    for r in rejected {
        let kind: String = r.reason.chars().filter(|c| !c.is_ascii_digit()).collect();
        match kinds.iter_mut().find(|(k, _)| *k == kind) {
            Some((_, runs)) => runs.push(r),
            None => kinds.push((kind, vec![r])),
        }
    }
    for (_, runs) in &kinds {
        for r in runs.iter().take(REJECTIONS_SHOWN_PER_KIND) {
            say!("  rejected {}: {}", r.run_id, r.reason);
        }
        let more = &runs[runs.len().min(REJECTIONS_SHOWN_PER_KIND)..];
        if !more.is_empty() {
            let ids: Vec<&str> = more.iter().map(|r| r.run_id.as_str()).collect();
            say!(
                "  rejected {} more for the same reason (each with its own figures, in {}'s \"rejected\"): {}",
                more.len(),
                out.display(),
                ids.join(", ")
            );
        }
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.min_gap_s.is_finite() && args.min_gap_s > 0.0) {
        bail!("--min-gap-s must be a positive number of seconds");
    }
    // Straight runs have no windows: a window option given to them would change nothing.
    let window_options: Vec<&str> = [
        ("--window-s", args.window_s.is_some()),
        ("--window-stride-s", args.window_stride_s.is_some()),
    ]
    .into_iter()
    .filter_map(|(name, given)| given.then_some(name))
    .collect();
    if args.layout == LayoutArg::Runs && !window_options.is_empty() {
        bail!(
            "{} {} only used with --layout windows; a dataset of straight runs (the default --layout runs) has no windows: add --layout windows, or leave {} out",
            window_options.join(" and "),
            if window_options.len() == 1 { "is" } else { "are" },
            if window_options.len() == 1 { "it" } else { "them" }
        );
    }
    check_output_file(&args.out, "--out")?;
    if let Some(csv) = &args.csv {
        check_output_file(csv, "--csv")?;
    }
    let manifest = Manifest::read(&args.manifest)?;
    // A wrong truth file is found before the work, not after the dataset is written.
    let oracle = args.truth.as_deref().map(OracleFile::read).transpose()?;
    manifest.check_files()?;
    let inputs = manifest.files();
    check_output_not_input(&args.out, "--out", &inputs, "listed in the manifest")?;
    if let Some(csv) = &args.csv {
        check_output_not_input(csv, "--csv", &inputs, "listed in the manifest")?;
    }
    // The tag's options are checked before any video is opened, and before a note says
    // they are not used: a value that makes no sense is an error either way.
    let track_options = args.tag.apply(TrackOptions::default())?;
    let has_videos = manifest.runs.iter().any(|r| r.video.is_some());
    if !has_videos {
        // A trajectory file's mount is taken off it as a tag's is off its fixes.
        let unused: Vec<String> = args
            .tag
            .given()
            .into_iter()
            .filter(|o| !o.starts_with("--tag-offset ") && !o.starts_with("--tag-yaw "))
            .collect();
        if !unused.is_empty() || args.camera.is_some() {
            let mut what = unused;
            if args.camera.is_some() {
                what.insert(0, "--camera".into());
            }
            tell!(
                "note: {} not used: {} the manifest's videos, and it lists trajectories only",
                what.join(", "),
                if what.len() == 1 {
                    "it is for tracking"
                } else {
                    "they are for tracking"
                }
            );
        }
    }
    if has_videos {
        match &args.camera {
            None => {
                bail!("the manifest lists videos: give the calibration with --camera camera.json")
            }
            Some(c) if c.is_dir() => bail!(
                "camera calibration {} is a directory: give the camera.json that `odocal calibrate` wrote",
                c.display()
            ),
            Some(c) if !c.is_file() => bail!("camera calibration {} does not exist", c.display()),
            _ => {}
        }
    }
    let camera = match &args.camera {
        Some(p) => Some(CameraFile::load(p)?),
        None => None,
    };
    if let Some(c) = &camera {
        track_options.check(c.floor.as_ref().map(|f| f.camera_height_m))?;
    }
    let robot = match &args.robot {
        Some(p) => RobotParams::read(p)?,
        None => RobotParams::default(),
    };
    let layout = match args.layout {
        LayoutArg::Runs => Layout::StraightRuns,
        LayoutArg::Windows => {
            let steps = |v: f64, name: &str| -> anyhow::Result<usize> {
                let n = v / robot.period_s;
                if !(v.is_finite() && n >= 1.0 - 1e-9 && (n - n.round()).abs() < 1e-6) {
                    bail!(
                        "{name} {v} s must be a positive whole number of the robot's {} s log periods",
                        robot.period_s
                    );
                }
                Ok(n.round() as usize)
            };
            Layout::Windows(WindowOptions {
                steps: steps(args.window_s.unwrap_or(10.0), "--window-s")?,
                stride: steps(args.window_stride_s.unwrap_or(5.0), "--window-stride-s")?,
                ..WindowOptions::default()
            })
        }
    };
    let opts = BuildOptions {
        robot,
        min_gap_s: args.min_gap_s,
        layout,
        trajectory_mount: if has_videos {
            odocal_core::TagToRobot::IDENTITY
        } else {
            track_options.tag_to_robot
        },
        ..BuildOptions::default()
    };
    let bar = progress(manifest.runs.len() as u64, "dataset");
    let repeated = RepeatedWarnings::default();
    let track = |row: &ManifestRow, video: &Path| -> Result<Trajectory, String> {
        let camera = camera.as_ref().ok_or("no camera")?;
        let (trajectory, warnings) = track_video(video, camera, &track_options)
            .map_err(|e| format!("run \"{}\": tracking {}: {e}", row.id, video.display()))?;
        for w in warnings {
            if repeated.first(&w, &row.id) {
                bar.suspend(|| tell!("warning: run \"{}\": {}: {w}", row.id, video.display()));
            }
        }
        Ok(trajectory)
    };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let ds = build_from_manifest(
        &manifest,
        &opts,
        camera.is_some().then_some(&track as &VideoTracker),
        threads,
        &|| bar.inc(1),
    )?;
    bar.finish_and_clear();
    repeated.report();
    // Straight runs are rejected one by one; windows whose log never follows the camera are
    // rejected a recording at a time.
    let (unit, total) = if ds.is_windows() {
        ("recordings", ds.summary.recordings)
    } else {
        ("runs", ds.summary.runs)
    };
    let unmatched = ds
        .rejected
        .iter()
        .filter(|r| {
            r.reason.contains("speed-profile correlation")
                || r.reason.contains("speed profiles correlate")
        })
        .count();
    // When the logs' speed never follows the camera's, the logs are read wrongly, not the runs.
    let hint = if unmatched * 2 >= ds.rejected.len().max(1) && unmatched > 0 {
        format!(
            "; the log's speed never followed the camera's in {unmatched} of the {total} {unit}: are the ticks cumulative counts (not counts per period) with both encoders counting up when the robot drives forward, the times in seconds, and each log paired with its own run?"
        )
    } else {
        String::new()
    };
    let robot_file = match &args.robot {
        Some(p) => p.display().to_string(),
        None => "the default robot (give yours with --robot robot.json)".into(),
    };
    // Before the rejections are judged: a robot file of another scale rejects a window
    // dataset's windows one by one as off the clock.
    // Speed logs (t,v_left,v_right) carry no ticks: their scale is the speeds' unit.
    let speed_logs = manifest.runs.iter().all(|r| {
        odocal_dataset::OdometryLog::read_csv(&manifest.resolve(&r.odometry))
            .is_ok_and(|l| l.kind == odocal_dataset::LogKind::Speeds)
    });
    match odocal_dataset::units::robot_scale_mismatch(&ds, &opts.robot, speed_logs) {
        // A trajectory in feet is no fault of the robot file.
        Err(why) if speed_logs || why.contains("a trajectory in feet") => {
            bail!("{why}; nothing was written")
        }
        Err(why) => bail!("{robot_file}: {why}; nothing was written"),
        Ok(Some(w)) if speed_logs => tell!("warning: {w}"),
        Ok(Some(w)) => tell!("warning: {robot_file}: {w}"),
        Ok(None) => {}
    }
    if ds.samples.is_empty() && ds.rejected.is_empty() && args.layout == LayoutArg::Windows {
        // Windows where the robot stands still are no samples and no rejections either.
        bail!(
            "no window gave a sample, so nothing was written: every window lay where the robot stood still (windows of {:.1} s every {:.1} s); take windows that cover the motion: a --window-stride-s shorter than the recordings, and a --window-s of several seconds",
            args.window_s.unwrap_or(10.0),
            args.window_stride_s.unwrap_or(5.0)
        );
    }
    if ds.samples.is_empty() {
        let mut why: Vec<String> = ds
            .rejected
            .iter()
            .take(3)
            .map(|r| format!("{}: {}", r.run_id, r.reason))
            .collect();
        if ds.rejected.len() > 3 {
            why.push("…".into());
        }
        bail!(
            "no run gave a sample, so nothing was written: all {} rejected ({}){hint}",
            ds.rejected.len(),
            why.join("; ")
        );
    }
    if !hint.is_empty() && unmatched * 2 >= total {
        // A window dataset's rejections mix windows and recordings: only the recordings count.
        let rejected = if ds.is_windows() {
            unmatched
        } else {
            ds.rejected.len()
        };
        tell!("warning: {rejected} of {total} {unit} rejected{hint}");
    } else if ds.rejected.len() > ds.samples.len() {
        // Most of the experiment gone is no dataset of it, however good the rest: said where
        // it is seen, not left in the list of rejections above.
        let mut reasons: Vec<(String, usize)> = Vec::new();
        for r in &ds.rejected {
            // The kind of reason: its words before the first number.
            let kind: String = r
                .reason
                .split(|c: char| c.is_ascii_digit())
                .next()
                .unwrap_or("")
                .trim()
                .to_string();
            match reasons.iter_mut().find(|(k, _)| *k == kind) {
                Some((_, n)) => *n += 1,
                None => reasons.push((kind, 1)),
            }
        }
        reasons.sort_by_key(|r| std::cmp::Reverse(r.1));
        let (example, n) = reasons
            .first()
            .and_then(|(k, n)| {
                ds.rejected
                    .iter()
                    .find(|r| r.reason.starts_with(k.as_str()))
                    .map(|r| (r, *n))
            })
            .map_or((String::new(), 0), |(r, n)| {
                (format!("{}: {}", r.run_id, r.reason), n)
            });
        // Windows whose wheels disagree with the camera one after another are what a robot
        // file of another robot's geometry gives: 88 of 120 were rejected, unsaid, for a
        // wheel_base_m of 0.35 m.
        let (what, robot_hint) = if ds.is_windows() {
            (
                "windows",
                format!(
                    "; windows rejected one after another are also what {robot_file} gives when its wheel_base_m or wheel_diameter_m is not the robot's"
                ),
            )
        } else {
            ("runs", String::new())
        };
        tell!(
            "warning: {} of {} {what} rejected ({n} like {example}): the dataset holds a minority of the experiment; mend what the reasons name before training on it{robot_hint}",
            ds.rejected.len(),
            ds.rejected.len() + ds.samples.len()
        );
    }
    for w in &ds.warnings {
        tell!("warning: {w}");
    }
    // Every note is in the dataset file; a few name the kind on the terminal.
    const NOTES_SHOWN: usize = 3;
    for n in ds.notes.iter().take(NOTES_SHOWN) {
        tell!("note: {n}");
    }
    if ds.notes.len() > NOTES_SHOWN {
        tell!(
            "note: and {} more, on other files (every note is in {}'s \"notes\")",
            ds.notes.len() - NOTES_SHOWN,
            args.out.display()
        );
    }
    // Compared before anything is written or said to be, so a wrong truth leaves nothing.
    let against_truth = match (&args.truth, &oracle) {
        (Some(path), Some(oracle)) => {
            errors_against_truth(&ds, oracle, &path.display().to_string())?
        }
        _ => None,
    };
    write_json(&args.out, &ds)?;
    if let Some(csv) = &args.csv {
        write_atomic(csv, samples_csv(&ds).as_bytes())?;
    }
    commit()?;
    print_summary(&ds, &args.out);
    {
        if let Some(e) = against_truth {
            // Said only where a recording's rate was told apart from 1, as the summary does.
            let rates = if e.rate_max_ppm > 0.0 {
                format!(
                    ", clock rates up to {:.0} ppm from the truth's (its clocks tick together)",
                    e.rate_max_ppm
                )
            } else {
                String::new()
            };
            if e.target_rms_m.is_nan() {
                say!(
                    "against the truth: clock offsets RMS {:.2} ms (max {:.2} ms){rates} over {} windows",
                    1e3 * e.offset_rms_s,
                    1e3 * e.offset_max_s,
                    e.n
                );
                return Ok(());
            }
            say!(
                "against the truth: end-point targets RMS {:.2} mm (max {:.2} mm), clock offsets RMS {:.2} ms (max {:.2} ms){rates} over {} samples",
                1e3 * e.target_rms_m,
                1e3 * e.target_max_m,
                1e3 * e.offset_rms_s,
                1e3 * e.offset_max_s,
                e.n
            );
            if let Some(path) = &args.truth {
                if let Some(w) = e.mismatch_warning(&path.display().to_string()) {
                    tell!("warning: {w}");
                }
            }
        }
    }
    Ok(())
}

/// Tracking warnings of the same kind (the same words, other numbers) from many runs: a
/// camera's rolling shutter or a wrong marker height shows in every run, and 131 copies would
/// bury everything else. The first of each kind is printed in full, the rest counted.
#[derive(Default)]
struct RepeatedWarnings {
    /// Per kind of warning, the first run's text and the runs after it that gave it.
    more: std::sync::Mutex<std::collections::BTreeMap<String, (String, Vec<String>)>>,
}

impl RepeatedWarnings {
    /// Whether `warning` of run `run_id` is the first of its kind (then print it).
    fn first(&self, warning: &str, run_id: &str) -> bool {
        let kind: String = warning.chars().filter(|c| !c.is_ascii_digit()).collect();
        let mut more = self.more.lock().unwrap_or_else(|e| e.into_inner());
        match more.get_mut(&kind) {
            Some((_, runs)) => {
                runs.push(run_id.to_string());
                false
            }
            None => {
                more.insert(kind, (warning.to_string(), Vec::new()));
                true
            }
        }
    }

    /// One line per kind of warning that more runs gave.
    fn report(&self) {
        let more = self.more.lock().unwrap_or_else(|e| e.into_inner());
        for (first, runs) in more.values().filter(|(_, r)| !r.is_empty()) {
            let head: String = first.chars().take(60).collect();
            let mut runs = runs.clone();
            runs.sort();
            let shown: Vec<&str> = runs.iter().take(5).map(String::as_str).collect();
            tell!(
                "warning: {} more run(s) gave the warning \"{head}…\" (each with its own figures): {}{}",
                runs.len(),
                shown.join(", "),
                if runs.len() > shown.len() { ", …" } else { "" }
            );
        }
    }
}
