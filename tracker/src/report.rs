//! The track report (`odocal track --report`): per-frame quality, gaps with their reasons, the
//! tag ids seen, and the trajectory's error against a reference.

use crate::track::median;
use std::collections::BTreeMap;

use crate::{GapReason, Outcome, TrackOptions, TrackResult, Trajectory};

/// The `format` tag of the track report.
pub const TRACK_REPORT_FORMAT: &str = "odocal.track-report/1";

/// A trajectory's errors against the truth, and how honest its σ is there.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TruthErrors {
    /// Rows of the trajectory judged: those with a truth row at the fix's own time (within
    /// 0.1 ms) or between two truth rows close enough to interpolate ([`reference_at`]).
    pub matched: usize,
    /// Of those, the ones judged by interpolating between truth rows.
    #[serde(default)]
    pub interpolated: usize,
    /// RMS and largest position error, metres.
    pub position_rms_m: f64,
    pub position_max_m: f64,
    /// RMS heading error, radians.
    pub heading_rms_rad: f64,
    /// RMS of error/σ over x and y, and of the heading's (1 when σ is right; absent when the
    /// trajectory has no σ).
    pub error_over_sigma_xy: Option<f64>,
    pub error_over_sigma_theta: Option<f64>,
}

/// The truth at time `t`: a row at that time, or the pose interpolated between the rows around
/// it when the straight line between them strays no further from a robot accelerating at
/// 1 m/s² than it does midway between rows [`odocal_core::REFERENCE_MAX_GAP_S`] apart. That
/// stray is a·δ·(h−δ)/2 at δ from the nearer of rows h apart, so a fix a few milliseconds
/// from a row of a truth sampled at the frame rate (a fix a rolling shutter times at its tag's
/// row near the top of the image) is judged too, where only rows 25 ms apart qualified.
pub fn reference_at(truth: &Trajectory, t: f64) -> Option<odocal_core::Reference> {
    use odocal_core::{REFERENCE_MAX_GAP_S as G, SAME_TIME_S};
    if let Some(r) = truth.reference_at(t) {
        return Some(r);
    }
    let i = truth.rows.partition_point(|r| r.t_s < t);
    let (a, b) = (truth.rows.get(i.checked_sub(1)?)?, truth.rows.get(i)?);
    let h = b.t_s - a.t_s;
    let d = (t - a.t_s).min(b.t_s - t);
    // The same floating-point tolerance as for rows 25 ms apart.
    let g = G + SAME_TIME_S;
    (d * (h - d) <= g * g / 4.0).then(|| odocal_core::Reference {
        pose: a.pose.lerp(&b.pose, (t - a.t_s) / h),
        row: None,
    })
}

/// `est`'s errors against `truth`, each row judged by the truth at its time (a row, or
/// interpolated between close rows: [`reference_at`]).
pub fn errors_against(est: &Trajectory, truth: &Trajectory) -> TruthErrors {
    let (mut sp, mut sh, mut max, mut n, mut between) = (0.0, 0.0, 0.0f64, 0usize, 0usize);
    let (mut zxy, mut zt, mut nz) = (0.0, 0.0, 0usize);
    for r in &est.rows {
        if let Some(t) = reference_at(truth, r.t_s) {
            between += usize::from(t.row.is_none());
            let d = r.pose.position() - t.pose.position();
            let dh = odocal_core::wrap_angle(r.pose.theta_rad - t.pose.theta_rad);
            sp += d.norm_squared();
            sh += dh.powi(2);
            max = max.max(d.norm());
            n += 1;
            if let Some(s) = r.sigma {
                zxy += (d.x / s.x_m).powi(2) + (d.y / s.y_m).powi(2);
                zt += (dh / s.theta_rad).powi(2);
                nz += 1;
            }
        }
    }
    let k = n.max(1) as f64;
    let z = |sum: f64, per: usize| (nz > 0).then(|| (sum / (per * nz) as f64).sqrt());
    TruthErrors {
        matched: n,
        interpolated: between,
        position_rms_m: (sp / k).sqrt(),
        position_max_m: max,
        heading_rms_rad: (sh / k).sqrt(),
        error_over_sigma_xy: z(zxy, 2),
        error_over_sigma_theta: z(zt, 1),
    }
}

