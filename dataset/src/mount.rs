//! Where a trajectory file's point and heading sit on the robot. A motion-capture body is
//! defined by hand: its x axis a few degrees off the robot's front, its origin a few
//! centimetres off the wheel axle. The wheels' odometry is the axle midpoint's, heading
//! forwards, so every target made from such a trajectory is turned and shifted with it: a
//! heading 3° off put straight-run targets 77 mm from the truth (0.5 mm without), a body 8 cm
//! ahead of the axle put tour windows 128 mm off (3 mm without), and nothing was said. The
//! trajectories of all recordings are fitted together ([`MountFit`], as `track` does for a
//! tag), since a straight run alone turns too little to show a distance ahead.

use odocal_core::{wrap_angle, MotionAgainstHeading, MountFit, TagToRobot, Trajectory};

/// What the trajectories' motion says about their mount.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MountCheck {
    /// Why the dataset is refused: a heading turned from the direction the robot drives.
    pub refusal: Option<String>,
    /// A point off the axle, said as a warning: a skid-steered robot slips sideways on turns
    /// as such a point does, so the fit alone cannot refuse the data.
    pub warning: Option<String>,
}

/// Checks the robot trajectories `trajectories` (each taken off `given`, the
/// `--tag-offset`/`--tag-yaw` the user gave) for a heading turned from the direction of
/// motion and a point that slips sideways on turns.
pub fn check_mount(trajectories: &[&Trajectory], given: &TagToRobot) -> MountCheck {
    let runs: Vec<&[odocal_core::TrajectoryRow]> =
        trajectories.iter().map(|t| t.rows.as_slice()).collect();
    // Backwards along the heading is the heading check's ([`crate::heading`]) to name.
    let motion = MotionAgainstHeading::of_runs(&runs, 1.0);
    if motion.line_misfit_rad().is_some()
        && motion.forward_share() <= 1.0 - MotionAgainstHeading::ONE_WAY
    {
        return MountCheck::default();
    }
    let Some(fit) = MountFit::of_runs(&runs) else {
        return MountCheck::default();
    };
    let taken_off = if given.is_identity() {
        ""
    } else {
        ", taken off the --tag-offset/--tag-yaw given,"
    };
    let recordings = trajectories.len();
    let refusal = fit.named_yaw_rad().map(|yaw| {
        format!(
            "the trajectories' heading{taken_off} is turned {:+.1}° (± {:.2}°, 1σ, over {} steps of {} recording{}) from the direction the robot drives, where a wheeled robot drives along its heading, so every target would be turned by as much (3° puts a 1.5 m run's end 8 cm off): give --tag-yaw {:.1} (degrees from the robot's front to the trajectory's x axis, counter-clockwise; a motion-capture body's axes are often set by hand), or define the body's x axis along the robot's front",
            yaw.to_degrees(),
            fit.yaw_sigma_rad.to_degrees(),
            fit.steps,
            recordings,
            if recordings == 1 { "" } else { "s" },
            wrap_angle(given.0.theta_rad + yaw).to_degrees()
        )
    });
    let warning = fit.ahead_m.and_then(|ahead| {
        // As `track` advises: the distance ahead adds to the offset given along the robot's
        // axes; the path cannot show the sideways one, so the one given is kept.
        let (s, c) = fit.named_yaw_rad().unwrap_or(0.0).sin_cos();
        let advised_ahead_m = ahead + c * given.0.x_m - s * given.0.y_m;
        let change_m = (advised_ahead_m - given.0.x_m).abs();
        (change_m > MountFit::NAMED_AHEAD_M && change_m > 5.0 * fit.ahead_sigma_m).then(|| {
            format!(
                "the trajectories' point{taken_off} slips sideways on turns as a point {:.1} cm {} the wheel axle does (± {:.1} cm, 1σ, from {:.0}° of turning over {} recording{}), where the midpoint of a differential drive's axle never slips: if that is where the motion-capture body's origin (or the tag) sits, give --tag-offset {:.3},{:.3} (metres ahead of and to the left of the axle midpoint; the path shows only the distance ahead, so measure the sideways one) so the trajectory is the axle's, as the odometry is; until then targets on turns are off by up to {:.1} cm. Skid-steered robots slip on every turn and may show this too",
                100.0 * ahead.abs(),
                if ahead > 0.0 { "ahead of" } else { "behind" },
                100.0 * fit.ahead_sigma_m,
                fit.turned_rad.to_degrees(),
                recordings,
                if recordings == 1 { "" } else { "s" },
                advised_ahead_m,
                given.0.y_m,
                100.0 * ahead.abs(),
            )
        })
    });
    MountCheck { refusal, warning }
}
