//! The robot's tag and how the camera reads it: the options `track` and `dataset` (whose
//! manifest rows with a video are tracked) share, with the same names and defaults.

use odocal_core::{TagToRobot, TagYawError};
use odocal_tracker::TrackOptions;

/// Two finite numbers written `A,B`.
fn finite_pair(s: &str) -> Option<(f64, f64)> {
    let nums: Option<Vec<f64>> = s.split(',').map(|p| p.trim().parse().ok()).collect();
    match nums.as_deref() {
        Some(&[a, b]) if a.is_finite() && b.is_finite() => Some((a, b)),
        _ => None,
    }
}

/// Where the tag's centre sits on the robot, metres ahead of and to the left of the midpoint
/// of its wheel axle.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct TagOffset {
    /// Ahead of the axle midpoint, metres (negative: behind).
    pub ahead_m: f64,
    /// To the left of it, metres (negative: to the right).
    pub left_m: f64,
}

impl std::str::FromStr for TagOffset {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match finite_pair(s) {
            Some((ahead_m, left_m)) => Ok(Self { ahead_m, left_m }),
            None => Err(
                "give the tag's centre as AHEAD,LEFT in metres from the midpoint of the wheel axle (0.12,0 for 12 cm ahead; -0.05,0.02 for 5 cm behind and 2 cm to the left)"
                    .into(),
            ),
        }
    }
}

impl std::fmt::Display for TagOffset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{}", self.ahead_m, self.left_m)
    }
}

/// How the tag's plate leans on the robot: the degrees by which it falls toward the tag's x
/// axis (its heading) and toward its y axis.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct TagTiltDeg {
    /// Fall toward the tag's x axis, degrees (positive: the edge its heading points to is
    /// lower).
    pub x_deg: f64,
    /// Fall toward the tag's y axis, degrees (positive: its left edge is lower).
    pub y_deg: f64,
}

impl std::str::FromStr for TagTiltDeg {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match finite_pair(s) {
            Some((x_deg, y_deg)) => Ok(Self { x_deg, y_deg }),
            None => Err(
                "give the tag's tilt on the robot as X,Y: the degrees its plate falls toward the tag's x axis (its heading) and toward its y axis (-1.5,0 for a plate whose back edge is 1.5° lower), as `track` prints it"
                    .into(),
            ),
        }
    }
}

impl std::fmt::Display for TagTiltDeg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{}", self.x_deg, self.y_deg)
    }
}

/// The tag's options on the command line.
#[derive(clap::Args, Clone, Debug)]
pub struct TagArgs {
    /// Id of the robot's tag.
    #[arg(long, default_value_t = 0)]
    pub tag_id: u32,
    /// Tag family.
    #[arg(long, default_value = "tag36h11")]
    pub family: String,
    /// Side of the tag's black square, metres.
    #[arg(long, default_value_t = 0.08)]
    pub tag_size: f64,
    /// Height of the marker above the floor, metres.
    #[arg(long, default_value_t = 0.08)]
    pub marker_height: f64,
    /// Rolling-shutter readout time, seconds: from reading the first row of a frame to reading
    /// its last (0 for a global shutter; typically 0.01–0.04 s; negative for rows read from the
    /// bottom of the image up, as by a sensor mounted upside down whose image is turned after
    /// readout). Each fix is then timed at the rows where the tag was read: t = frame time +
    /// tag centre row / rows × readout (rows counted from the bottom when negative).
    #[arg(long, default_value_t = 0.0)]
    pub rolling_shutter_s: f64,
    /// Where the tag's centre sits on the robot: AHEAD,LEFT in metres from the midpoint of the
    /// wheel axle (the point the wheel odometry follows). The trajectory is then the axle
    /// midpoint's; `track` warns when a tag off the axle is not given.
    #[arg(
        long,
        default_value = "0,0",
        allow_hyphen_values = true,
        value_name = "AHEAD,LEFT"
    )]
    pub tag_offset: TagOffset,
    /// Angle from the robot's front to the tag's x axis, degrees counter-clockwise (90: the
    /// tag's x axis points to the robot's left). The trajectory's heading is then the robot's.
    #[arg(long, default_value_t = 0.0, value_name = "DEG")]
    pub tag_yaw: f64,
    /// How the tag's plate leans on the robot: X,Y, the degrees it falls toward the tag's x axis
    /// (its heading) and toward its y axis. Each corner's ray is then met at the corner's own
    /// height; `track` warns with the figure when a tilt that turns the headings is not given.
    #[arg(
        long,
        default_value = "0,0",
        allow_hyphen_values = true,
        value_name = "X,Y"
    )]
    pub tag_tilt: TagTiltDeg,
    /// Read the whole video even when the tag's id is in none of its first 90 frames while
    /// another tag is in nearly all of them (a wrong --tag-id, reported then by default): for
    /// a robot whose tag comes into view only later.
    #[arg(long)]
    pub whole_video: bool,
}

/// The tag's options alone, for their defaults.
#[derive(clap::Parser)]
struct TagOnly {
    #[command(flatten)]
    tag: TagArgs,
}

impl TagArgs {
    /// The options given other than at their defaults, as `--name value`.
    pub fn given(&self) -> Vec<String> {
        use clap::Parser;
        let d = TagOnly::parse_from(["odocal"]).tag;
        let mut out = Vec::new();
        if self.tag_id != d.tag_id {
            out.push(format!("--tag-id {}", self.tag_id));
        }
        if self.family != d.family {
            out.push(format!("--family {}", self.family));
        }
        if self.tag_offset != d.tag_offset {
            out.push(format!("--tag-offset {}", self.tag_offset));
        }
        if self.tag_tilt != d.tag_tilt {
            out.push(format!("--tag-tilt {}", self.tag_tilt));
        }
        for (name, v, dv) in [
            ("--tag-yaw", self.tag_yaw, d.tag_yaw),
            ("--tag-size", self.tag_size, d.tag_size),
            ("--marker-height", self.marker_height, d.marker_height),
            (
                "--rolling-shutter-s",
                self.rolling_shutter_s,
                d.rolling_shutter_s,
            ),
        ] {
            if v != dv {
                out.push(format!("{name} {v}"));
            }
        }
        out
    }

    /// `opts` with this tag and readout; a --tag-yaw that is no angle is refused here, as
    /// the mount wraps it.
    pub fn apply(&self, opts: TrackOptions) -> Result<TrackOptions, TagYawError> {
        Ok(TrackOptions {
            family: self.family.clone(),
            tag_id: self.tag_id,
            tag_size_m: self.tag_size,
            marker_height_m: self.marker_height,
            rolling_shutter_s: self.rolling_shutter_s,
            tag_to_robot: TagToRobot::from_degrees(
                self.tag_offset.ahead_m,
                self.tag_offset.left_m,
                self.tag_yaw,
            )?,
            tag_tilt_rad: nalgebra::Vector2::new(
                self.tag_tilt.x_deg.to_radians(),
                self.tag_tilt.y_deg.to_radians(),
            ),
            wrong_id_after_frames: match self.whole_video {
                true => None,
                false => opts.wrong_id_after_frames,
            },
            ..opts
        })
    }
}
