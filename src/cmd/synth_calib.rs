//! `odocal synth calib`: checkerboard and floor views from a known camera.

use std::path::{Path, PathBuf};

use clap::Args as ClapArgs;
use odocal_calib::{BoardSpec, CameraFile};
use odocal_synth::board::{calibration_errors, CalibScene, CalibTruth};
use odocal_synth::calib_set::{self, check_scene};

use crate::output::{progress, staged_dir};

/// Arguments of `odocal synth calib`.
#[derive(ClapArgs)]
pub struct Args {
    /// Output folder (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Number of hand-held checkerboard views.
    #[arg(long, default_value_t = 20)]
    views: usize,
    /// Number of views of the board lying on the floor.
    #[arg(long, default_value_t = 4)]
    floor_views: usize,
    /// Random seed (same seed, same bytes).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Image width, pixels.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Horizontal field of view, degrees.
    #[arg(long, default_value_t = 70.0)]
    hfov: f64,
    /// Sensor noise σ, grey levels.
    #[arg(long, default_value_t = 2.0)]
    noise: f32,
    /// Optical blur σ, pixels.
    #[arg(long, default_value_t = 0.5)]
    blur: f32,
    /// Board inner corners, COLSxROWS.
    #[arg(long, default_value = "9x6")]
    board: String,
    /// Board square size, metres.
    #[arg(long, default_value_t = 0.05)]
    square: f64,
}

/// Renders a calibration session into `out` (staged: it appears when the command succeeds).
pub fn write_calib_set(out: &Path, scene: &CalibScene, seed: u64) -> anyhow::Result<CalibTruth> {
    check_scene(scene)?;
    let dir = staged_dir(out, "--out")?;
    let bar = progress((scene.views + scene.floor_views) as u64, "rendering");
    let truth = calib_set::write_calib_set(&dir, scene, seed, &|| bar.inc(1));
    bar.finish_and_clear();
    Ok(truth?)
}

/// Runs `odocal synth calib`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let scene = CalibScene {
        width: a.width,
        height: a.height,
        hfov_deg: a.hfov,
        board: BoardSpec::parse(&a.board, a.square)?,
        views: a.views,
        floor_views: a.floor_views,
        noise_sigma: a.noise,
        blur_px: a.blur,
        ..CalibScene::default()
    };
    let truth = write_calib_set(&a.out, &scene, a.seed)?;
    let k = truth.camera.intrinsics;
    println!(
        "wrote {} board views and {} floor views ({}x{}, board {}x{} inner corners, {} m squares) to {}",
        truth.views.len(),
        truth.floor_views.len(),
        a.width,
        a.height,
        scene.board.cols,
        scene.board.rows,
        scene.board.square_m,
        a.out.display()
    );
    println!(
        "true camera: fx {:.2} px, fy {:.2} px, cx {:.2} px, cy {:.2} px (truth.json, camera_true.json)",
        k.fx, k.fy, k.cx, k.cy
    );
    Ok(())
}

/// Arguments of `odocal synth check-calib`.
#[derive(ClapArgs)]
pub struct CheckArgs {
    /// camera.json written by `odocal calibrate`.
    #[arg(long)]
    camera: PathBuf,
    /// truth.json written by `odocal synth calib`.
    #[arg(long)]
    truth: PathBuf,
}

/// Runs `odocal synth check-calib`: the calibration's error against the truth.
pub fn run_check(a: CheckArgs) -> anyhow::Result<()> {
    let cam = CameraFile::load(&a.camera)?;
    let truth = CalibTruth::read(&a.truth)?;
    let e = calibration_errors(
        &cam.camera,
        cam.floor.as_ref().map(|f| &f.floor_to_camera),
        &truth.camera,
        &truth.floor_to_camera,
    );
    println!(
        "calibration error against the truth: fx {:.3} %, fy {:.3} %, cx {:.2} px, cy {:.2} px (bounds 0.2 %, 0.2 %, 1 px, 1 px)",
        e.fx_rel * 100.0,
        e.fy_rel * 100.0,
        e.cx_px,
        e.cy_px
    );
    match (e.floor_max_m, e.floor_rms_m) {
        (Some(max), Some(rms)) => println!(
            "floor mapping error over the central 2.5 m x 1.5 m: {:.2} mm RMS, {:.2} mm max (bound 2 mm)",
            rms * 1e3,
            max * 1e3
        ),
        _ => println!("no floor plane in {}", a.camera.display()),
    }
    Ok(())
}