/// A tracking run compared with the truth, as the track report carries it (and the HTML
/// report's table of conditions reads it).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AgainstTruth {
    /// What the video went through (`odocal track --condition`; the video's name by default).
    pub condition: String,
    /// The truth file.
    pub truth: String,
    /// Frames the truth says are in the file.
    pub frames: usize,
    /// Frames with a fix (the errors are over those of them with a truth row at the fix's
    /// time: `errors.matched`).
    pub fixes: usize,
    /// Fraction of the frames in which AprilTag 3 alone (its C library, decimation 2, its
    /// defaults) finds the tag (`odocal track --apriltag3`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub apriltag3_rate: Option<f64>,
    /// The errors.
    pub errors: TruthErrors,
}

/// What a track report says of the truth, read back (`odocal report --track-report`).
#[derive(Debug, Clone, serde::Deserialize)]
pub struct TrackReportTruth {
    /// The tracked video.
    pub video: String,
    /// The comparison with the truth, when `odocal track` had `--truth`.
    pub against_truth: Option<AgainstTruth>,
    /// The warnings of the run.
    #[serde(default)]
    pub warnings: Vec<String>,
}

impl TrackReportTruth {
    /// Reads a track report (`"format": "odocal.track-report/1"`).
    pub fn load(path: &std::path::Path) -> Result<Self, odocal_core::FileError> {
        odocal_core::read_tagged_json(
            path,
            TRACK_REPORT_FORMAT,
            "expected the --report file of `odocal track`",
        )
    }
}

/// One frame in the track report: its fix (reprojection RMS, decision margin, whether the
/// region of interest found it, its σ, the time the tag was read, the PnP cross-check) or the
/// reason it has none.
#[derive(serde::Serialize)]
pub struct FrameReport {
    index: usize,
    t: f64,
    /// When the tag was read (differs from `t` under a rolling shutter), seconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    t_fix: Option<f64>,
    /// The fix's σ: x and y in millimetres, heading in degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    sigma_x_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sigma_y_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sigma_theta_deg: Option<f64>,
    fix: bool,
    reason: Option<&'static str>,
    reprojection_px: Option<f64>,
    decision_margin: Option<f32>,
    roi: Option<bool>,
    pnp_height_m: Option<f64>,
    pnp_heading_diff_deg: Option<f64>,
}

/// A run of frames without a fix: frames, times (s) and the reasons counted.
#[derive(serde::Serialize)]
pub struct GapReport {
    first_frame: usize,
    last_frame: usize,
    start_s: f64,
    end_s: f64,
    reasons: std::collections::BTreeMap<&'static str, usize>,
}

/// Frames rejected for one reason: how many, and the median decision margin and corner
/// reprojection error (pixels) of their detections (null when nothing was detected).
#[derive(serde::Serialize, Default)]
pub struct RejectionReport {
    frames: usize,
    median_decision_margin: Option<f64>,
    median_reprojection_px: Option<f64>,
}

/// The report `odocal track --report` writes (`"format": "odocal.track-report/1"`).
#[derive(serde::Serialize)]
pub struct TrackReport {
    format: &'static str,
    video: String,
    camera: String,
    tag_id: u32,
    family: String,
    frames: usize,
    fixes: usize,
    median_reprojection_px: f64,
    /// Median of the fixes' σ: position (the larger of x and y) in millimetres, heading in
    /// degrees.
    median_sigma_position_mm: Option<f64>,
    median_sigma_heading_deg: Option<f64>,
    ids_seen: std::collections::BTreeMap<u32, usize>,
    /// How the frames were timed; dropped, duplicate and repeated frames; a file cut short.
    timing: crate::TimingReport,
    /// Frames without a fix by reason, with the median figures of the rejected detections.
    rejections: std::collections::BTreeMap<&'static str, RejectionReport>,
    gaps: Vec<GapReport>,
    /// The trajectory against the truth (`odocal track --truth`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub against_truth: Option<AgainstTruth>,
    /// What the run warned of (the frames' timing, the marker height, the floor the
    /// calibration vouches for, a rolling shutter), one line each.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    per_frame: Vec<FrameReport>,
}

