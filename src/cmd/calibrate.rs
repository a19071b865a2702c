//! `odocal calibrate`: Zhang calibration from checkerboard images, plus the
//! floor plane from boards lying on the floor.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args as ClapArgs;
use odocal_calib::detect::guess_board_size;
use odocal_calib::export::{write_opencv_yaml, write_ros_yaml};
use odocal_calib::{
    calibrate, detect_file, fit_floor, BoardSpec, BoardView, CameraFile, Detection, SkippedView,
    CAMERA_FORMAT,
};
use rayon::prelude::*;

use crate::cmd::synth_calib::parse_board;
use crate::output::{progress, write_json};

/// Arguments of `odocal calibrate`.
#[derive(ClapArgs)]
pub struct Args {
    /// Checkerboard images (PNG/JPEG), ideally 15-25 views covering the image.
    #[arg(required = true)]
    images: Vec<PathBuf>,
    /// Board size in INNER corners, COLSxROWS (a board of 10x7 squares has 9x6 inner corners).
    #[arg(long, default_value = "9x6")]
    board: String,
    /// Side of one square, metres (measure the printed board).
    #[arg(long)]
    square: f64,
    /// Images of the board lying flat on the floor; the first fixes the floor frame.
    #[arg(long, num_args = 1..)]
    floor: Vec<PathBuf>,
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

/// Detects the board in every image in parallel, with a progress bar.
fn detect_all(paths: &[PathBuf], board: &BoardSpec, what: &str) -> anyhow::Result<Vec<Detection>> {
    let bar = progress(paths.len() as u64, what);
    let found: Result<Vec<Detection>, _> = paths
        .par_iter()
        .map(|p| {
            let d = detect_file(p, board);
            bar.inc(1);
            d
        })
        .collect();
    bar.finish_and_clear();
    Ok(found?)
}

type Sizes = Vec<(String, (u32, u32))>;

fn split(
    detections: Vec<Detection>,
    board: &BoardSpec,
) -> (Vec<BoardView>, Vec<SkippedView>, Sizes) {
    let mut views = Vec::new();
    let mut skipped = Vec::new();
    let mut sizes = Vec::new();
    for d in detections {
        match d {
            Detection::Found(v) => {
                sizes.push((v.image.clone(), v.size));
                views.push(v);
            }
            Detection::NotFound { image, size } => {
                sizes.push((image.clone(), size));
                skipped.push(SkippedView {
                    image,
                    reason: format!("no {}x{} checkerboard found", board.cols, board.rows),
                });
            }
        }
    }
    (views, skipped, sizes)
}

fn check_sizes(sizes: &[(String, (u32, u32))]) -> anyhow::Result<()> {
    if let Some((first, s0)) = sizes.first() {
        if let Some((other, s)) = sizes.iter().find(|(_, s)| s != s0) {
            anyhow::bail!(
                "{other} is {}x{} but {first} is {}x{}: all images must come from one camera at one resolution",
                s.0,
                s.1,
                s0.0,
                s0.1
            );
        }
    }
    Ok(())
}

fn no_board_error(paths: &[PathBuf], board: &BoardSpec, what: &str) -> anyhow::Error {
    let hint = paths
        .iter()
        .take(3)
        .find_map(|p| guess_board_size(p, board))
        .map(|(c, r)| format!(" A {c}x{r} board was found instead: pass --board {c}x{r}."))
        .unwrap_or_default();
    anyhow::anyhow!(
        "no {}x{} checkerboard found in any of the {} {what} image(s): --board counts INNER corners \
         (a board of {}x{} squares has {}x{} inner corners).{hint}",
        board.cols,
        board.rows,
        paths.len(),
        board.cols + 1,
        board.rows + 1,
        board.cols,
        board.rows
    )
}

/// Runs `odocal calibrate`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let board = parse_board(&a.board, a.square)?;
    let detections = detect_all(&a.images, &board, "detecting")?;
    let (views, skipped, sizes) = split(detections, &board);
    check_sizes(&sizes)?;
    for s in &skipped {
        eprintln!("skipped {}: {}", s.image, s.reason);
    }
    if views.is_empty() {
        return Err(no_board_error(&a.images, &board, "calibration"));
    }
    let cal = calibrate(&views, &board)?;

