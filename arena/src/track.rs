//! Tracking every camera's video of the arena: each video tracked on its own (all selected
//! tags in one pass, the camera's arena pose, so every fix is already in the arena's floor
//! frame), the videos in parallel, then the clock offsets and one fused trajectory per robot.

use std::collections::BTreeMap;
use std::path::PathBuf;

use nalgebra::{DMatrix, Matrix2, Point2, Vector2};
use odocal_calib::FloorToCamera;
use odocal_core::PoseSigma;
use odocal_tracker::multi::{track_source_multi, TagSelection};
use odocal_tracker::{open_source, Fix, Outcome, SourceOptions, TrackOptions, TrackResult};

use crate::fuse::{camera_agreement, estimate_clock_offsets, fix_weight, fuse_robot};
use crate::graph::camera_pose;
use crate::turned::{turned_fix, TurnedCamera, AGREE_SHARE, DISAGREE_SHARE};
use crate::{
    ArenaCamera, ArenaError, ArenaFile, CameraFix, CameraTrack, ClockOffsets, FuseGrid,
    FuseOptions, FusedTrack,
};

/// One camera's tracking: every selected tag's result.
pub type CameraResult = BTreeMap<u32, TrackResult>;

/// Tracks camera k's video (or image folder) with its arena pose.
pub fn track_camera(
    arena: &ArenaFile,
    k: usize,
    video: &std::path::Path,
    opts: &TrackOptions,
    selection: &TagSelection,
) -> Result<CameraResult, ArenaError> {
    let cam = &arena.cameras[k];
    let source = open_source(video, &SourceOptions::default())?;
    let (w, h) = (cam.calibration.camera.width, cam.calibration.camera.height);
    let info = source.info();
    // Width and height swapped: a camera's picture turned a quarter, which no other
    // calibration at another resolution explains as well.
    if w != h && (info.width, info.height) == (h, w) {
        return Err(ArenaError::Input(format!(
            "{} (camera {k}) is {}×{}, camera file {}'s {w}×{h} turned a quarter: the video looks turned 90°; turn it back with ffmpeg -vf transpose=1 or transpose=2 (whichever puts the image as the calibration views were taken; each image of a frame folder alike), or recalibrate that camera on turned views and run `odocal arena` again",
            video.display(),
            info.width,
            info.height,
            cam.source
        )));
    }
    Ok(track_source_multi(
        source,
        &cam.calibration.camera,
        &cam.arena_to_camera,
        // With the arena's covariance of this camera, the calibration's part of each fix's
        // σ is that (`camera_tracks`); the camera's own floor map is of its own floor frame.
        &match cam.pose_covariance {
            Some(_) => opts.clone(),
            None => opts.clone().with_calibration(&cam.calibration),
        },
        selection,
        &mut |_| {},
    )?)
}

/// Refuses a video given for two cameras, and a frame folder without its own timestamps
/// file: frame counts would put every camera on its own guess of a frame rate, and --fps is
/// one video's, so a frame folder of an arena camera carries its own times.
pub fn check_frame_folders(videos: &[PathBuf]) -> Result<(), ArenaError> {
    // One camera's recording given for two was tracked for half a minute, then blamed on an
    // unknown clock offset.
    let same = |v: &PathBuf| std::fs::canonicalize(v).unwrap_or_else(|_| v.clone());
    for (k, v) in videos.iter().enumerate() {
        if let Some(j) = videos[..k].iter().position(|u| same(u) == same(v)) {
            return Err(ArenaError::Input(format!(
                "{} is given for camera {j} and camera {k}: each arena camera's own video, in the order of arena.json's cameras",
                v.display()
            )));
        }
    }
    match videos
        .iter()
        .find(|v| v.is_dir() && !v.join(odocal_tracker::source::FOLDER_TIMESTAMPS).is_file())
    {
        Some(dir) => Err(ArenaError::Input(format!(
            "{}: a frame folder of an arena camera needs its frames' times: put a {} into it (columns file,t: each image's file name and its time in seconds on that camera's clock)",
            dir.display(),
            odocal_tracker::source::FOLDER_TIMESTAMPS
        ))),
        None => Ok(()),
    }
}