/// The report of a tracking run: per-frame quality, gaps with reasons, ids seen.
pub fn track_report(
    video: &str,
    camera: &str,
    opts: &TrackOptions,
    r: &TrackResult,
) -> TrackReport {
    let mut reproj: Vec<f64> = r.fixes().map(|(_, f)| f.reprojection_rms_px).collect();
    reproj.sort_by(f64::total_cmp);
    TrackReport {
        format: TRACK_REPORT_FORMAT,
        video: video.to_string(),
        camera: camera.to_string(),
        tag_id: opts.tag_id,
        family: opts.family.clone(),
        frames: r.records.len(),
        fixes: reproj.len(),
        median_reprojection_px: reproj.get(reproj.len() / 2).copied().unwrap_or(f64::NAN),
        median_sigma_position_mm: median(
            r.fixes()
                .map(|(_, f)| 1e3 * f.sigma.x_m.max(f.sigma.y_m))
                .collect(),
        ),
        median_sigma_heading_deg: median(
            r.fixes()
                .map(|(_, f)| f.sigma.theta_rad.to_degrees())
                .collect(),
        ),
        ids_seen: r.seen_ids.clone(),
        timing: crate::TimingReport::of(r),
        rejections: rejections(r),
        gaps: r
            .gaps()
            .into_iter()
            .map(|g| GapReport {
                first_frame: g.first_index,
                last_frame: g.last_index,
                start_s: g.start_s,
                end_s: g.end_s,
                reasons: g.reasons,
            })
            .collect(),
        against_truth: None,
        warnings: Vec::new(),
        per_frame: r
            .records
            .iter()
            .map(|rec| match &rec.outcome {
                Outcome::Fix(f) => FrameReport {
                    index: rec.index,
                    t: rec.t_s,
                    t_fix: Some(f.t_s),
                    sigma_x_mm: Some(1e3 * f.sigma.x_m),
                    sigma_y_mm: Some(1e3 * f.sigma.y_m),
                    sigma_theta_deg: Some(f.sigma.theta_rad.to_degrees()),
                    fix: true,
                    reason: None,
                    reprojection_px: Some(f.reprojection_rms_px),
                    decision_margin: Some(f.decision_margin),
                    roi: Some(f.from_roi),
                    pnp_height_m: f.pnp.map(|p| p.height_m),
                    pnp_heading_diff_deg: f.pnp.map(|p| p.heading_diff_rad.to_degrees()),
                },
                Outcome::Gap(g) => FrameReport {
                    index: rec.index,
                    t: rec.t_s,
                    t_fix: None,
                    sigma_x_mm: None,
                    sigma_y_mm: None,
                    sigma_theta_deg: None,
                    fix: false,
                    reason: Some(g.as_str()),
                    reprojection_px: rec.rejected.and_then(|x| x.reprojection_px),
                    decision_margin: rec.rejected.map(|x| x.decision_margin),
                    roi: None,
                    pnp_height_m: None,
                    pnp_heading_diff_deg: None,
                },
            })
            .collect(),
    }
}

