//! Tracking every camera's video of the arena: each video tracked on its own (all selected
//! tags in one pass, the camera's arena pose, so every fix is already in the arena's floor
//! frame), the videos in parallel, then the clock offsets and one fused trajectory per robot.

use std::collections::BTreeMap;
use std::path::PathBuf;

use odocal_tracker::multi::{track_source_multi, TagSelection};
use odocal_tracker::{open_source, Outcome, SourceOptions, TrackOptions, TrackResult};

use crate::fuse::{estimate_clock_offsets, fix_weight, fuse_robot};
use crate::{ArenaError, ArenaFile, CameraFix, CameraTrack, ClockOffsets, FuseOptions, FusedTrack};

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
    Ok(track_source_multi(
        source,
        &cam.calibration.camera,
        &cam.arena_to_camera,
        &opts.clone().with_calibration(&cam.calibration),
        selection,
        &mut |_| {},
    )?)
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

/// Every camera's fixes as [`CameraTrack`]s with their fusion weights.
pub fn camera_tracks(
    arena: &ArenaFile,
    results: &[CameraResult],
    marker_height_m: f64,
) -> Vec<CameraTrack> {
    let mut tracks = Vec::new();
    for (k, per_id) in results.iter().enumerate() {
        let cam = &arena.cameras[k];
        for (id, result) in per_id {
            let fixes: Vec<CameraFix> = result
                .records
                .iter()
                .filter_map(|r| match &r.outcome {
                    Outcome::Fix(f) => Some(CameraFix {
                        // The time the tag's rows were read (the frame's time unless a
                        // rolling shutter was given).
                        t_s: f.t_s,
                        pose: f.pose,
                        // The fix's own position σ (detection noise and calibration), the
                        // mean of its two axes' variances.
                        weight: fix_weight(
                            &cam.calibration.camera,
                            &cam.arena_to_camera,
                            &f.corners_px,
                            marker_height_m,
                            Some((0.5 * (f.sigma.x_m.powi(2) + f.sigma.y_m.powi(2))).sqrt()),
                        ),
                        quality: f.quality,
                        sigma: Some(f.sigma),
                    }),
                    Outcome::Gap(_) => None,
                })
                .collect();
            if fixes.len() >= 2 {
                tracks.push(CameraTrack {
                    camera: k,
                    tag_id: *id,
                    fixes,
                });
            }
        }
    }
    tracks
}

/// The clock offsets and every robot's fused trajectory.
pub struct ArenaTracking {
    /// The cameras' clock offsets.
    pub offsets: ClockOffsets,
    /// One fused trajectory per tag id seen, in id order.
    pub robots: Vec<FusedTrack>,
    /// Every camera's fixes, for plots.
    pub tracks: Vec<CameraTrack>,
}

/// Offsets and fusion from every camera's tracking.
pub fn fuse_all(
    arena: &ArenaFile,
    results: &[CameraResult],
    marker_height_m: f64,
    opts: &FuseOptions,
) -> Result<ArenaTracking, ArenaError> {
    let tracks = camera_tracks(arena, results, marker_height_m);
    let offsets = estimate_clock_offsets(&tracks, arena.cameras.len(), opts)?;
    let mut ids: Vec<u32> = tracks.iter().map(|t| t.tag_id).collect();
    ids.sort_unstable();
    ids.dedup();
    let robots = ids
        .iter()
        .map(|id| fuse_robot(*id, &tracks, &offsets, opts))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(ArenaTracking {
        offsets,
        robots,
        tracks,
    })
}
