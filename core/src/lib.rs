//! Shared 2-D geometry: planar poses, angle wrapping and the least-squares
//! rigid / Helmert fit used by both dataset alignment and laser positioning.
//!
//! Convention, stated once for all of odocal: x forward/right on the floor,
//! y to the left of x, z up; angles counter-clockwise positive, in radians.

mod fit;
mod pose;

pub use fit::{fit_helmert, fit_rigid, FitError, Helmert2, RigidFit};
pub use pose::{wrap_angle, Pose2};
