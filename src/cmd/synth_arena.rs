//! `odocal synth arena`: a 6 × 4 m floor under four overlapping ceiling cameras, their
//! calibration and shared floor-board views, and two robots driving at once, with truth.

use std::path::PathBuf;

use odocal_calib::BoardSpec;
use odocal_synth::arena::{write_arena, ArenaScene};

use crate::output::{commit, progress, synth_out_dir};

/// Arguments of `odocal synth arena`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Random seed: same seed, same bytes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Image width of every camera, pixels.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Image height of every camera, pixels.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Horizontal field of view of the first camera, degrees (the others differ by 1-2°).
    #[arg(long, default_value_t = 90.0)]
    pub hfov: f64,
    /// Height of the cameras above the floor, metres.
    #[arg(long, default_value_t = 2.6)]
    pub camera_height: f64,
    /// Frames per video (190 at 30 fps is one full turn of both robots).
    #[arg(long, default_value_t = 190)]
    pub frames: usize,
    /// Frame rate of every camera, frames/s.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Sensor noise σ, grey levels.
    #[arg(long, default_value_t = 2.0)]
    pub noise: f32,
    /// Side of the robots' tags (black square), metres.
    #[arg(long, default_value_t = 0.16)]
    pub tag_size: f64,
    /// Hand-held calibration views per camera.
    #[arg(long, default_value_t = 14)]
    pub calib_views: usize,
    /// Side of the board's squares, metres (9x6 inner corners; calibration, floor and shared views).
    #[arg(long, default_value_t = 0.07)]
    pub square: f64,
}

/// Runs `odocal synth arena`.
pub fn run(args: Args) -> anyhow::Result<()> {
    super::synth_count_at_most(
        args.frames,
        "--frames",
        super::synth_track::MAX_FRAMES,
        "an hour at 30 frames/s",
    )?;
    super::synth_count_at_most(args.calib_views, "--calib-views", 500, "views per camera")?;
    let scene = ArenaScene {
        seed: args.seed,
        width: args.width,
        height: args.height,
        hfov_deg: args.hfov,
        camera_height_m: args.camera_height,
        fps: args.fps,
        frames: args.frames,
        noise_sigma: args.noise,
        tag_size_m: args.tag_size,
        calib_views: args.calib_views,
        board: BoardSpec::parse("9x6", args.square)?,
        ..ArenaScene::default()
    };
    scene.check()?;
    let dir = synth_out_dir(&args.out, "--out")?;
    let bar = progress(
        (4 * (args.calib_views + 8 + args.frames)) as u64,
        "rendering",
    );
    let written = write_arena(&dir, &scene, &|| bar.inc(1));
    bar.finish_and_clear();
    let written = written?;
    let t = &written.truth;
    for c in &t.cameras {
        let at = c.arena_to_camera.0.inverse().translation.vector;
        say!(
            "{}: {} calibration views, {} floor views, at ({:.2}, {:.2}) m, {:.2} m up; clock offset {:+.3} ms",
            c.name,
            c.views.len(),
            c.floor_views.len(),
            at.x,
            at.y,
            at.z,
            c.clock_offset_s * 1e3
        );
    }
    commit()?;
    say!(
        "wrote {} shared-view images of {} boards, {} video frames ({}x{}, {} fps) and the truth to {}",
        written.shared_images,
        t.shared.len(),
        written.frames,
        args.width,
        args.height,
        args.fps,
        args.out.display()
    );
    say!(
        "next: odocal calibrate {0}/cam0/view_*.png --floor {0}/cam0/floor_*.png --square {1} --out {0}/cam0/camera.json (each camera), then odocal arena --camera {0}/cam*/camera.json --shared {0}/shared --out {0}/arena.json",
        args.out.display(),
        args.square
    );
    Ok(())
}
