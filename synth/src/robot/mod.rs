//! Differential-drive robot simulator for the odometry experiment odocal reproduces (131
//! straight runs of a small robot, each filmed from the ceiling and logged every 200 ms).
//!
//! The robot (wheel Ø 4.3 cm, 12 counts/rev, wheel base ≈ 10 cm) drives straight runs of
//! ~1.5 m. Control is "PID on one wheel": the left (master) wheel runs open loop at its
//! calibrated speed, the right (slave) wheel is PID-controlled to keep the encoder counts of the
//! two wheels equal. With 12 counts/rev the tick difference is coarse, so the heading
//! oscillates, as on small real robots.
//!
//! Error model (the experiment's: measured = true + sigma |d| + eps):
//! - systematic: true wheel diameters differ from the nominal one and from each other, the
//!   effective wheel base differs from the nominal one, and each wheel slips by a fraction that
//!   grows with speed (slip = k * v);
//! - random: per-wheel slip wandering along the path (Ornstein-Uhlenbeck in distance), floor
//!   roughness (heading random walk), motor speed disturbances (seen by the encoders);
//! - encoder quantisation (floor of the wheel angle in counts, random initial phase);
//! - the robot's clock: its log starts at robot time 0, the camera started `lead` seconds
//!   earlier, so t_camera = t_robot + offset with offset = lead, different per recording.
//!
//! Everything is seeded: a recording is a function of (config, speeds, seed, stream).

mod config;
mod physics;
mod plan;
mod recording;
mod simulate;
mod truth_track;

pub use config::*;
pub use plan::{simulate_plan, PathKind, Plan, Segment};
pub use recording::*;
pub use simulate::simulate_recording;
pub use truth_track::{TruthTrack, TruthTrackRow, TRUTH_TRACK_HEADER};

use odocal_core::{wrap_angle, Pose2};
use odocal_core::{FileError, Trajectory, TrajectoryRow};
use odocal_dataset::{DatasetError, OdometryLog};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use thiserror::Error;