/// Tracks every camera's video, `parallel` (a thread per video) or one after another.
///
/// A video is one sequential chain (each frame's search region comes from the previous
/// fix), so as tasks on a pool the last video would run alone while the other cores wait;
/// with a thread per video the cores are shared among all chains until the end (1.96× on
/// 2 cores for four videos, `cargo bench --bench arena`, against 1.49× as pool tasks).
pub fn track_cameras(
    arena: &ArenaFile,
    videos: &[PathBuf],
    opts: &TrackOptions,
    selection: &TagSelection,
    parallel: bool,
) -> Result<Vec<CameraResult>, ArenaError> {
    if videos.len() != arena.cameras.len() {
        return Err(ArenaError::Input(format!(
            "{} videos for an arena of {} cameras: give one video per camera, in the arena file's order",
            videos.len(),
            arena.cameras.len()
        )));
    }
    check_frame_folders(videos)?;
    let one = |(k, v): (usize, &PathBuf)| track_camera(arena, k, v, opts, selection);
    if parallel {
        std::thread::scope(|scope| {
            let handles: Vec<_> = videos
                .iter()
                .enumerate()
                .map(|kv| scope.spawn(move || one(kv)))
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .collect()
        })
    } else {
        videos.iter().enumerate().map(one).collect()
    }
}

/// A camera's frame period, seconds: the median interval between its frames (every tag's
/// records are every frame, fix or gap, so dropped frames do not count); none with fewer
/// than two frames.
pub fn frame_period_s(result: &CameraResult) -> Option<f64> {
    let records = &result.values().next()?.records;
    let mut dt: Vec<f64> = records
        .windows(2)
        .map(|w| w[1].t_s - w[0].t_s)
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    dt.sort_by(f64::total_cmp);
    dt.get(dt.len() / 2).copied()
}

/// Every camera's fixes as [`CameraTrack`]s with their fusion weights.
pub fn camera_tracks(
    arena: &ArenaFile,
    results: &[CameraResult],
    marker_height_m: f64,
) -> Vec<CameraTrack> {
    tracks_turning(arena, results, marker_height_m, None)
}

/// [`camera_tracks`] with camera `turned`'s fixes as they are with its image turned half a
/// turn ([`turned_fix`]).
fn tracks_turning(
    arena: &ArenaFile,
    results: &[CameraResult],
    marker_height_m: f64,
    turned: Option<usize>,
) -> Vec<CameraTrack> {
    let mut tracks = Vec::new();
    for (k, per_id) in results.iter().enumerate() {
        let cam = &arena.cameras[k];
        // Two fixes make a track, and their frames a period.
        let Some(period_s) = frame_period_s(per_id) else {
            continue;
        };
        for (id, result) in per_id {
            let fixes: Vec<CameraFix> = result
                .records
                .iter()
                .filter_map(|r| match &r.outcome {
                    Outcome::Fix(f) if turned == Some(k) => turned_fix(cam, f, marker_height_m)
                        .map(|f| camera_fix(cam, &f, marker_height_m)),
                    Outcome::Fix(f) => Some(camera_fix(cam, f, marker_height_m)),
                    Outcome::Gap(_) => None,
                })
                .collect();
            if fixes.len() >= 2 {
                tracks.push(CameraTrack {
                    camera: k,
                    tag_id: *id,
                    fixes,
                    period_s,
                });
            }
        }
    }
    tracks
}

/// One fix as the fusion takes it: its σ with the calibration's part, and how much of it is
/// shared with the camera's other fixes and the other cameras (`CameraFix::shared_m`).
fn camera_fix(cam: &ArenaCamera, f: &Fix, marker_height_m: f64) -> CameraFix {
    let centre = odocal_tracker::detect::quad_centre(&f.corners_px);
    let (sigma, shared_m) = match calibration_covariance(cam, &centre, marker_height_m) {
        // Tracked without the calibration: the fix's own σ is its corners' noise.
        Some(c) => (
            PoseSigma {
                x_m: (f.sigma.x_m.powi(2) + c[(0, 0)]).sqrt(),
                y_m: (f.sigma.y_m.powi(2) + c[(1, 1)]).sqrt(),
                ..f.sigma
            },
            Vector2::new(c[(0, 0)].sqrt(), c[(1, 1)].sqrt()),
        ),
        // The tracker added the camera's floor map (the first camera's floor is the arena's).
        None => (
            f.sigma,
            cam.calibration
                .floor_uncertainty
                .as_ref()
                .and_then(|m| m.at(&centre))
                .map_or(Vector2::zeros(), |s_mm| Vector2::repeat(s_mm * 1e-3)),
        ),
    };
    CameraFix {
        // The time the tag's rows were read (the frame's time unless a rolling shutter was
        // given).
        t_s: f.t_s,
        pose: f.pose,
        // The fix's position σ, the mean of its two axes' variances.
        weight: fix_weight(
            &cam.calibration.camera,
            &cam.arena_to_camera,
            &f.corners_px,
            marker_height_m,
            Some((0.5 * (sigma.x_m.powi(2) + sigma.y_m.powi(2))).sqrt()),
        ),
        quality: f.quality,
        sigma: Some(sigma),
        shared_m,
    }
}