fn rejections(r: &TrackResult) -> std::collections::BTreeMap<&'static str, RejectionReport> {
    let mut by: std::collections::BTreeMap<&'static str, Vec<&crate::FrameRecord>> =
        Default::default();
    for rec in &r.records {
        if let Outcome::Gap(g) = rec.outcome {
            by.entry(g.as_str()).or_default().push(rec);
        }
    }
    by.into_iter()
        .map(|(reason, recs)| {
            let rej: Vec<_> = recs.iter().filter_map(|x| x.rejected).collect();
            let report = RejectionReport {
                frames: recs.len(),
                median_decision_margin: median(
                    rej.iter().map(|x| x.decision_margin as f64).collect(),
                ),
                median_reprojection_px: median(
                    rej.iter().filter_map(|x| x.reprojection_px).collect(),
                ),
            };
            (reason, report)
        })
        .collect()
}

/// Tracks the robot's tag through the video (or image folder) at `video` with the camera of
/// `camera` and `options` (their calibration uncertainty taken from `camera`), as `odocal
/// dataset` does for a manifest row with a video. Also returns the warnings about the
/// video's timeline (dropped or repeated frames, a file cut short) and [`fix_warnings`].
pub fn track_video(
    video: &std::path::Path,
    camera: &odocal_calib::CameraFile,
    options: &TrackOptions,
) -> Result<(Trajectory, Vec<String>), crate::TrackError> {
    let floor = camera
        .floor
        .as_ref()
        .map(|f| f.floor_to_camera)
        .ok_or_else(|| {
            crate::TrackError::Mismatch(
                "the camera calibration has no floor plane (calibrate with --floor)".into(),
            )
        })?;
    let source = crate::open_source(video, &crate::SourceOptions::default())?;
    let options = options.clone().with_calibration(camera);
    let result = crate::track_source(source, &camera.camera, &floor, &options, &mut |_, _| Ok(()))?;
    let mut warnings = crate::TimingReport::of(&result).warnings();
    warnings.extend(fix_warnings(&result, camera, &floor, &options));
    Ok((result.trajectory()?, warnings))
}

/// The frames of a run where the tag was found, how many of them gave a fix, and why the
/// others did not.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FoundFrames {
    /// Frames where the tag was found, fixed or not.
    pub found: usize,
    /// Of those, the frames that gave a fix.
    pub fixes: usize,
    /// Why the others gave none: each reason ([`GapReason::as_str`]) with its frames.
    pub left_out: BTreeMap<&'static str, usize>,
}

impl FoundFrames {
    /// Counts the frames of `result`.
    pub fn of(result: &TrackResult) -> Self {
        let mut counts = Self::default();
        for r in &result.records {
            match &r.outcome {
                Outcome::Fix(_) => counts.fixes += 1,
                Outcome::Gap(GapReason::NotDetected) => continue,
                Outcome::Gap(g) => *counts.left_out.entry(g.as_str()).or_default() += 1,
            }
            counts.found += 1;
        }
        counts
    }

