//! `odocal track`: the robot's floor trajectory from a ceiling-camera video.

use std::path::PathBuf;

use anyhow::Context;
use odocal_calib::CameraFile;
use odocal_tracker::{
    open_source, overlay, track_source, Outcome, SourceOptions, TrackOptions, TrackResult,
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

/// Position RMS (m), heading RMS (rad) and matched rows of `est` against `truth`;
/// rows are matched by timestamp (within 0.1 ms).
fn errors_against(
    est: &odocal_tracker::Trajectory,
    truth: &odocal_tracker::Trajectory,
) -> (f64, f64, usize) {
    let (mut sp, mut sh, mut n) = (0.0, 0.0, 0usize);
    for r in &est.rows {
        let i = truth.rows.partition_point(|t| t.t_s < r.t_s - 1e-4);
        if let Some(t) = truth.rows.get(i).filter(|t| (t.t_s - r.t_s).abs() <= 1e-4) {
            sp += (r.pose.position() - t.pose.position()).norm_squared();
            sh += odocal_core::wrap_angle(r.pose.theta_rad - t.pose.theta_rad).powi(2);
            n += 1;
        }
    }
    let k = n.max(1) as f64;
    ((sp / k).sqrt(), (sh / k).sqrt(), n)
}

#[derive(serde::Serialize)]
struct FrameReport {
    index: usize,
    t: f64,
    fix: bool,
    reason: Option<&'static str>,
    reprojection_px: Option<f64>,
    decision_margin: Option<f32>,
    roi: Option<bool>,
    pnp_height_m: Option<f64>,
    pnp_heading_diff_deg: Option<f64>,
}

#[derive(serde::Serialize)]
struct GapReport {
    first_frame: usize,
    last_frame: usize,
    start_s: f64,
    end_s: f64,
    reasons: std::collections::BTreeMap<&'static str, usize>,
}

#[derive(serde::Serialize)]
struct Report {
    format: &'static str,
    video: String,
    camera: String,
    tag_id: u32,
    family: String,
    frames: usize,
    fixes: usize,
    median_reprojection_px: f64,
    ids_seen: std::collections::BTreeMap<u32, usize>,
    gaps: Vec<GapReport>,
    per_frame: Vec<FrameReport>,
}

fn report(args: &Args, r: &TrackResult) -> Report {
    let mut reproj: Vec<f64> = r.fixes().map(|(_, f)| f.reprojection_rms_px).collect();
    reproj.sort_by(f64::total_cmp);
    Report {
        format: "odocal.track-report/1",
        video: args.video.display().to_string(),
        camera: args.camera.display().to_string(),
        tag_id: args.tag_id,
        family: args.family.clone(),
        frames: r.records.len(),
        fixes: reproj.len(),
        median_reprojection_px: reproj.get(reproj.len() / 2).copied().unwrap_or(f64::NAN),
        ids_seen: r.seen_ids.clone(),
        gaps: r
            .gaps()
            .into_iter()
            .map(|g| GapReport {
                first_frame: g.first_index,
                last_frame: g.last_index,
                start_s: g.start_s,
                end_s: g.end_s,
                reasons: g.reasons,
            })
            .collect(),
        per_frame: r
            .records
            .iter()
            .map(|rec| match &rec.outcome {
                Outcome::Fix(f) => FrameReport {
                    index: rec.index,
                    t: rec.t_s,
                    fix: true,
                    reason: None,
                    reprojection_px: Some(f.reprojection_rms_px),
                    decision_margin: Some(f.decision_margin),
                    roi: Some(f.from_roi),
                    pnp_height_m: f.pnp.map(|p| p.height_m),
                    pnp_heading_diff_deg: f.pnp.map(|p| p.heading_diff_rad.to_degrees()),
                },
                Outcome::Gap(g) => FrameReport {
                    index: rec.index,
                    t: rec.t_s,
                    fix: false,
                    reason: Some(g.as_str()),
                    reprojection_px: None,
                    decision_margin: None,
                    roi: None,
                    pnp_height_m: None,
                    pnp_heading_diff_deg: None,
                },
            })
            .collect(),
    }
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
        write_json(path, &report(&args, &result))?;
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
