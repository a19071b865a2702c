//! odocal-lrf: positioning a laser range finder (Hokuyo Pos-URG-like) among
//! sparse reflective landmarks with known positions.
//!
//! Pipeline: [`Map`] (landmarks, reflector orientation, visibility lines,
//! sorted distance relations) → [`Scan`] (one sweep, right to left) →
//! [`extract_detections`] (clusters of high-intensity returns) →
//! [`Localizer::global`] (association without a prior: the source's chained
//! distance/angle search made robust to missed and spurious reflections, with
//! negative evidence and ambiguity detection) or [`ScanTracker::process`]
//! (matching near the predicted pose, falling back to global search, keeping
//! several hypotheses until the motion resolves them).
//!
//! Poses are [`odocal_core::Pose2`] of the *sensor in the map frame*:
//! they map points from the sensor frame (x along the scan's 0 rad beam,
//! angles counter-clockwise) into the map frame.

mod check;
mod error;
mod eval;
mod localize;
mod map;
mod noise_probe;
mod pose_fit;
mod pose_log;
mod scan;
mod scan_track;
mod search;
mod sweep;

pub use check::{
    check_map_report, find_ambiguities, layout_repeats, Ambiguity, AmbiguityKind,
    DEFAULT_TOLERANCE_M,
};
pub use error::LrfError;
pub use eval::{
    evaluate, read_truth_csv, truth_unit_hint, EstimatedPose, Evaluation, LaserTruth, TruthAt,
    TruthPose, BEYOND_SIGMAS, CORRECT_POS_M,
};
pub use localize::{
    check_beam_step, check_fov, check_intensity_scale, check_range_unit, check_scan_times,
    drop_beyond_range, localize_scans, read_scan_files, Calibration, FitQuality, Localized,
    MovedLandmark, ScanFiles, Skewed, Systematic, SUPPORT_ROWS,
};
pub use map::{Landmark, LandmarkSpec, Map, MapFile, Side, VisibilityLine, MAP_FORMAT};
pub use noise_probe::{
    facings_hide_poses, mirror_fits_better, mirrored_finds_poses, poses_outside,
    wider_noise_finds_poses, FacingsOff, MirrorFits, Mirrored, WiderNoise, HULL_MARGIN_M,
};
pub use pose_log::{PoseLog, PoseLogRow, POSE_LOG_HEADER};
pub use scan::{
    extract_detections, parse_scans_csv, read_scans_csv, Detection, Scan, ScanFile, SensorConfig,
};
pub use scan_track::{ScanFix, ScanTracker};
pub use search::{Hypothesis, Localization, Localizer, LocalizerConfig, SearchStats, Status};

#[cfg(test)]
mod tests;
