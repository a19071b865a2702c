//! odocal-arena: several ceiling cameras in one floor frame, and robots tracked across them.
//!
//! Each camera is calibrated on its own (`odocal calibrate`). Boards lying on the floor where
//! views overlap, photographed by two or more cameras at once (the shared views), tie the
//! cameras together: [`solve_arena`] fits every camera's pose in the floor frame of the first
//! camera and every shared board's place on the floor by least squares over the corners'
//! pixel residuals (a small pose graph through `odocal_core::lsq`), and reports how far apart
//! two cameras put the same floor point ([`Consistency`]). The result is the arena file
//! (`odocal.arena/1`, [`ArenaFile`]).
//!
//! Tracking across cameras ([`fuse`]): each camera's video is tracked on its own, already in
//! the arena's floor frame; the cameras' clock offsets are estimated from robots seen by two
//! cameras at once, and simultaneous fixes are fused with weights that fade out towards each
//! image's border, so a robot handed from one view to the next does not jump. Each fix's σ
//! carries the calibrations' uncertainty through the arena fit (every camera's intrinsics
//! covariance moves the fitted poses, and so does the first camera's floor, which is the
//! arena's floor frame), and the fusion does not average that part down. The part of the
//! floor frame's uncertainty that moves every fix alike is stated on its own
//! ([`FramePlacement`]): a run aligned to its odometry takes it up.
//! A camera whose video is turned 180° against its calibration is named ([`TurnedCamera`])
//! rather than blamed on its clock.

mod error;
mod file;
pub mod fuse;
mod graph;
mod shared;
pub mod track;
mod track_file;
mod turned;

pub use error::ArenaError;
pub use file::{
    ArenaCamera, ArenaFile, Consistency, FramePlacement, PairConsistency, ARENA_FORMAT,
};
pub use fuse::{
    estimate_clock_offsets, fix_weight, fuse_robot, Agreement, CameraFix, CameraTrack,
    ClockOffsets, ClockRate, Disagreement, FuseGrid, FuseOptions, FusedTrack, Handoff, TooFast,
    DISAGREE_SIGMAS, MAX_RATE_PPM, MIN_RATE_SPAN_S,
};
pub use graph::{
    build_arena, height_warnings, shared_residual_warnings, solve_arena, ArenaSolution, Renumbered,
    SharedObservation, REFUSE_RMS_MM,
};
pub use shared::{check_board_scale, detect_shared, parse_shared_name, SharedView};
pub use track::{
    camera_tracks, check_frame_folders, clock_priors, frame_period_s, fuse_all, track_camera,
    track_cameras, ArenaTracking, CameraResult,
};
pub use track_file::{
    ArenaTrackFile, FrameRateEntry, FusedRow, HandoffEntry, OffsetEntry, RobotEntry,
    ARENA_TRACK_FORMAT,
};
pub use turned::TurnedCamera;
