//! `odocal track`: the robot's floor trajectory from a ceiling-camera video.

use std::path::{Path, PathBuf};

use odocal_calib::CameraFile;
use odocal_core::{TextFormat, REFERENCE_MAX_GAP_S, SAME_TIME_S};
use odocal_synth::scene::FramesTruth;
use odocal_tracker::multi::TagSelection;
use odocal_tracker::Trajectory;
use odocal_tracker::{
    errors_against, fix_warnings, open_source, overlay, quiet_video_logs, reference_at,
    track_report, track_source, AgainstTruth, SourceOptions, TagDetector, TimingReport, TrackError,
    TrackOptions, TrackResult,
};

use crate::output::{
    check_output_file, check_output_not_input, commit, progress, staged_dir, write_atomic,
    write_json,
};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Video file (MP4/H.264, MJPG AVI, anything FFmpeg reads) or a folder of PNG/JPEG frames.
    pub video: PathBuf,
    /// camera.json with the floor plane (from `odocal calibrate`); required, except with
    /// --arena, whose file carries every camera's.
    // The placeholder default only fills the field under --arena: shown, it read as if the
    // option could be left out.
    #[arg(
        long,
        required_unless_present = "arena",
        conflicts_with = "arena",
        default_value = "none",
        hide_default_value = true
    )]
    pub camera: PathBuf,
    #[command(flatten)]
    pub tag: super::tag::TagArgs,
    /// Output trajectory CSV (`t,x,y,theta,quality,sigma_x,sigma_y,sigma_theta`: σ in metres and
    /// radians per fix; frames without a confident fix are absent).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the trajectory in TUM format (for `evo`).
    #[arg(long)]
    pub tum: Option<PathBuf>,
    /// Write every frame with its detection drawn into this folder.
    #[arg(long)]
    pub overlay: Option<PathBuf>,
    /// Write a JSON report: per-frame quality, gaps with reasons, ids seen.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Frame rate, frames/s: overrides the video's own; for image folders without timestamps.
    #[arg(long)]
    pub fps: Option<f64>,
    /// CSV of image timestamps for an image folder (`file,t`, or `t` per image in natural name
    /// order: img2 before img10), t in seconds.
    #[arg(long)]
    pub timestamps: Option<PathBuf>,
    /// Detect on the full frame in every frame (no region of interest).
    #[arg(long)]
    pub no_roi: bool,
    /// Fastest plausible robot speed, m/s: faster apparent motion is rejected as a jump.
    #[arg(long, default_value_t = 2.0)]
    pub max_speed: f64,
    /// Largest accepted corner reprojection RMS, pixels.
    #[arg(long, default_value_t = 1.5)]
    pub max_reprojection: f64,
    /// Run the solvePnP (IPPE_SQUARE) cross-check on every fix and report it.
    #[arg(long)]
    pub pnp_check: bool,
    /// A reference trajectory CSV (e.g. `synth track`'s truth.csv), or `synth track`'s
    /// frames.csv (the truth at each frame's own time and at its tag rows' read time): print
    /// the errors against it and how honest the σ are (rows matched by timestamp); with
    /// --report, the report carries them (the HTML report's table of conditions reads them).
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// With --truth: what the video went through, for the report's table of conditions
    /// (e.g. "9 px motion blur"; default: the video's path).
    #[arg(long, requires = "truth")]
    pub condition: Option<String>,
    /// With --truth: also run AprilTag 3 alone (its C library, decimation 2, its defaults) on
    /// every frame and report in how many it finds the tag, beside odocal's own rate.
    #[arg(long, requires = "truth")]
    pub apriltag3: bool,
    #[command(flatten)]
    pub multi: super::track_arena::MultiArgs,
}

/// The tracker's options from the command line (one tag, several, or an arena alike).
pub(super) fn options(args: &Args) -> anyhow::Result<TrackOptions> {
    Ok(args.tag.apply(TrackOptions {
        use_roi: !args.no_roi,
        max_speed_mps: args.max_speed,
        max_reprojection_px: args.max_reprojection,
        pnp_cross_check: args.pnp_check,
        ..TrackOptions::default()
    })?)
}

/// The truth to compare with and the frames it says are in the file (when it knows).
fn read_truth(path: &Path) -> anyhow::Result<(Trajectory, Option<usize>)> {
    let text = odocal_core::read_text(path)?;
    if text.starts_with("frame,") {
        let frames = FramesTruth::parse(&text, &path.display().to_string())?;
        return Ok((frames.trajectory()?, Some(frames.frames_in_file())));
    }
    // Rows of quality 0 (samples a motion capture lost) are read as absent.
    Ok((Trajectory::read_csv(path)?, None))
}

