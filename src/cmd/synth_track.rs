//! `odocal synth track`: a ceiling video of a robot carrying an AprilTag, with
//! the true camera.json and the true trajectory.

use std::path::PathBuf;

use odocal_synth::scene::{
    AutoExposure, CameraEffects, Flicker, PaperTag, VideoFormat, REALISTIC_BLUR_STEP_PX,
    REALISTIC_EXPOSURE_S,
};
use odocal_synth::track_scene::{write_track_scene, TrackScene};

use crate::output::{commit, count, progress, synth_out_dir};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Random seed (floor texture, path phases, sensor noise): same seed, same bytes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of frames.
    #[arg(long, default_value_t = 300)]
    pub frames: usize,
    /// Container: avi (MJPG), mp4 (H.264) or png (frames/ + timestamps.csv) [default: avi;
    /// mp4 with --realistic].
    #[arg(long)]
    pub video: Option<String>,
    /// Frame rate, frames/s.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Slowest robot speed, m/s.
    #[arg(long, default_value_t = 0.2)]
    pub speed_min: f64,
    /// Fastest robot speed, m/s.
    #[arg(long, default_value_t = 0.7)]
    pub speed_max: f64,
    /// Sensor noise σ, grey levels.
    #[arg(long, default_value_t = 2.0)]
    pub noise: f32,
    /// Id of the robot's tag36h11 marker.
    #[arg(long, default_value_t = 0)]
    pub tag_id: u32,
    /// Where the tag's centre sits on the robot: AHEAD,LEFT in metres from the midpoint of the
    /// wheel axle. The truth is the axle midpoint's pose, as the wheel odometry's is.
    #[arg(
        long,
        default_value = "0,0",
        allow_hyphen_values = true,
        value_name = "AHEAD,LEFT"
    )]
    pub tag_offset: super::tag::TagOffset,
    /// Angle from the robot's front to the tag's x axis, degrees counter-clockwise.
    #[arg(long, default_value_t = 0.0, value_name = "DEG")]
    pub tag_yaw: f64,
    /// Tilt of the tag plate on the robot, degrees: its front edge (the tag's +x side) raised,
    /// as a tag glued a little off flat (the tracker takes the tag as level).
    #[arg(
        long,
        default_value_t = 0.0,
        value_name = "DEG",
        allow_hyphen_values = true
    )]
    pub tag_tilt: f64,
    /// Also write mocap.csv: the robot's true pose as a motion-capture system at this rate
    /// (Hz) records it, its samples falling between the camera's frames. `track --truth
    /// mocap.csv` judges each fix by the truth interpolated at its time.
    #[arg(long)]
    pub mocap_hz: Option<f64>,
    /// A realistic camera.
    #[command(flatten)]
    pub camera: CameraArgs,
}

/// A realistic camera: options shared by `synth track` and `synth experiment`. All are off
/// unless given; `--realistic` turns every one on at a plausible value (each option given
/// beside it overrides the preset's value).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct CameraArgs {
    /// Exposure time, milliseconds: the scene is integrated over it (motion blur) [default: 4;
    /// 16 with --realistic]. Given explicitly, or with any camera option, the exposure is
    /// sampled finely enough (two samples per pixel of the tag's motion) for a smooth blur.
    #[arg(long)]
    pub exposure_ms: Option<f64>,
    /// Rolling shutter: readout time of a whole frame, milliseconds (row v is exposed
    /// v / height of it after row 0, whose exposure is centred on the frame's timestamp).
    #[arg(long)]
    pub rolling_shutter_ms: Option<f64>,
    /// Light flicker frequency, Hz (100 for 50 Hz mains, 120 for 60 Hz) [depth 0.3 if
    /// --flicker-depth is not given].
    #[arg(long)]
    pub flicker_hz: Option<f64>,
    /// Light flicker depth: relative amplitude of the intensity (0.3 = ±30 %) [at 100 Hz if
    /// --flicker-hz is not given].
    #[arg(long)]
    pub flicker_depth: Option<f64>,
    /// Auto-exposure drift: standard deviation of the camera's log gain (0.05 ≈ ±5 %).
    #[arg(long)]
    pub auto_exposure: Option<f64>,
    /// Vignetting: relative fall-off of the light at the image corners (0.3: corners at 70 %).
    #[arg(long)]
    pub vignetting: Option<f64>,
    /// Uneven light: the gain changes across the image from 1 − g to 1 + g.
    #[arg(long)]
    pub gradient: Option<f64>,
    /// The camera's tone curve: each pixel is written as 255 · (linear / 255)^(1 / G), as
    /// cameras encode their output for display (2.2 is about sRGB's; 1 keeps it linear).
    #[arg(long, value_name = "G")]
    pub tone_gamma: Option<f64>,
    /// The tag is printed on paper: print contrast --paper-contrast, a soft specular
    /// highlight of the room's lamp of --paper-gloss.
    #[arg(long)]
    pub paper_tag: bool,
    /// Print contrast (white − black) / white of the paper tag [default: 0.7].
    #[arg(long)]
    pub paper_contrast: Option<f64>,
    /// Peak of the paper's highlight, fraction of full scale [default: 0.15].
    #[arg(long)]
    pub paper_gloss: Option<f64>,
    /// A person walks through and hides the tag for about this long, seconds.
    #[arg(long)]
    pub occlusion_s: Option<f64>,
    /// Fraction of frames the camera drops (missing from the file, the others keeping their
    /// true timestamps; needs FFmpeg's command-line program for avi and mp4).
    #[arg(long)]
    pub drop_rate: Option<f64>,
    /// H.264 bitrate, kbit/s, for --video mp4, encoded by FFmpeg's libx264 as a USB or IP
    /// camera records (4000 is typical at 1280x720).
    #[arg(long)]
    pub bitrate_kbps: Option<f64>,
    /// Every effect on at a plausible value ("all conditions combined"): 16 ms exposure,
    /// 30 ms rolling shutter, 100 Hz flicker of depth 0.4, auto-exposure 0.05, vignetting
    /// 0.3, gradient 0.3, paper tag (0.7, 0.15), a 1 s occlusion, 1 % dropped frames, H.264
    /// at 4000 kbit/s.
    #[arg(long)]
    pub realistic: bool,
}