    /// The reasons frames were left out, most frequent first ("58 bad geometry, 2 low
    /// confidence").
    pub fn left_out_text(&self) -> String {
        let mut why: Vec<(&str, usize)> = self.left_out.iter().map(|(r, n)| (*r, *n)).collect();
        why.sort_by_key(|w| std::cmp::Reverse(w.1));
        why.iter()
            .map(|(r, n)| format!("{n} {r}"))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Whether the tag was found in enough frames ([`FEW_FIXES_MIN_FOUND`]) to judge how many
    /// of them gave a fix: a tag glimpsed at the image's edge for a frame or two is not.
    pub fn judged(&self) -> bool {
        self.found >= FEW_FIXES_MIN_FOUND
    }
}

/// A warning when fewer than half the frames where the tag was found gave a fix (at least
/// [`FEW_FIXES_MIN_FOUND`] found): the robot was in view, and a damaged video (frames decoded
/// as repeats of the last good one), a wrong size or calibration (geometry) or a blurred tag
/// (confidence) left most of it out. Each reason is counted.
pub fn few_fixes_warning(result: &TrackResult, tag_id: u32) -> Option<String> {
    let counts = FoundFrames::of(result);
    if !counts.judged() || 2 * counts.fixes >= counts.found {
        return None;
    }
    Some(format!(
        "only {} of the {} frames where tag {tag_id} was found gave a fix (left out: {}): the trajectory misses most of the time the robot was in view; the lines above say why (a damaged video decodes frames as repeats of the last good one; a wrong --tag-size or camera file fails the geometry; a smeared tag fails the confidence)",
        counts.fixes,
        counts.found,
        counts.left_out_text()
    ))
}

/// The fewest frames with the tag found for [`few_fixes_warning`] to judge.
const FEW_FIXES_MIN_FOUND: usize = 5;

/// What the fixes of a run say about the inputs, one line each: [`tag_shape_warnings`], and
/// fixes outside the floor the calibration vouches for.
pub fn fix_warnings(
    result: &TrackResult,
    camera: &odocal_calib::CameraFile,
    floor: &odocal_calib::FloorToCamera,
    options: &TrackOptions,
) -> Vec<String> {
    let mut warnings: Vec<String> = few_fixes_warning(result, options.tag_id)
        .into_iter()
        .chain(calibration_share_warning(camera))
        .chain(teleport_warning(result, options))
        .chain(tag_shape_warnings(result, camera, floor, options))
        .collect();
    if let Some(map) = &camera.floor_uncertainty {
        warnings.extend(
            crate::UnvouchedFixes::of(result, map, &camera.camera, floor).map(|u| u.warning()),
        );
    }
    if let Ok(trajectory) = result.trajectory() {
        let runs: Vec<&[odocal_core::TrajectoryRow]> = result
            .continuous_runs()
            .into_iter()
            .map(|r| &trajectory.rows[r])
            .collect();
        warnings.extend(mount_warnings_of_runs(&runs, &result.tag_to_robot));
    }
    warnings
}

/// Where the tag stands farther from its last fix than `--max-speed` allows over the time
/// between them: the tracker rejects such a fix, but three in a row restart the track from
/// the new place (the old track taken for the outlier), so a video joined from two
/// recordings put a 1.8 m leap at 13 m/s into the trajectory after a 3-frame gap, in silence.
fn teleport_warning(result: &TrackResult, options: &TrackOptions) -> Option<String> {
    let fixes: Vec<(usize, &crate::Fix)> = result.fixes().map(|(r, f)| (r.index, f)).collect();
    let leaps: Vec<String> = fixes
        .windows(2)
        .filter_map(|w| {
            let ((i, a), (j, b)) = (w[0], w[1]);
            let dt = (b.t_s - a.t_s).abs();
            let dist = (b.pose.position() - a.pose.position()).norm();
            (dist > options.max_speed_mps * dt + 0.02).then(|| {
                format!(
                    "{dist:.3} m in {dt:.3} s ({:.1} m/s) from frame {i} ({:.3} s) to frame {j} ({:.3} s)",
                    dist / dt.max(1e-9),
                    a.t_s,
                    b.t_s
                )
            })
        })
        .collect();
    let first = leaps.first()?;
    let more = match leaps.len() {
        1 => String::new(),
        n => format!(" ({} places in all: {})", n, leaps[1..].join(", ")),
    };
    Some(format!(
        "the tag leaps {first}{more}, faster than --max-speed {} m/s: the fixes after it were taken up as a new track, as a video joined from two recordings or a second tag of this id gives; the trajectory holds both sides, so split the video there (or track each part alone), or raise --max-speed if the robot is that fast",
        options.max_speed_mps
    ))
}

/// What a camera file that was calibrated lacks for each fix's σ to hold the calibration's
/// share: without the intrinsics' covariance the σ are the tag's corner noise alone (8 times
/// too small against a calibrated camera's error, error/σ 2.25), and without the floor
/// uncertainty map the intrinsics' covariance is carried with the floor held fixed, which
/// overstates it many times over (σ 1.29 mm for errors of 0.09 mm, error/σ 0.06). A camera
/// file written with the true camera (`synth track`) has no calibration error to add.
pub fn calibration_share_warning(camera: &odocal_calib::CameraFile) -> Option<String> {
    let calibrated = camera.rms_px > 0.0 || camera.board.is_some() || !camera.views.is_empty();
    if !calibrated {
        return None;
    }
    let advice = "calibrate again with `odocal calibrate` (with --floor views) to have it";
    if camera.covariance.is_none() {
        return Some(format!(
            "the camera file has no `covariance` of its intrinsics, so each fix's σ leaves out the calibration's share and holds the tag's corner noise alone (several times too small where the calibration's error dominates): {advice}"
        ));
    }
    if camera.floor.is_some() && camera.floor_uncertainty.is_none() {
        return Some(format!(
            "the camera file has no `floor_uncertainty` map, so the calibration's share of each fix's σ is its intrinsics' covariance carried with the floor held fixed, which overstates it many times over (σ too large, error/σ far below 1): {advice}"
        ));
    }
    None
}

/// What a trajectory's motion says about where its tag sits on the robot, one line each. A
/// differential drive's axle midpoint moves along the robot's heading and never sideways, so
/// a heading turned from the line of motion says the tag is mounted turned (and every
/// heading, and every dataset target made from it, is turned with it), and a sideways swing
/// on turns says the tag sits ahead of or behind the axle (see [`odocal_core::MountFit`]).
/// `trajectory` is the robot's, taken off the `mount` given; each warning names the
/// `--tag-yaw` or `--tag-offset` that would take the rest off.
pub fn mount_warnings(
    trajectory: &odocal_core::Trajectory,
    mount: &odocal_core::TagToRobot,
) -> Vec<String> {
    mount_warnings_of_runs(&[&trajectory.rows], mount)
}

/// [`mount_warnings`] over the steps within each of `runs`, stretches of one continuous
/// motion (see [`crate::TrackResult::continuous_runs`]).
pub fn mount_warnings_of_runs(
    runs: &[&[odocal_core::TrajectoryRow]],
    mount: &odocal_core::TagToRobot,
) -> Vec<String> {
    use odocal_core::{wrap_angle, MotionAgainstHeading, MountFit};
    use std::f64::consts::PI;
    let subject = if mount.is_identity() {
        "the tag"
    } else {
        "the tag, taken off the --tag-offset/--tag-yaw given,"
    };
    let yaw_fix = |yaw_rad: f64| {
        format!(
            "give --tag-yaw {:.1} (degrees from the robot's front to the tag's x axis, counter-clockwise) or remount the tag; until then every heading (and every dataset target) is turned by as much",
            wrap_angle(yaw_rad).to_degrees()
        )
    };
    let motion = MotionAgainstHeading::of_runs(runs, 1.0);
    let backwards = motion.line_misfit_rad().is_some()
        && motion.forward_share() <= 1.0 - MotionAgainstHeading::ONE_WAY;
    if backwards {
        return vec![format!(
            "{subject} moves backwards along its x axis on {:.0} % of {} straight stretches: unless the robot reversed the whole time, the tag is mounted turned 180°; {}",
            100.0 * (1.0 - motion.forward_share()),
            motion.steps(),
            yaw_fix(mount.0.theta_rad + PI)
        )];
    }
    let Some(fit) = MountFit::of_runs(runs) else {
        return Vec::new();
    };
    let mut warnings = Vec::new();
    // The fit already takes the robot to have driven forwards more than backwards, as the
    // check above does; folding its yaw into ±90° turned a tag at +90.1° into "-89.9°".
    let yaw = fit.named_yaw_rad();
    if let Some(yaw) = yaw {
        warnings.push(format!(
            "{subject} is turned {:+.1}° (± {:.1}°, 1σ, over {} steps) from the direction the robot drives, where a wheeled robot drives along its heading: {}",
            yaw.to_degrees(),
            fit.yaw_sigma_rad.to_degrees(),
            fit.steps,
            yaw_fix(mount.0.theta_rad + yaw)
        ));
    }
    if let Some(ahead) = fit.ahead_m {
        // The trajectory's point is the true mount after the given one was taken off along
        // the tag's axes as the given yaw has them: with the rest of the yaw put on, the
        // offset given turns by it before the fitted distance ahead adds to it (a 90° tag
        // given 0.1,0 read "0.200" where 0.100 was right). The path cannot show the sideways
        // offset, so the one given is kept. A swing that the yaw advised explains leaves the
        // offset given as it is, and is not named.
        let (s, c) = yaw.unwrap_or(0.0).sin_cos();
        let advised_ahead_m = ahead + c * mount.0.x_m - s * mount.0.y_m;
        let change_m = (advised_ahead_m - mount.0.x_m).abs();
        let named_change = change_m > MountFit::NAMED_AHEAD_M && change_m > 5.0 * fit.ahead_sigma_m;
        if !named_change {
            return warnings;
        }
        warnings.push(format!(
            "{subject} slips sideways on turns as a point {:.1} cm {} the wheel axle does (± {:.1} cm, 1σ, from {:.0}° of turning), where the midpoint of a differential drive's axle never slips: if that is where the tag sits, give --tag-offset {:.3},{:.3} (metres ahead of and to the left of the axle midpoint; the path shows only the distance ahead, so measure the sideways one) so the trajectory is the axle's, as the odometry is; until then positions on turns are off by up to {:.1} cm. Skid-steered robots slip on every turn and may show this too",
            100.0 * ahead.abs(),
            if ahead > 0.0 { "ahead of" } else { "behind" },
            100.0 * fit.ahead_sigma_m,
            fit.turned_rad.to_degrees(),
            advised_ahead_m,
            mount.0.y_m,
            100.0 * ahead.abs(),
        ));
    }
    warnings
}

/// What the tags' shapes in a run's fixes say, one line each: a marker height their apparent
/// size contradicts, a square whose side is not the size given, and a rolling shutter
/// `options` do not name or name wrongly (their shear). An arena's
/// cameras take only these: the fixes near one camera's edge are fused with its neighbours'
/// by their σ, so that camera's floor alone does not bound them.
pub fn tag_shape_warnings(
    result: &TrackResult,
    camera: &odocal_calib::CameraFile,
    floor: &odocal_calib::FloorToCamera,
    options: &TrackOptions,
) -> Vec<String> {
    let height = crate::MarkerHeight::of(result, &camera.camera, floor, options.tag_size_m)
        .and_then(|h| h.warning(options.marker_height_m, options.tag_size_m));
    // The tags' shear says whether the camera has a rolling shutter, and checks the readout
    // the user gave (a datasheet's figure may be another mode's, or read the other way).
    let shear = crate::ShutterEstimate::of(result, &camera.camera, floor, options)
        .and_then(|e| e.warning());
    // A height far off says it already, and a shear left in the corners shrinks the square
    // (0.4 % at 0.7 m/s under a 30 ms readout): the side would only repeat them.
    let side = if height.is_none() && shear.is_none() {
        crate::marker_height::TagSide::of(
            result,
            &camera.camera,
            floor,
            options.tag_size_m,
            options.marker_height_m,
        )
        .and_then(|s| s.warning(options.tag_size_m, options.marker_height_m))
    } else {
        None
    };
    // The tilt is read from the tags' corners as the camera file maps them: a wrong size or
    // height leaves it, and a shear named by the rolling-shutter check would repeat it. A
    // camera file that maps the image wrongly (a height or side named above) tilts every
    // tag's corners too, and reads as a tag tilted on the robot: advice to tilt it back
    // would turn the headings further (distortion left out of the file: 0.03° → 0.42°).
    let camera_file_named = height.is_some() || side.is_some();
    let tilt = if shear.is_none() {
        crate::tag_tilt::TagTilt::of(result, &camera.camera, floor, options)
            .map(|t| {
                if camera_file_named {
                    t.camera_warning().into_iter().collect()
                } else {
                    t.warnings()
                }
            })
            .unwrap_or_default()
    } else {
        Vec::new()
    };
    [height, side, shear]
        .into_iter()
        .flatten()
        .chain(tilt)
        .collect()
}

/// Silences FFmpeg's and OpenCV's own complaints about bad files (unless the user set their
/// log levels), so that odocal's one-line messages are the ones seen.
pub fn quiet_video_logs() {
    for (var, level) in [
        ("OPENCV_FFMPEG_LOGLEVEL", "0"),
        ("OPENCV_LOG_LEVEL", "SILENT"),
    ] {
        if std::env::var_os(var).is_none() {
            std::env::set_var(var, level);
        }
    }
}

impl TrackResult {
    /// One line on the tracking run: fixes, gaps and the ids seen.
    pub fn summary(&self, tag_id: u32) -> String {
        let gaps = self.gaps();
        let longest = gaps
            .iter()
            .map(|g| g.last_index - g.first_index + 1)
            .max()
            .unwrap_or(0);
        format!(
            "tracked tag {tag_id} in {}/{} frames ({} gaps, longest {longest} frames); {}",
            self.fixes().count(),
            self.records.len(),
            gaps.len(),
            self.seen_ids_text()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::mount_warnings;
    use odocal_core::{Pose2, TagToRobot, Trajectory, TrajectoryRow};

    /// 3 s at 30 frames/s of a robot driving at 0.3 m/s along 40°, backwards when `speed` <
    /// 0, its tag turned by `tag_turn_rad` from the robot's front.
    fn drive(speed: f64, tag_turn_rad: f64) -> Trajectory {
        let dir = 40f64.to_radians();
        let rows = (0..90)
            .map(|i| {
                let t_s = i as f64 / 30.0;
                TrajectoryRow {
                    t_s,
                    pose: Pose2::new(
                        speed * t_s * dir.cos(),
                        speed * t_s * dir.sin(),
                        dir + tag_turn_rad + 1e-3 * ((i * 37) % 5) as f64,
                    ),
                    quality: 1.0,
                    sigma: None,
                }
            })
            .collect();
        Trajectory::new(rows).expect("trajectory")
    }

    fn said(t: &Trajectory) -> String {
        mount_warnings(t, &TagToRobot::IDENTITY).join("\n")
    }

    #[test]
    fn a_tag_mounted_turned_is_named() {
        assert_eq!(said(&drive(0.3, 0.0)), "");
        // Without the wheels to say which way it drove, a run spent reversing is named too,
        // with that caveat.
        let back = said(&drive(-0.3, 0.0));
        assert!(
            back.contains("unless the robot reversed the whole time"),
            "{back}"
        );
        let turned = said(&drive(0.3, std::f64::consts::PI));
        assert!(
            turned.contains("backwards along its x axis on 100 % of"),
            "{turned}"
        );
        assert!(turned.contains("give --tag-yaw 180.0 (degrees"), "{turned}");
        let side = said(&drive(0.3, -std::f64::consts::FRAC_PI_2));
        // The headings' jitter averages 0.1°.
        assert!(side.contains("the tag is turned -89.9° (± 0.0°"), "{side}");
        assert!(side.contains("give --tag-yaw -89.9 (degrees"), "{side}");
        // 20° is named, 1° (a tag laid by eye) is not.
        let slight = said(&drive(0.3, 0.35));
        assert!(slight.contains("give --tag-yaw 20.2 (degrees"), "{slight}");
        assert_eq!(said(&drive(0.3, 0.017)), "");
        // Given that yaw, the trajectory is the robot's and nothing is said.
        for yaw in [-std::f64::consts::FRAC_PI_2, std::f64::consts::PI, 0.35] {
            let mount = TagToRobot::new(0.0, 0.0, yaw);
            let robot = mount.robot_trajectory(&drive(0.3, yaw));
            assert_eq!(mount_warnings(&robot, &mount), Vec::<String>::new());
        }
    }
}