/// The covariance of the floor point a pixel maps to, from the arena's joint covariance of
/// the camera's pose and intrinsics (none without it).
pub(crate) fn calibration_covariance(
    cam: &ArenaCamera,
    pixel: &Point2<f64>,
    marker_height_m: f64,
) -> Option<Matrix2<f64>> {
    let rows = cam.pose_covariance.as_ref()?;
    let n = rows.len();
    let c = DMatrix::from_fn(n, n, |i, j| rows[i].get(j).copied().unwrap_or(0.0));
    let p0 = cam.calibration.camera.parameters();
    if n != 6 + p0.len() {
        return None;
    }
    let at = |d: &[f64]| {
        let q: Vec<f64> = p0.iter().zip(&d[6..]).map(|(a, b)| a + b).collect();
        let pose = FloorToCamera(camera_pose(&cam.arena_to_camera, &d[..6]));
        cam.calibration
            .camera
            .with_parameters(&q)
            .pixel_to_floor(&pose, pixel, marker_height_m)
    };
    let mut jac = DMatrix::zeros(2, n);
    for i in 0..n {
        let h = if i < 6 {
            1e-6
        } else {
            1e-6 * p0[i - 6].abs().max(1e-3)
        };
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        a[i] = h;
        b[i] = -h;
        let d = (at(&a)? - at(&b)?) / (2.0 * h);
        jac[(0, i)] = d.x;
        jac[(1, i)] = d.y;
    }
    let v = &jac * c * jac.transpose();
    Some(Matrix2::new(v[(0, 0)], v[(0, 1)], v[(1, 0)], v[(1, 1)]))
}

/// The clock offsets and every robot's fused trajectory.
pub struct ArenaTracking {
    /// The cameras' clock offsets.
    pub offsets: ClockOffsets,
    /// Each camera's clock offset as guessed from its frames' times before the fit
    /// ([`clock_priors`]): not 0 for a camera on another clock, re-based.
    pub prior_s: Vec<f64>,
    /// One fused trajectory per tag id seen, in id order.
    pub robots: Vec<FusedTrack>,
    /// Each camera's frame period, seconds ([`frame_period_s`]; none without two frames).
    pub frame_period_s: Vec<Option<f64>>,
    /// The fused rows' instants.
    pub grid: FuseGrid,
    /// Every camera's fixes, for plots.
    pub tracks: Vec<CameraTrack>,
}

/// Each camera's clock offset guessed from its frames' times, seconds (t_arena ≈ t_camera +
/// prior): 0, except for a camera whose recording lies, on its clock, more than
/// `max_offset_s` before or after the first camera's: it cannot have seen a robot at the
/// same time on the same clock, so its clock counts from another origin (epoch seconds
/// against seconds from the recording's start), and its first frame is taken as the first
/// camera's, the offset searched around that.
pub fn clock_priors(results: &[CameraResult], max_offset_s: f64) -> Vec<f64> {
    let spans: Vec<(f64, f64)> = results
        .iter()
        .map(|per_id| {
            per_id
                .values()
                .flat_map(|r| r.records.iter().map(|x| x.t_s))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| {
                    (lo.min(t), hi.max(t))
                })
        })
        .collect();
    priors_of_spans(&spans, max_offset_s)
}

/// [`clock_priors`] from each camera's first and last frame times (infinite for a camera
/// without frames).
pub(crate) fn priors_of_spans(spans: &[(f64, f64)], max_offset_s: f64) -> Vec<f64> {
    let Some(&(start, end)) = spans.iter().find(|s| s.0.is_finite()) else {
        return vec![0.0; spans.len()];
    };
    spans
        .iter()
        .map(|&(s, e)| {
            let apart = s > end + max_offset_s || e < start - max_offset_s;
            if s.is_finite() && apart {
                start - s
            } else {
                0.0
            }
        })
        .collect()
}

