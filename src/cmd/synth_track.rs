//! `odocal synth track`: a ceiling video of a robot carrying an AprilTag, with
//! the true camera.json and the true trajectory.

use std::path::PathBuf;

use anyhow::Context;
use odocal_calib::{CameraFile, FloorPlane};
use odocal_synth::scene::{
    demo_trajectory, nadir, render_video_with_progress, truth_csv, SceneConfig, VideoFormat,
};

use crate::output::{progress, write_atomic, write_json};

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

#[derive(serde::Serialize)]
struct SceneInfo {
    format: &'static str,
    seed: u64,
    fps: f64,
    frames: usize,
    video: String,
    tag_family: &'static str,
    tag_id: u32,
    tag_size_m: f64,
    marker_height_m: f64,
    exposure_s: f64,
    noise_sigma: f32,
    speed_min_mps: f64,
    speed_max_mps: f64,
    /// Frames in which the whole tag is not inside the image.
    tag_not_fully_visible: Vec<usize>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let format: VideoFormat = args.video.parse()?;
    if args.frames == 0 {
        anyhow::bail!("--frames must be at least 1");
    }
    if !(args.fps > 0.0 && args.fps.is_finite()) {
        anyhow::bail!(
            "--fps {}: must be a positive number of frames per second",
            args.fps
        );
    }
    if !(0.0 < args.speed_min && args.speed_min <= args.speed_max && args.speed_max < 5.0) {
        anyhow::bail!(
            "--speed-min {} --speed-max {}: need 0 < min ≤ max < 5 m/s",
            args.speed_min,
            args.speed_max
        );
    }
    if !(args.exposure_ms >= 0.0 && args.exposure_ms < 1000.0 / args.fps) {
        anyhow::bail!(
            "--exposure-ms {}: must be between 0 and the frame period",
            args.exposure_ms
        );
    }
    let mut cfg = SceneConfig::default();
    cfg.robot.tag_id = args.tag_id;
    cfg.exposure_s = args.exposure_ms / 1000.0;
    cfg.sensor.noise_sigma = args.noise;
    let duration = (args.frames - 1) as f64 / args.fps;
    let traj = demo_trajectory(
        nadir(&cfg.floor),
        duration + 0.01,
        args.speed_min,
        args.speed_max,
        args.seed,
    );
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let (name, tmp_name) = match format {
        VideoFormat::Avi => ("video.avi", format!(".video.tmp{}.avi", std::process::id())),
        VideoFormat::Mp4 => ("video.mp4", format!(".video.tmp{}.mp4", std::process::id())),
        VideoFormat::Png => ("frames", format!(".frames.tmp{}", std::process::id())),
    };
    let tmp = args.out.join(&tmp_name);
    let bar = progress(args.frames as u64, "rendering");
    let rendered =
        render_video_with_progress(&tmp, format, &cfg, &traj, args.fps, args.seed, &|_| {
            bar.inc(1)
        });
    bar.finish_and_clear();
    let truths = match rendered {
        Ok(t) => t,
        Err(e) => {
            let _ = if format == VideoFormat::Png {
                std::fs::remove_dir_all(&tmp)
            } else {
                std::fs::remove_file(&tmp)
            };
            return Err(e.into());
        }
    };
    let truths: Vec<_> = truths.into_iter().take(args.frames).collect();
    let dest = args.out.join(name);
    if format == VideoFormat::Png && dest.is_dir() {
        std::fs::remove_dir_all(&dest)
            .with_context(|| format!("cannot replace {}", dest.display()))?;
    }
    std::fs::rename(&tmp, &dest).with_context(|| format!("cannot write {}", dest.display()))?;
    let floor = FloorPlane {
        floor_to_camera: cfg.floor,
        plane_rms_m: 0.0,
        camera_height_m: cfg.floor.0.inverse().translation.vector.z,
        views: vec![],
    };
    write_json(
        &args.out.join("camera.json"),
        &CameraFile::from_model(cfg.camera, Some(floor)),
    )?;
    write_atomic(
        &args.out.join("truth.csv"),
        truth_csv(&truths, false).as_bytes(),
    )?;
    let hidden: Vec<usize> = truths
        .iter()
        .filter(|t| !t.tag_visible)
        .map(|t| t.index)
        .collect();
    write_json(
        &args.out.join("scene.json"),
        &SceneInfo {
            format: "odocal.synth-track/1",
            seed: args.seed,
            fps: args.fps,
            frames: truths.len(),
            video: name.into(),
            tag_family: "tag36h11",
            tag_id: args.tag_id,
            tag_size_m: cfg.robot.tag_size_m,
            marker_height_m: cfg.robot.marker_height_m,
            exposure_s: cfg.exposure_s,
            noise_sigma: args.noise,
            speed_min_mps: args.speed_min,
            speed_max_mps: args.speed_max,
            tag_not_fully_visible: hidden,
        },
    )?;
    println!(
        "wrote {} frames ({}x{}, {} fps) to {}, the true camera.json and truth.csv",
        truths.len(),
        cfg.camera.width,
        cfg.camera.height,
        args.fps,
        dest.display()
    );
    Ok(())
}
