//! odocal-tracker: the robot's trajectory on the floor from ceiling-camera
//! frames. Frame sources (videos through OpenCV/FFmpeg, image folders),
//! AprilTag detection, the planar floor pose of a horizontal marker at a known
//! height (solvePnP as a cross-check), ROI tracking with full-frame fallback,
//! per-frame quality, gaps and jump rejection, and overlays. Trajectory files
//! are `odocal_core::Trajectory` (CSV `t,x,y,theta,quality,sigma_x,sigma_y,sigma_theta`, TUM export).

mod deblur;
pub mod detect;
mod edges;
mod error;
mod interlace;
mod lost_frames;
pub mod marker_height;
pub mod multi;
pub mod overlay;
pub mod pose;
mod repeats;
mod report;
pub mod rolling_shutter;
pub mod source;
pub mod tag_tilt;
pub mod timing;
pub mod track;
pub mod uncertainty;
pub mod vouched;

pub use detect::{check_tag_id, Roi, TagDetection, TagDetector};
pub use error::TrackError;
pub use marker_height::MarkerHeight;
pub use odocal_core::{PoseSigma, Trajectory, TrajectoryRow};
pub use pose::{planar_pose, pnp_cross_check, tag_model, PlanarPose, PnpCheck};
pub use report::{
    errors_against, few_fixes_warning, fix_warnings, mount_warnings, mount_warnings_of_runs,
    quiet_video_logs, reference_at, tag_shape_warnings, track_report, track_video, AgainstTruth,
    FoundFrames, TrackReport, TrackReportTruth, TruthErrors, TRACK_REPORT_FORMAT,
};
pub use rolling_shutter::ShutterEstimate;
pub use source::{
    open_source, Frame, FrameSource, GrayFrame, MemorySource, SourceInfo, SourceOptions,
};
pub use timing::{DroppedFrames, TimingReport};
pub use track::{
    track_source, Fix, FrameRecord, Gap, GapReason, OtherTag, Outcome, TrackOptions, TrackResult,
    Tracker,
};
pub use vouched::UnvouchedFixes;