/// Offsets and fusion from every camera's tracking.
pub fn fuse_all(
    arena: &ArenaFile,
    results: &[CameraResult],
    marker_height_m: f64,
    opts: &FuseOptions,
) -> Result<ArenaTracking, ArenaError> {
    let tracks = camera_tracks(arena, results, marker_height_m);
    let prior_s = clock_priors(results, opts.max_offset_s);
    let cameras = arena.cameras.len();
    let saw: Vec<usize> = (0..cameras)
        .filter(|&k| tracks.iter().any(|t| t.camera == k))
        .collect();
    let turned = |suspects: &[usize], recorded: &dyn Fn(usize) -> Option<f64>| {
        suspects.iter().find_map(|&k| {
            turned_camera(
                arena,
                results,
                marker_height_m,
                opts,
                &prior_s,
                k,
                recorded(k),
            )
        })
    };
    let offsets = match estimate_clock_offsets(&tracks, cameras, opts, &prior_s) {
        Ok(o) => o,
        // A camera that lines up with no other at any offset may be turned: every camera is
        // a suspect, since the first one turned leaves all the others unplaced.
        Err(e) => return Err(turned(&saw, &|_| None).map_or(e, ArenaError::Turned)),
    };
    let grid = fuse_grid(results, &offsets, &tracks);
    // A turned camera placed in time (a robot near its image centre, whose mirror lands
    // close by) disagrees with the others wherever else it sees a robot.
    let disagreeing: Vec<(usize, f64)> = saw
        .iter()
        .filter_map(|&k| {
            let (a, beyond) = camera_agreement(k, &tracks, &offsets, opts, &grid);
            let share = beyond as f64 / a.fixes.max(1) as f64;
            (share > DISAGREE_SHARE).then_some((k, a.rms_m))
        })
        .collect();
    let suspects: Vec<usize> = disagreeing.iter().map(|(k, _)| *k).collect();
    let rms_of = |k: usize| disagreeing.iter().find(|(c, _)| *c == k).map(|(_, m)| *m);
    if let Some(t) = turned(&suspects, &rms_of) {
        return Err(ArenaError::Turned(t));
    }
    let mut ids: Vec<u32> = tracks.iter().map(|t| t.tag_id).collect();
    ids.sort_unstable();
    ids.dedup();
    let robots = ids
        .iter()
        .map(|id| fuse_robot(*id, &tracks, &offsets, opts, &grid))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(ArenaTracking {
        offsets,
        prior_s,
        robots,
        frame_period_s: results.iter().map(frame_period_s).collect(),
        grid,
        tracks,
    })
}

/// The fused rows' instants: on the reference camera's frames, its first frame time the
/// grid's origin (its records are every frame, fix or gap), every frame of the fastest camera
/// that saw a robot: on all the reference camera's frames when it is that fast, or a whole
/// multiple slower.
fn fuse_grid(results: &[CameraResult], offsets: &ClockOffsets, tracks: &[CameraTrack]) -> FuseGrid {
    FuseGrid {
        origin_s: results
            .get(offsets.reference)
            .and_then(|per_id| per_id.values().next())
            .and_then(|r| r.records.first())
            .map_or(0.0, |r| r.t_s),
        period_s: tracks
            .iter()
            .map(|t| t.period_s)
            .fold(f64::INFINITY, f64::min),
    }
}

/// Camera `k` as turned half a turn, when with its fixes turned back ([`turned_fix`]) the
/// clocks fit, it is placed in time, and its fixes agree with the other cameras' fused pose
/// (at least `opts.min_matches` comparisons, at most [`AGREE_SHARE`] of them beyond
/// [`crate::DISAGREE_SIGMAS`]). `recorded_rms_m`: its fixes' RMS distance from the others' as
/// recorded, none where they were never placed.
fn turned_camera(
    arena: &ArenaFile,
    results: &[CameraResult],
    marker_height_m: f64,
    opts: &FuseOptions,
    prior_s: &[f64],
    k: usize,
    recorded_rms_m: Option<f64>,
) -> Option<TurnedCamera> {
    let tracks = tracks_turning(arena, results, marker_height_m, Some(k));
    let offsets = estimate_clock_offsets(&tracks, arena.cameras.len(), opts, prior_s).ok()?;
    if offsets.sigma_s.get(k).is_none_or(|s| s.is_nan()) {
        return None;
    }
    let grid = fuse_grid(results, &offsets, &tracks);
    let (a, beyond) = camera_agreement(k, &tracks, &offsets, opts, &grid);
    let share = beyond as f64 / a.fixes.max(1) as f64;
    let agrees = a.fixes >= opts.min_matches && share <= AGREE_SHARE;
    agrees.then_some(TurnedCamera {
        camera: k,
        compared: a.fixes,
        turned_rms_m: a.rms_m,
        turned_sigmas_rms: a.sigmas_rms,
        recorded_rms_m,
        max_offset_s: opts.max_offset_s,
    })
}
