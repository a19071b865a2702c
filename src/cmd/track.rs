//! `odocal track`: the robot's floor trajectory from a ceiling-camera video.

use std::path::PathBuf;

use anyhow::Context;
use odocal_calib::CameraFile;
use odocal_tracker::{
    errors_against, open_source, overlay, track_report, track_source, SourceOptions, TrackOptions,
};

use crate::output::{progress, write_atomic, write_json};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Video file (MP4/H.264, MJPG AVI, anything FFmpeg reads) or a folder of PNG/JPEG frames.
    pub video: PathBuf,
    /// camera.json with the floor plane (from `odocal calibrate`).
    #[arg(long)]
    pub camera: PathBuf,
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
    /// Output trajectory CSV (`t,x,y,theta,quality`; frames without a confident fix are absent).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the trajectory in TUM format (for `evo`).
    #[arg(long)]
    pub tum: Option<PathBuf>,
    /// Write every frame with its detection drawn into this folder.
    #[arg(long)]
    pub overlay: Option<PathBuf>,
    /// Write a JSON report: per-frame quality, gaps with reasons, ids seen.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Frame rate, frames/s: overrides the video's own; for image folders without timestamps.
    #[arg(long)]
    pub fps: Option<f64>,
    /// CSV of image timestamps for an image folder (`file,t`, or `t` per image in name order).
    #[arg(long)]
    pub timestamps: Option<PathBuf>,
    /// Detect on the full frame in every frame (no region of interest).
    #[arg(long)]
    pub no_roi: bool,
    /// Fastest plausible robot speed, m/s: faster apparent motion is rejected as a jump.
    #[arg(long, default_value_t = 2.0)]
    pub max_speed: f64,
    /// Largest accepted corner reprojection RMS, pixels.
    #[arg(long, default_value_t = 1.5)]
    pub max_reprojection: f64,
    /// Run the solvePnP (IPPE_SQUARE) cross-check on every fix and report it.
    #[arg(long)]
    pub pnp_check: bool,
    /// A reference trajectory CSV (e.g. `synth track`'s truth.csv): print the
    /// position and heading RMS error against it (rows matched by timestamp).
    #[arg(long)]
    pub truth: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    // FFmpeg and OpenCV print their own complaints about bad files; ours are one line.
    for (var, level) in [
        ("OPENCV_FFMPEG_LOGLEVEL", "0"),
        ("OPENCV_LOG_LEVEL", "SILENT"),
    ] {
        if std::env::var_os(var).is_none() {
            std::env::set_var(var, level);
        }
    }
    let camera_file = CameraFile::load(&args.camera)?;
    let truth = match &args.truth {
        Some(path) => Some(odocal_tracker::Trajectory::read_csv(path)?),
        None => None,
    };
    let floor = *camera_file.require_floor(&args.camera)?;
    let source = open_source(
        &args.video,
        &SourceOptions {
            fps: args.fps,
            timestamps: args.timestamps.clone(),
        },
    )?;
    let opts = TrackOptions {
        family: args.family.clone(),
        tag_id: args.tag_id,
        tag_size_m: args.tag_size,
        marker_height_m: args.marker_height,
        use_roi: !args.no_roi,
        max_speed_mps: args.max_speed,
        max_reprojection_px: args.max_reprojection,
        pnp_cross_check: args.pnp_check,
        ..TrackOptions::default()
    };
    if let Some(dir) = &args.overlay {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create overlay folder {}", dir.display()))?;
    }
    let bar = progress(source.info().frame_count.unwrap_or(0) as u64, "tracking");
    let overlay_dir = args.overlay.clone();
    let result = track_source(
        source,
        &camera_file.camera,
        &floor,
        &opts,
        &mut |frame, rec| {
            bar.inc(1);
            match &overlay_dir {
                Some(dir) => overlay::write_overlay(dir, frame, rec),
                None => Ok(()),
            }
        },
    );
    bar.finish_and_clear();
    let result = result?;
    let trajectory = result.trajectory()?;
    let gaps = result.gaps();
    // All outputs are built before anything is written; each is written atomically.
    write_atomic(&args.out, trajectory.to_csv().as_bytes())?;
    if let Some(tum) = &args.tum {
        write_atomic(tum, trajectory.to_tum().as_bytes())?;
    }
    if let Some(path) = &args.report {
        write_json(
            path,
            &track_report(
                &args.video.display().to_string(),
                &args.camera.display().to_string(),
                &opts,
                &result,
            ),
        )?;
    }
    let longest = gaps
        .iter()
        .map(|g| g.last_index - g.first_index + 1)
        .max()
        .unwrap_or(0);
    eprintln!(
        "tracked tag {} in {}/{} frames ({} gaps, longest {} frames); {} → {}",
        args.tag_id,
        trajectory.rows.len(),
        result.records.len(),
        gaps.len(),
        longest,
        result.seen_ids_text(),
        args.out.display()
    );
    if let (Some(truth), Some(path)) = (&truth, &args.truth) {
        let (pos, head, n) = errors_against(&trajectory, truth);
        if n == 0 {
            anyhow::bail!(
                "{}: no row has the timestamp of a tracked frame",
                path.display()
            );
        }
        println!(
            "against {}: position RMS {:.3} mm, heading RMS {:.3} deg over {n} frames",
            path.display(),
            pos * 1e3,
            head.to_degrees()
        );
    }
    Ok(())
}