/// Why a truth spanning other times than the fixes (`fixes_s`: first and last, seconds) judges
/// none of them, and what to do: the fixes count from the video's first frame, which is
/// `first_clock_s` on the container's own clock (a truth on that clock is that much late).
fn other_clock(
    path: &Path,
    truth: &Trajectory,
    fixes_s: (f64, f64),
    first_clock_s: Option<f64>,
) -> String {
    let (t0, t1) = (truth.start_s(), truth.end_s());
    let todo = match first_clock_s {
        Some(c) if t0 - c <= fixes_s.1 && t1 - c >= fixes_s.0 => format!(
            "the video's first frame is at {c:.3} s on its container's clock, so this looks like a truth on that clock: subtract {c:.3} s from its times"
        ),
        Some(c) => format!(
            "the video's first frame is at {c:.3} s on its container's clock: give the truth in seconds from the first frame"
        ),
        None => "give the truth of this video in seconds from its first frame".to_string(),
    };
    format!(
        "{}: it spans {t0:.3} to {t1:.3} s, and the fixes are timed in seconds from the video's first frame (t = 0), {:.3} to {:.3} s: {todo}",
        path.display(),
        fixes_s.0,
        fixes_s.1
    )
}

/// Why a truth whose rows are too far apart to interpolate between anywhere judges no fix
/// (None when its rows are close enough): its spacing, how near a row a fix must be, and,
/// under a rolling shutter (`readout_s`), that fixes are timed between the frames.
fn too_sparse(path: &Path, truth: &Trajectory, readout_s: f64) -> Option<String> {
    let gap = truth
        .median_spacing_s()
        .filter(|s| *s > REFERENCE_MAX_GAP_S + SAME_TIME_S)?;
    // How far from one of its rows a fix can be judged (the tracker's `reference_at`).
    let g = REFERENCE_MAX_GAP_S;
    let reach = (gap - (gap * gap - g * g).max(0.0).sqrt()) / 2.0;
    let readout = match readout_s {
        0.0 => String::new(),
        r => format!(
            " (with --rolling-shutter-s {r} each fix is timed at its tag's row, up to {:.0} ms after its frame, so a truth at the frames' times judges only the fixes within {:.1} ms of a frame: give the truth at the tags' rows, as frames.csv of a video rendered with that readout has, or check the readout)",
            r.abs() * 1e3,
            reach * 1e3
        ),
    };
    Some(format!(
        "{}: no row has the time of a tracked frame, and its rows are {:.0} ms apart (median), too far apart to interpolate between except within {:.1} ms of a row, where no fix is (rows at most {:.0} ms apart interpolate anywhere): give a truth sampled at 40 Hz or more, or at the fixes' times{readout}",
        path.display(),
        gap * 1e3,
        reach * 1e3,
        REFERENCE_MAX_GAP_S * 1e3
    ))
}

/// The trajectory against the truth.
fn against_truth(
    args: &Args,
    result: &TrackResult,
    trajectory: &Trajectory,
    (truth, frames): &(Trajectory, Option<usize>),
    path: &Path,
    first_clock_s: Option<f64>,
) -> anyhow::Result<AgainstTruth> {
    let e = errors_against(trajectory, truth);
    if e.matched == 0 {
        // A truth too sparse to interpolate is named by its spacing; otherwise its times are
        // another clock's or another recording's.
        let overlaps =
            truth.start_s() <= trajectory.end_s() && truth.end_s() >= trajectory.start_s();
        if let Some(why) = overlaps
            .then(|| too_sparse(path, truth, args.tag.rolling_shutter_s))
            .flatten()
        {
            anyhow::bail!("{why}");
        }
        // Under a rolling shutter each fix is timed at its tag's row: only a truth timed
        // with the same readout has rows at those times.
        let r = args.tag.rolling_shutter_s;
        let readout = if r != 0.0 {
            format!(
                "; with --rolling-shutter-s {r} the fixes are timed at the tag's row, which only frames.csv of a video rendered with that readout has"
            )
        } else {
            String::new()
        };
        if !overlaps {
            anyhow::bail!(
                "{}",
                other_clock(
                    path,
                    truth,
                    (trajectory.start_s(), trajectory.end_s()),
                    first_clock_s
                )
            );
        }
        anyhow::bail!(
            "{}: no row has the timestamp of a tracked frame, nor are two rows around one: give the truth of this video (synth track's truth.csv or frames.csv, in seconds from the video's first frame){readout}",
            path.display()
        );
    }
    Ok(AgainstTruth {
        condition: args
            .condition
            .clone()
            .unwrap_or_else(|| args.video.display().to_string()),
        truth: path.display().to_string(),
        frames: frames.unwrap_or(result.records.len()),
        fixes: result.fixes().count(),
        apriltag3_rate: None,
        errors: e,
    })
}