/// Exposure of the default scene, milliseconds.
const DEFAULT_EXPOSURE_MS: f64 = 4.0;

impl CameraArgs {
    /// The exposure (seconds) and the camera's effects these options ask for, for a video
    /// written as `format` (the preset's H.264 bitrate applies to MP4 only).
    pub fn effects(&self, format: VideoFormat) -> (f64, CameraEffects) {
        let preset = if self.realistic {
            CameraEffects::realistic()
        } else {
            CameraEffects::default()
        };
        let exposure_ms = self.exposure_ms.unwrap_or(if self.realistic {
            REALISTIC_EXPOSURE_S * 1000.0
        } else {
            DEFAULT_EXPOSURE_MS
        });
        let flicker = match (self.flicker_hz, self.flicker_depth) {
            (None, None) => preset.flicker,
            (hz, depth) => Flicker {
                frequency_hz: hz.unwrap_or(preset.flicker.frequency_hz),
                depth: depth.unwrap_or(if preset.flicker.depth > 0.0 {
                    preset.flicker.depth
                } else {
                    0.3
                }),
            },
        };
        let paper = if self.paper_tag
            || self.paper_contrast.is_some()
            || self.paper_gloss.is_some()
            || preset.paper.is_some()
        {
            let base = preset.paper.unwrap_or(PaperTag {
                contrast: 0.7,
                gloss: 0.15,
            });
            Some(PaperTag {
                contrast: self.paper_contrast.unwrap_or(base.contrast),
                gloss: self.paper_gloss.unwrap_or(base.gloss),
            })
        } else {
            None
        };
        let mut e = CameraEffects {
            blur_step_px: None,
            rolling_shutter_s: self
                .rolling_shutter_ms
                .map_or(preset.rolling_shutter_s, |ms| ms / 1000.0),
            flicker,
            auto_exposure: AutoExposure {
                sigma: self.auto_exposure.unwrap_or(preset.auto_exposure.sigma),
                period_s: preset.auto_exposure.period_s,
            },
            vignetting: self.vignetting.unwrap_or(preset.vignetting),
            gradient: self.gradient.unwrap_or(preset.gradient),
            paper,
            occlusion_s: self.occlusion_s.unwrap_or(preset.occlusion_s),
            drop_rate: self.drop_rate.unwrap_or(preset.drop_rate),
            tone_gamma: self.tone_gamma.unwrap_or(preset.tone_gamma),
            h264_bitrate_kbps: self.bitrate_kbps.or(if format == VideoFormat::Mp4 {
                preset.h264_bitrate_kbps
            } else {
                None
            }),
        };
        // Today's videos keep their fixed five exposure samples; a camera asked for samples
        // its blur smoothly.
        if e != CameraEffects::default() || self.exposure_ms.is_some() {
            e.blur_step_px = Some(REALISTIC_BLUR_STEP_PX);
        }
        (exposure_ms / 1000.0, e)
    }