    let floor = if a.floor.is_empty() {
        None
    } else {
        let fd = detect_all(&a.floor, &board, "floor views")?;
        let (fviews, fskipped, fsizes) = split(fd, &board);
        check_sizes(&[sizes[..1].to_vec(), fsizes].concat())?;
        for s in &fskipped {
            eprintln!("skipped floor view {}: {}", s.image, s.reason);
        }
        if fviews.is_empty() {
            return Err(no_board_error(&a.floor, &board, "floor"));
        }
        Some(fit_floor(&cal.camera, &fviews, &board)?)
    };

    let file = CameraFile {
        format: CAMERA_FORMAT.into(),
        camera: cal.camera,
        rms_px: cal.rms_px,
        std: Some(cal.std),
        views: cal.views.clone(),
        skipped,
        board: Some(board),
        floor,
    };
    write_json(&a.out, &file)?;
    if let Some(p) = &a.yaml_opencv {
        write_opencv_yaml(&file, p).with_context(|| format!("writing {}", p.display()))?;
    }
    if let Some(p) = &a.yaml_ros {
        write_ros_yaml(&file, p, "odocal_ceiling")
            .with_context(|| format!("writing {}", p.display()))?;
    }
    print_summary(&file, &a.out);
    Ok(())
}

/// Prints the calibration: every number with its unit and uncertainty.
pub fn print_summary(f: &CameraFile, out: &Path) {
    let k = f.camera.intrinsics;
    let d = f.camera.distortion.to_opencv();
    println!(
        "calibration of a {}x{} camera from {} views ({} skipped); RMS reprojection error {:.3} px",
        f.camera.width,
        f.camera.height,
        f.views.len(),
        f.skipped.len(),
        f.rms_px
    );
    let sd = f.std;
    let s = |v: Option<f64>| v.map(|x| format!("± {x:.3}")).unwrap_or_default();
    println!("  fx = {:10.3} px {}", k.fx, s(sd.map(|x| x.fx)));
    println!("  fy = {:10.3} px {}", k.fy, s(sd.map(|x| x.fy)));
    println!("  cx = {:10.3} px {}", k.cx, s(sd.map(|x| x.cx)));
    println!("  cy = {:10.3} px {}", k.cy, s(sd.map(|x| x.cy)));
    for (i, name) in ["k1", "k2", "p1", "p2", "k3"].iter().enumerate() {
        let e = sd
            .map(|x| format!("± {:.5}", x.distortion[i]))
            .unwrap_or_default();
        println!("  {name} = {:10.5}    {e}", d[i]);
    }
    println!("  (± is one standard deviation from OpenCV's covariance at the optimum)");
    let mut worst = f.views.clone();
    worst.sort_by(|a, b| b.rms_px.total_cmp(&a.rms_px));
    let list: Vec<String> = worst
        .iter()
        .take(3)
        .map(|v| format!("{} {:.3} px", short(&v.image), v.rms_px))
        .collect();
    println!("  worst views (RMS reprojection): {}", list.join(", "));
    if let Some(fl) = &f.floor {
        println!(
            "floor plane from {} view(s): corners within {:.2} mm RMS of the plane; camera {:.4} m above the floor",
            fl.views.len(),
            fl.plane_rms_m * 1000.0,
            fl.camera_height_m
        );
    } else {
        println!(
            "no floor plane (pass --floor images of the board lying on the floor to track robots)"
        );
    }
    println!("wrote {}", out.display());
}

fn short(p: &str) -> String {
    Path::new(p)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.to_string())
}