/// A trajectory this far from its truth (RMS, metres) is compared with the wrong file: the
/// tracker's own errors are millimetres even under heavy blur.
const TRUTH_MISMATCH_M: f64 = 0.05;

/// Headings this far from their truth (RMS, radians: 10°) with the positions agreeing are read
/// in another unit or frame: the tracker's own heading errors are a fraction of a degree.
const TRUTH_HEADING_MISMATCH_RAD: f64 = 0.17;

/// Prints the comparison with the truth (and AprilTag 3's rate when measured).
/// `worst_both_ways`: the camera file's floor uncertainty map has σ of the worst direction
/// only, which the fixes take for x and y alike, so an honest σ gives error/σ under 1 where
/// it dominates.
fn print_against_truth(a: &AgainstTruth, tag_id: u32, worst_both_ways: bool, readout_s: f64) {
    let e = &a.errors;
    let z = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.2}"));
    say!(
        "against {}: position RMS {:.3} mm (max {:.3} mm), heading RMS {:.3} deg over the {} fixes with a truth at their time{}; error/σ RMS {} (x,y) {} (θ), 1 when σ is right{}",
        a.truth,
        e.position_rms_m * 1e3,
        e.position_max_m * 1e3,
        e.heading_rms_rad.to_degrees(),
        e.matched,
        if e.interpolated > 0 {
            format!(
                " ({} of them interpolated between two truth rows, where that strays at most as far as midway between rows {:.0} ms apart)",
                e.interpolated,
                REFERENCE_MAX_GAP_S * 1e3
            )
        } else {
            String::new()
        },
        z(e.error_over_sigma_xy),
        z(e.error_over_sigma_theta),
        if worst_both_ways {
            " (x,y: 0.7 to 1 where the floor's σ dominates: this camera file's floor map has its worst direction only, taken for both; calibrate again for its covariance)"
        } else {
            ""
        },
    );
    if e.position_rms_m > TRUTH_MISMATCH_M {
        tell!(
            "warning: the trajectory is {:.0} mm RMS from {}: is that the truth of this video, and camera.json this camera's?",
            e.position_rms_m * 1e3,
            a.truth
        );
    } else if e.heading_rms_rad > TRUTH_HEADING_MISMATCH_RAD {
        // Positions agree, so the file is this video's truth: its headings are read wrongly.
        tell!(
            "warning: the headings are {:.1}° RMS from {} while the positions agree: is its theta in degrees (it must be in radians), or its heading another body's?",
            e.heading_rms_rad.to_degrees(),
            a.truth
        );
    }
    if 2 * e.matched < a.fixes {
        let readout = match readout_s {
            0.0 => String::new(),
            r => format!(
                " (with --rolling-shutter-s {r} the fixes are timed at their tag's row, between the frames' times: a truth at the frames' times judges only those near one)"
            ),
        };
        tell!(
            "warning: only {} of the {} fixes have a truth in {} at their time, so the figures above judge those only: give the truth of the whole video (frames.csv of `synth track` has a row per frame){readout}",
            e.matched, a.fixes, a.truth
        );
    }
    if let Some(rate) = a.apriltag3_rate {
        say!(
            "AprilTag 3 alone (decimation 2, its defaults) finds tag {tag_id} in {:.1} % of the {} frames; odocal tracks {} ({:.1} %)",
            100.0 * rate,
            a.frames,
            a.fixes,
            100.0 * a.fixes as f64 / a.frames.max(1) as f64
        );
    }
}

fn write_report(
    args: &Args,
    opts: &TrackOptions,
    result: &TrackResult,
    against_truth: Option<AgainstTruth>,
    warnings: &[String],
    path: &Path,
) -> anyhow::Result<()> {
    let mut report = track_report(
        &args.video.display().to_string(),
        &args.camera.display().to_string(),
        opts,
        result,
    );
    report.against_truth = against_truth;
    report.warnings = warnings.to_vec();
    write_json(path, &report)
}

/// Refuses a rolling-shutter readout longer than a frame period (`period_s`): a sensor
/// reads its rows within one frame, so such a value is another unit (milliseconds given as
/// seconds) and would time every fix by up to that much.
fn check_readout(readout_s: f64, period_s: f64) -> anyhow::Result<()> {
    if readout_s.abs() > period_s * (1.0 + 1e-6) {
        anyhow::bail!(
            "--rolling-shutter-s {readout_s}: a sensor reads its rows within one frame, and these frames come every {:.1} ms ({:.2} fps); give the readout time in seconds (20 ms is 0.02), at most the frame period",
            period_s * 1e3,
            1.0 / period_s
        );
    }
    Ok(())
}

