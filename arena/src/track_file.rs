//! The arena tracking summary (`odocal.arena-track/1`): the clock offsets found, and for
//! every robot which cameras gave each fused pose and every handoff, for reports.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{ArenaError, ArenaTracking};

/// The `format` tag of arena tracking summaries.
pub const ARENA_TRACK_FORMAT: &str = "odocal.arena-track/1";

/// One camera's clock offset and rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OffsetEntry {
    /// The camera's index in the arena.
    pub camera: usize,
    /// Offset, seconds.
    pub offset_s: f64,
    /// Its standard deviation, seconds.
    pub sigma_s: f64,
    /// How much faster the camera's clock runs than the arena clock, ppm (0 where not
    /// fitted): t_arena = t_camera + offset_s − rate·(t_camera − origin_s). Absent in files
    /// written before rates were fitted.
    #[serde(default)]
    pub rate_ppm: f64,
    /// The instant on the camera's clock at which the offset is `offset_s`, seconds.
    #[serde(default)]
    pub origin_s: f64,
}

/// One camera's frame rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrameRateEntry {
    /// The camera's index in the arena.
    pub camera: usize,
    /// Its frame rate, frames/s: one over the median interval between its frames
    /// ([`crate::frame_period_s`]).
    pub frames_per_s: f64,
}

/// One fused pose and the camera that weighed most in it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FusedRow {
    /// Arena time, seconds.
    pub t_s: f64,
    /// Floor x, metres.
    pub x_m: f64,
    /// Floor y, metres.
    pub y_m: f64,
    /// The camera with the largest share of the weight.
    pub camera: usize,
    /// How many cameras contributed.
    pub cameras: usize,
}

/// A handoff as written: a camera joining or leaving the fused set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HandoffEntry {
    /// Arena time, seconds.
    pub t_s: f64,
    /// The camera.
    pub camera: usize,
    /// Joins (true) or leaves (false).
    pub joins: bool,
    /// How far the fused position moves because of it, millimetres.
    pub jump_mm: f64,
    /// How far that camera's own position is from the others' fused one, millimetres.
    pub disagreement_mm: f64,
}

/// One robot's fused track in the summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotEntry {
    /// The robot's tag id.
    pub tag_id: u32,
    /// The trajectory file written for it.
    pub trajectory: String,
    /// The fused poses.
    pub rows: Vec<FusedRow>,
    /// The handoffs.
    pub handoffs: Vec<HandoffEntry>,
}

/// The contents of an arena tracking summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArenaTrackFile {
    /// Always [`ARENA_TRACK_FORMAT`].
    pub format: String,
    /// Every camera's clock offset (cameras that saw no robot have none).
    pub offsets: Vec<OffsetEntry>,
    /// RMS distance between simultaneous fixes of two cameras after the offsets, millimetres.
    pub offset_fit_rms_mm: f64,
    /// Every camera's frame rate (the cameras may run at different rates; a camera with fewer
    /// than two frames has none). Empty in files written before it was kept.
    #[serde(default)]
    pub frame_rates: Vec<FrameRateEntry>,
    /// The robots.
    pub robots: Vec<RobotEntry>,
    /// SHA-256 of the arena.json the tracking used ([`odocal_core::sha256_hex`]), so a report
    /// beside another arena is refused; absent in files written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arena_sha256: Option<String>,
}

impl ArenaTrackFile {
    /// The summary of a tracking; `files` names each robot's trajectory file, in robot order;
    /// `arena_sha256` is that of the arena.json tracked with.
    pub fn of(tracking: &ArenaTracking, files: &[String], arena_sha256: String) -> Self {
        Self {
            arena_sha256: Some(arena_sha256),
            format: ARENA_TRACK_FORMAT.into(),
            // Cameras that saw no robot have no offset to write.
            offsets: (0..tracking.offsets.offset_s.len())
                .filter(|&k| !tracking.offsets.sigma_s[k].is_nan())
                .map(|k| OffsetEntry {
                    camera: k,
                    offset_s: tracking.offsets.offset_s[k],
                    sigma_s: tracking.offsets.sigma_s[k],
                    rate_ppm: tracking.offsets.rate[k].ppm(),
                    origin_s: tracking.offsets.origin_s[k],
                })
                .collect(),
            offset_fit_rms_mm: tracking.offsets.rms_m * 1e3,
            frame_rates: tracking
                .frame_period_s
                .iter()
                .enumerate()
                .filter_map(|(camera, p)| {
                    p.map(|p| FrameRateEntry {
                        camera,
                        frames_per_s: 1.0 / p,
                    })
                })
                .collect(),
            robots: tracking
                .robots
                .iter()
                .zip(files)
                .map(|(r, f)| RobotEntry {
                    tag_id: r.tag_id,
                    trajectory: f.clone(),
                    rows: r
                        .trajectory
                        .rows
                        .iter()
                        .zip(&r.contributions)
                        .map(|(row, c)| FusedRow {
                            t_s: row.t_s,
                            x_m: row.pose.x_m,
                            y_m: row.pose.y_m,
                            camera: c
                                .iter()
                                .max_by(|a, b| a.1.total_cmp(&b.1))
                                .map_or(0, |(k, _)| *k),
                            cameras: c.len(),
                        })
                        .collect(),
                    handoffs: r
                        .handoffs
                        .iter()
                        .map(|h| HandoffEntry {
                            t_s: h.t_s,
                            camera: h.camera,
                            joins: h.joins,
                            jump_mm: h.jump_m * 1e3,
                            disagreement_mm: h.disagreement_m * 1e3,
                        })
                        .collect(),
                })
                .collect(),
        }
    }

    /// Reads a summary written by `odocal track --arena --arena-report`.
    pub fn load(path: &Path) -> Result<Self, ArenaError> {
        Ok(odocal_core::read_tagged_json(
            path,
            ARENA_TRACK_FORMAT,
            "expected the --arena-report file of `odocal track --arena`",
        )?)
    }
}