    /// The container: `video` if given, else MP4 for a camera that records H.264, else AVI.
    pub fn format(&self, video: Option<&str>) -> anyhow::Result<VideoFormat> {
        match video {
            Some(v) => Ok(v.parse()?),
            None if self.realistic || self.bitrate_kbps.is_some() => Ok(VideoFormat::Mp4),
            None => Ok(VideoFormat::Avi),
        }
    }
}

/// The fastest frame rate OpenCV's AVI writer keeps: above it, it writes 600 fps timestamps
/// that repeat, and FFmpeg drops the frames on them.
const MAX_AVI_FPS: f64 = 1000.0;

/// Refuses a frame rate `track` does not read (0.1 to 10000 frames/s), a recording longer
/// than the hour `--frames` allows at 30 frames/s (0.0001 fps asked for 47 GB of path), and
/// an AVI faster than its writer times (1001 fps wrote 600 fps frames, some lost).
fn check_fps(fps: f64, frames: usize, format: VideoFormat) -> anyhow::Result<()> {
    use odocal_tracker::source::{MAX_FPS, MIN_FPS};
    if !(MIN_FPS..=MAX_FPS).contains(&fps) {
        anyhow::bail!(
            "--fps {fps}: a camera's frame rate is {MIN_FPS} to {MAX_FPS} frames/s (what `odocal track` reads)"
        );
    }
    let hour_s = MAX_FRAMES as f64 / 30.0;
    let duration_s = frames.saturating_sub(1) as f64 / fps;
    if duration_s > hour_s {
        anyhow::bail!(
            "--fps {fps} --frames {frames}: {duration_s:.0} s of video, more than an hour; give fewer frames (at most {} at {fps} fps) or a higher rate",
            (hour_s * fps).floor() as usize + 1
        );
    }
    if format == VideoFormat::Avi && fps > MAX_AVI_FPS {
        anyhow::bail!(
            "--fps {fps} --video avi: the AVI writer times frames at most {MAX_AVI_FPS} fps (faster, it writes 600 fps timestamps and loses frames); use --video mp4 or --video png, which hold up to {MAX_FPS} fps"
        );
    }
    Ok(())
}

/// Runs the subcommand.
/// Frames `synth track` and `synth arena` render at most: an hour at 30 frames/s.
pub(crate) const MAX_FRAMES: usize = 108_000;

pub fn run(args: Args) -> anyhow::Result<()> {
    super::synth_count_at_most(
        args.frames,
        "--frames",
        MAX_FRAMES,
        "an hour at 30 frames/s",
    )?;
    let format = args.camera.format(args.video.as_deref())?;
    check_fps(args.fps, args.frames, format)?;
    let (mut exposure_s, effects) = args.camera.effects(format);
    // The default exposure (4 ms, 16 with --realistic) is longer than a frame at 250 fps
    // (62.5 with --realistic): left to its default, it takes half the frame period there.
    if args.camera.exposure_ms.is_none() && exposure_s >= 0.5 / args.fps {
        exposure_s = 0.5 / args.fps;
    }
    let scene = TrackScene {
        seed: args.seed,
        frames: args.frames,
        format,
        fps: args.fps,
        speed_min_mps: args.speed_min,
        speed_max_mps: args.speed_max,
        noise_sigma: args.noise,
        exposure_s,
        tag_id: args.tag_id,
        tag_to_robot: odocal_core::TagToRobot::from_degrees(
            args.tag_offset.ahead_m,
            args.tag_offset.left_m,
            args.tag_yaw,
        )?,
        tag_tilt_deg: args.tag_tilt,
        effects,
        mocap_hz: args.mocap_hz,
    };
    scene.check()?;
    let dir = synth_out_dir(&args.out, "--out")?;
    let bar = progress(args.frames as u64, "rendering");
    let written = write_track_scene(&dir, &scene, &|_| bar.inc(1));
    bar.finish_and_clear();
    let written = written?;
    commit()?;
    // Dropped frames are not in the video: its frame count is what a reader finds.
    let frames = match written.dropped {
        0 => count(written.frames, "frame"),
        d => format!(
            "{} of the {} frames rendered ({} dropped as a camera drops them)",
            written.frames - d,
            written.frames,
            d
        ),
    };
    say!(
        "wrote {frames} ({}x{}, {} fps) to {}, the true camera.json, truth.csv and frames.csv{}",
        written.size_px.0,
        written.size_px.1,
        args.fps,
        args.out.join(&written.video).display(),
        args.mocap_hz
            .map(|hz| format!(", and mocap.csv (the truth at {hz} Hz)"))
            .unwrap_or_default()
    );
    Ok(())
}