/// `--tags` naming one id without `--arena` is `--tag-id` (its report and truth check too):
/// the id moves there. Naming several, the outputs that judge one tag are refused with the way
/// to them: that tag tracked alone (`--arena-report` is for an arena's cameras).
fn one_tag_of_tags(args: &mut Args) -> anyhow::Result<()> {
    let (None, Some(tags)) = (&args.multi.arena, &args.multi.tags) else {
        return Ok(());
    };
    let selection = TagSelection::parse(tags)?;
    selection.check(&args.tag.family)?;
    let example = match &selection {
        TagSelection::Ids(ids) if ids.len() == 1 => {
            args.tag.tag_id = ids[0];
            args.multi.tags = None;
            return Ok(());
        }
        TagSelection::Ids(ids) => ids[0],
        TagSelection::All => args.tag.tag_id,
    };
    for (flag, what, given) in [
        ("--report", "report", args.report.is_some()),
        ("--truth", "truth check", args.truth.is_some()),
        ("--tum", "TUM file", args.tum.is_some()),
        ("--overlay", "overlay", args.overlay.is_some()),
    ] {
        if given {
            anyhow::bail!(
                "{flag} is for one tag, and --tags {tags} tracks several into trajectory files only: track a tag alone with --tag-id N for its {what} (--tag-id {example} {flag} … for tag {example})"
            );
        }
    }
    Ok(())
}

