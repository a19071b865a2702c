//! `odocal calibrate`: Zhang calibration from checkerboard or ChArUco images with a chosen
//! or automatically selected lens model, plus the floor plane from boards lying on the floor.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use odocal_calib::export::{opencv_yaml, ros_yaml};
use odocal_calib::{calibrate_session, summary, ModelChoice};

use super::board::TargetArgs;
use crate::output::{check_output_file, commit, progress, write_atomic, write_json};

/// Arguments of `odocal calibrate`.
#[derive(ClapArgs)]
pub struct Args {
    /// Board images (PNG/JPEG), ideally 15-25 views covering the image.
    images: Vec<PathBuf>,
    /// Board size, COLSxROWS: a checkerboard's INNER corners (a board of 10x7 squares has 9x6
    /// inner corners; default 9x6), a ChArUco board's squares (e.g. 11x8).
    #[arg(long)]
    board: Option<String>,
    /// Side of one square, metres (measure the printed board).
    #[arg(long)]
    square: f64,
    #[command(flatten)]
    target: TargetArgs,
    /// Images of the board lying flat on the floor; the first fixes the floor frame. The floor
    /// board is taken to be the --board/--square board unless --floor-square gives its own.
    #[arg(long, num_args = 1..)]
    floor: Vec<PathBuf>,
    /// Side of one square of the floor board, metres, when it is another (e.g. larger) print
    /// of the --board layout than the hand-held one: one flat board cannot tell its own scale,
    /// so a wrong side scales the camera's height and every floor distance. Default --square.
    #[arg(long)]
    floor_square: Option<f64>,
    /// Lens model: pinhole5 (OpenCV's k1 k2 p1 p2 k3), rational (wide lenses to ~120°),
    /// fisheye (Kannala–Brandt, to ~180°), or auto: fit each and keep the one that best
    /// predicts views left out of its calibration (the comparison is printed).
    #[arg(long, default_value = "auto")]
    model: String,
    /// Where to write camera.json.
    #[arg(long)]
    out: PathBuf,
    /// Also write an OpenCV FileStorage YAML file.
    #[arg(long)]
    yaml_opencv: Option<PathBuf>,
    /// Also write a ROS camera_info YAML file.
    #[arg(long)]
    yaml_ros: Option<PathBuf>,
}

/// Runs `odocal calibrate`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let board = a
        .target
        .board_spec(a.board.as_deref(), a.square, "9x6", None)?;
    let choice = ModelChoice::parse(&a.model)?;
    check_output_file(&a.out, "--out")?;
    if a.floor_square.is_some() && a.floor.is_empty() {
        anyhow::bail!("--floor-square is the side of the floor board's squares: give the floor views with --floor, or leave --floor-square out");
    }
    for (p, opt) in [
        (&a.yaml_opencv, "--yaml-opencv"),
        (&a.yaml_ros, "--yaml-ros"),
    ] {
        if let Some(p) = p {
            check_output_file(p, opt)?;
        }
    }
    let model_steps = if choice == ModelChoice::Auto { 3 } else { 1 };
    let bar = progress(
        (a.images.len() + a.floor.len() + model_steps) as u64,
        "calibrating",
    );
    let session = calibrate_session(&a.images, &a.floor, &board, a.floor_square, choice, &|| {
        bar.inc(1)
    });
    bar.finish_and_clear();
    let session = session?;
    for note in &session.notes {
        tell!("{note}");
    }
    let file = &session.file;
    write_json(&a.out, file)?;
    if let Some(p) = &a.yaml_opencv {
        write_atomic(p, opencv_yaml(file)?.as_bytes())?;
    }
    if let Some(p) = &a.yaml_ros {
        write_atomic(p, ros_yaml(file, "odocal_ceiling").as_bytes())?;
    }
    for line in summary(file) {
        say!("{line}");
    }
    commit()?;
    let mut wrote = vec![a.out.display().to_string()];
    if let Some(p) = &a.yaml_opencv {
        wrote.push(format!("{} (OpenCV)", p.display()));
    }
    if let Some(p) = &a.yaml_ros {
        wrote.push(format!("{} (ROS camera_info)", p.display()));
    }
    say!("wrote {}", wrote.join(", "));
    Ok(())
}
