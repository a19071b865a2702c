//! The robot's tag and how the camera reads it: the options `track` and `dataset` (whose
//! manifest rows with a video are tracked) share, with the same names and defaults.

use odocal_tracker::TrackOptions;

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
    /// its last (0 for a global shutter; typically 0.01–0.04 s). Each fix is then timed at the
    /// rows where the tag was read: t = frame time + tag centre row / rows × readout.
    #[arg(long, default_value_t = 0.0)]
    pub rolling_shutter_s: f64,
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
        for (name, v, dv) in [
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

    /// `opts` with this tag and readout.
    pub fn apply(&self, opts: TrackOptions) -> TrackOptions {
        TrackOptions {
            family: self.family.clone(),
            tag_id: self.tag_id,
            tag_size_m: self.tag_size,
            marker_height_m: self.marker_height,
            rolling_shutter_s: self.rolling_shutter_s,
            ..opts
        }
    }
}
