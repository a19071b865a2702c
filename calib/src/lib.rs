//! Camera model, checkerboard and ChArUco detection, Zhang calibration (through OpenCV)
//! and the floor plane of a ceiling camera.

pub mod calibrate;
pub mod camera_file;
pub mod charuco;
mod coverage;
pub mod detect;
mod error;
pub mod export;
pub mod floor;
mod floor_consistency;
pub mod floor_uncertainty;
pub mod model;
mod opencv_glue;
pub mod select;
mod session;
pub mod uncertainty;
pub mod view_consistency;

pub use calibrate::{board_points, calibrate, Calibration, Observation};
pub use camera_file::{
    check_pose_covariance, BoardSpec, BoardTarget, CameraFile, FloorPlane, IntrinsicsStd,
    SkippedView, ViewResidual, CAMERA_FORMAT, MAX_POSE_SHIFT_SIGMA_M, MAX_POSE_TURN_SIGMA_RAD,
};
pub use charuco::ArucoDictionary;
pub use detect::{detect_file, display_rotation, BoardView, Detection, IMREAD_SENSOR_GRAY};
pub use error::CalibError;
pub use floor::{board_pose, fit_floor};
pub use floor_uncertainty::{
    FloorReach, FloorUncertaintyMap, FLOOR_BOUND_MM, FLOOR_BOUND_SIGMAS, MODEL_SPREAD_SHARE,
};
pub use model::{
    intersect_plane_z, BoardToCamera, CameraModel, Distortion, FloorToCamera, Intrinsics, LensModel,
};
pub use opencv_glue::{camera_matrix, dist_coeffs, solve_pnp};
pub use select::{compare_models, ModelScore};
pub use session::{calibrate_session, summary, ModelChoice, Session};
pub use uncertainty::{projection_sigma_px, UncertaintyMap};