/// Runs the subcommand.
pub fn run(mut args: Args) -> anyhow::Result<()> {
    args.multi.check_arena_options()?;
    one_tag_of_tags(&mut args)?;
    if args.multi.wanted() {
        return super::track_arena::run(args);
    }
    check_output_file(&args.out, "--out")?;
    for (p, opt) in [(&args.tum, "--tum"), (&args.report, "--report")] {
        if let Some(p) = p {
            check_output_file(p, opt)?;
        }
    }
    // A frame folder is read whole: an output inside it would be read as a frame next time.
    if args.video.is_dir() {
        let folder = [args.video.clone()];
        for (p, opt) in [
            (Some(&args.out), "--out"),
            (args.tum.as_ref(), "--tum"),
            (args.report.as_ref(), "--report"),
            (args.overlay.as_ref(), "--overlay"),
        ] {
            if let Some(p) = p {
                check_output_not_input(p, opt, &folder, "the frame folder tracked")?;
            }
        }
    }
    let source_options = SourceOptions {
        fps: args.fps,
        timestamps: args.timestamps.clone(),
    };
    // Two timings of the frames are refused before any work, not one of them dropped.
    source_options.timestamps_file(&args.video)?;
    quiet_video_logs();
    let camera_file = CameraFile::load(&args.camera)?;
    let truth = match &args.truth {
        Some(path) => Some(read_truth(path)?),
        None => None,
    };
    let floor = *camera_file.require_floor(&args.camera)?;
    // The calibration's uncertainty goes into every fix's σ.
    let opts = options(&args)?.with_calibration(&camera_file);
    opts.check(camera_file.floor.as_ref().map(|f| f.camera_height_m))?;
    // The fixes' calibration part, and the floor map's σ in it, need the intrinsics' covariance;
    // a map written before the floor's covariance was kept per cell gives its worst direction's
    // σ to x and y alike.
    let worst_both_ways = camera_file.covariance.is_some()
        && camera_file
            .floor_uncertainty
            .as_ref()
            .is_some_and(|m| m.covariance_mm2.is_empty());
    let source = open_source(&args.video, &source_options)?;
    if let Some(turn) = &source.info().display_rotation {
        tell!(
            "note: {}: {turn}, which is not applied: odocal reads frames and calibration images as the sensor recorded them",
            args.video.display()
        );
    }
    if let Some(fps) = args.fps.or(source.info().container_fps) {
        check_readout(args.tag.rolling_shutter_s, 1.0 / fps)?;
    }
    let first_clock_s = source.info().first_frame_clock_s;
    // A truth on another clock is refused before the tracking it could not judge.
    if let (Some((truth, _)), Some(path), Some(n), Some(fps)) = (
        &truth,
        &args.truth,
        source.info().frame_count,
        args.fps.or(source.info().container_fps),
    ) {
        let (end, slack) = (n.saturating_sub(1) as f64 / fps, 1.0 / fps);
        if truth.end_s() < -slack || truth.start_s() > end + slack {
            anyhow::bail!("{}", other_clock(path, truth, (0.0, end), first_clock_s));
        }
        // Without a readout the fixes are at the frames' times, which the container states:
        // a truth judging none of them is refused before the tracking.
        let judged = (0..n).any(|k| reference_at(truth, k as f64 / fps).is_some());
        if args.tag.rolling_shutter_s == 0.0 && !judged {
            if let Some(why) = too_sparse(path, truth, 0.0) {
                anyhow::bail!("{why}");
            }
        }
    }
    let overlay_dir = match &args.overlay {
        Some(dir) => Some(staged_dir(dir, "--overlay")?),
        None => None,
    };
    let bar = progress(source.info().frame_count.unwrap_or(0) as u64, "tracking");
    let mut reference = match args.apriltag3 {
        true => Some(TagDetector::reference(&args.tag.family)?),
        false => None,
    };
    let (mut at3_frames, mut at3_hits) = (0usize, 0usize);
    let result = track_source(
        source,
        &camera_file.camera,
        &floor,
        &opts,
        &mut |frame, rec| {
            bar.inc(1);
            if let Some(det) = reference.as_mut() {
                at3_frames += 1;
                if det
                    .detect_raw(&frame.image)?
                    .iter()
                    .any(|d| d.id == args.tag.tag_id)
                {
                    at3_hits += 1;
                }
            }
            match &overlay_dir {
                Some(dir) => overlay::write_overlay(dir, frame, rec),
                None => Ok(()),
            }
        },
    );
    bar.finish_and_clear();
    let timeline = match &result {
        Ok(r) => Some(r),
        Err(TrackError::NoFix { result, .. }) => Some(result.as_ref()),
        Err(_) => None,
    };
    // A frame folder's period is known once its frames are timed.
    if let Some(step) = timeline.and_then(|r| TimingReport::of(r).frame_step_s) {
        check_readout(args.tag.rolling_shutter_s, step)?;
    }
    // Every warning is printed as it is found and kept in --report.
    let mut warnings = timeline
        .map(|r| TimingReport::of(r).warnings())
        .unwrap_or_default();
    for w in &warnings {
        tell!("warning: {}: {w}", args.video.display());
    }
    let result = match result {
        Err(TrackError::NoFix { message, result }) => {
            // The report is what tells the user why: it is written even though nothing else is.
            if let Some(path) = &args.report {
                write_report(&args, &opts, &result, None, &warnings, path)?;
                commit()?;
                anyhow::bail!("{message}; per-frame figures in {}", path.display());
            }
            anyhow::bail!("{message}; --report FILE gives the per-frame figures");
        }
        r => r?,
    };
    let trajectory = result.trajectory()?;
    let other_tag = result.other_tag_warning(opts.tag_id);
    for w in other_tag
        .into_iter()
        .chain(fix_warnings(&result, &camera_file, &floor, &opts))
    {
        tell!("warning: {}: {w}", args.video.display());
        warnings.push(w);
    }
    // The truth only judges the trajectory: a truth that cannot is said after the trajectory
    // is written, not instead of it.
    let (compared, truth_refused) = match (&truth, &args.truth) {
        (Some(truth), Some(path)) => {
            match against_truth(&args, &result, &trajectory, truth, path, first_clock_s) {
                Ok(mut a) => {
                    if args.apriltag3 && at3_frames > 0 {
                        a.apriltag3_rate = Some(at3_hits as f64 / at3_frames as f64);
                    }
                    (Some(a), None)
                }
                Err(e) => {
                    let w = format!("no comparison with the truth: {e:#}");
                    warnings.push(w);
                    (None, Some(e))
                }
            }
        }
        _ => (None, None),
    };
    // All outputs are built before anything is written; each is written atomically.
    write_atomic(&args.out, trajectory.to_csv().as_bytes())?;
    if let Some(tum) = &args.tum {
        write_atomic(tum, trajectory.to_tum().as_bytes())?;
    }
    if let Some(path) = &args.report {
        write_report(&args, &opts, &result, compared.clone(), &warnings, path)?;
    }
    commit()?;
    tell!("{} → {}", result.summary(opts.tag_id), args.out.display());
    if let Some(a) = &compared {
        print_against_truth(
            a,
            args.tag.tag_id,
            worst_both_ways,
            args.tag.rolling_shutter_s,
        );
    }
    if let Some(e) = truth_refused {
        let report = match &args.report {
            Some(r) => format!(" and {}", r.display()),
            None => String::new(),
        };
        anyhow::bail!(
            "{e:#} (the trajectory is written all the same: {}{report}; only the comparison with --truth failed)",
            args.out.display()
        );
    }
    Ok(())
}
