//! `odocal synth track`: a ceiling video of a robot carrying an AprilTag, with
//! the true camera.json and the true trajectory.

use std::path::PathBuf;

use odocal_synth::track_scene::{write_track_scene, TrackScene};

use crate::output::{progress, staged_dir};

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
    /// Container: avi (MJPG), mp4 (H.264) or png (frames/ + timestamps.csv).
    #[arg(long, default_value = "avi")]
    pub video: String,
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
    /// Exposure time (motion blur), milliseconds.
    #[arg(long, default_value_t = 4.0)]
    pub exposure_ms: f64,
    /// Id of the robot's tag36h11 marker.
    #[arg(long, default_value_t = 0)]
    pub tag_id: u32,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let scene = TrackScene {
        seed: args.seed,
        frames: args.frames,
        format: args.video.parse()?,
        fps: args.fps,
        speed_min_mps: args.speed_min,
        speed_max_mps: args.speed_max,
        noise_sigma: args.noise,
        exposure_s: args.exposure_ms / 1000.0,
        tag_id: args.tag_id,
    };
    scene.check()?;
    let dir = staged_dir(&args.out, "--out")?;
    let bar = progress(args.frames as u64, "rendering");
    let written = write_track_scene(&dir, &scene, &|_| bar.inc(1));
    bar.finish_and_clear();
    let written = written?;
    println!(
        "wrote {} frames ({}x{}, {} fps) to {}, the true camera.json and truth.csv",
        written.frames,
        written.size_px.0,
        written.size_px.1,
        args.fps,
        args.out.join(&written.video).display()
    );
    Ok(())
}
