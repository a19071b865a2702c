//! The bottom of odocal: planar poses and angle wrapping, the least-squares rigid / Helmert
//! fit used by both dataset alignment and laser positioning, and the file formats every stage
//! shares (trajectory CSV, CSV tables of numbers, JSON files tagged with their format).
//! ARCHITECTURE.md at the repository root shows where this crate sits.
//!
//! Convention, stated once for all of odocal: x forward/right on the floor,
//! y to the left of x, z up; angles counter-clockwise positive, in radians.

mod digest;
mod file_error;
mod file_kind;
mod fit;
pub mod lsq;
mod motion_heading;
mod natural_order;
mod pose;
mod ray;
pub mod staging;
mod table;
mod tag_mount;
mod tagged_json;
mod trajectory;

pub use digest::sha256_hex;
pub use file_error::{read_text, FileError};
pub use file_kind::{file_kind, is_video};
pub use fit::{fit_helmert, fit_rigid, FitError, Helmert2, RigidFit};
pub use motion_heading::MotionAgainstHeading;
pub use natural_order::{natural_cmp, natural_path_cmp, sort_naturally};
pub use pose::{wrap_angle, Pose2};
pub use ray::ray_segment;
pub use table::{
    csv_error, csv_table, csv_table_with_header, numeric_row, CsvTable, LineIndex, TextFormat,
};
pub use tag_mount::{MountFit, TagToRobot, TagYawError, MAX_TAG_YAW_DEG};
pub use tagged_json::{
    check_format_tag, parse_json_value, parse_tagged_json, read_tagged_json, without_bom,
};
pub use trajectory::{
    mean_pose, PoseSigma, Reference, Trajectory, TrajectoryRow, REFERENCE_MAX_GAP_S, SAME_TIME_S,
    TRAJECTORY_HEADER, TRAJECTORY_SIGMA_HEADER,
};
