//! A rendered calibration session on disk, as `odocal synth calib` writes it: the hand-held
//! board views and floor views as PNG, truth.json (every true pose) and camera_true.json
//! (the true camera in camera.json's format).

use std::path::Path;

use odocal_calib::{CameraFile, FloorPlane};
use rayon::prelude::*;
use thiserror::Error;

use crate::board::{draw_views, render_view, BoardPattern, CalibScene, CalibTruth};
use crate::raycast::RayGrid;

/// The largest image `synth calib` renders, pixels (a 40-megapixel camera).
pub const MAX_PIXELS: u64 = 40_000_000;

/// What goes wrong while writing a calibration session.
#[derive(Debug, Error)]
pub enum CalibSetError {
    /// Settings that cannot give a session (names the option).
    #[error("{0}")]
    Settings(String),
    /// A file could not be written.
    #[error("cannot write {path}: {reason}")]
    Write {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), CalibSetError> {
    std::fs::write(path, bytes).map_err(|e| CalibSetError::Write {
        path: path.display().to_string(),
        reason: e.to_string(),
    })
}

fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), CalibSetError> {
    let mut s = serde_json::to_string_pretty(value).map_err(|e| CalibSetError::Write {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    s.push('\n');
    write(path, s.as_bytes())
}

/// Checks that a scene can be rendered: an image of at least 64x48 and at most
/// [`MAX_PIXELS`], a horizontal field of view the lens model can render
/// ([`crate::board::max_hfov_deg`]).
pub fn check_scene(scene: &CalibScene) -> Result<(), CalibSetError> {
    let pixels = u64::from(scene.width) * u64::from(scene.height);
    if scene.width < 64 || scene.height < 48 || pixels > MAX_PIXELS {
        return Err(CalibSetError::Settings(format!(
            "--width {} --height {}: need at least 64x48 and at most {} megapixels",
            scene.width,
            scene.height,
            MAX_PIXELS / 1_000_000
        )));
    }
    if scene.views < 3 {
        return Err(CalibSetError::Settings(format!(
            "--views {}: Zhang calibration needs at least 3 hand-held views (10-20 recommended)",
            scene.views
        )));
    }
    if !(scene.noise_sigma >= 0.0 && scene.noise_sigma <= 50.0) {
        return Err(CalibSetError::Settings(format!(
            "--noise {}: 0 to 50 grey levels",
            scene.noise_sigma
        )));
    }
    // A lens blurs over a pixel or a few; wider is a board out of focus that no detector finds.
    if !(scene.blur_px >= 0.0 && scene.blur_px <= 20.0) {
        return Err(CalibSetError::Settings(format!(
            "--blur {}: the optical blur σ is 0 to 20 pixels",
            scene.blur_px
        )));
    }
    let model = scene.distortion.model;
    let max = crate::board::max_hfov_deg(model);
    if !(scene.hfov_deg >= 10.0 && scene.hfov_deg <= max) {
        return Err(CalibSetError::Settings(format!(
            "--hfov {}: the {model} lens is rendered at 10-{max:.0} degrees{}",
            scene.hfov_deg,
            if model == odocal_calib::LensModel::Fisheye
                || scene.hfov_deg <= max
                || scene.hfov_deg.is_nan()
            {
                ""
            } else {
                "; wider needs --lens fisheye"
            }
        )));
    }
    if scene.board.is_charuco() {
        odocal_calib::charuco::check_board(&scene.board)
            .map_err(|e| CalibSetError::Settings(e.to_string()))?;
    }
    Ok(())
}

/// Renders a calibration session into the existing directory `out`; `on_view` is called after
/// each view (for a progress bar).
pub fn write_calib_set(
    out: &Path,
    scene: &CalibScene,
    seed: u64,
    on_view: &(dyn Fn() + Sync),
) -> Result<CalibTruth, CalibSetError> {
    check_scene(scene)?;
    let truth = draw_views(scene, seed);
    if truth.views.len() < scene.views {
        return Err(CalibSetError::Settings(format!(
            "could only place {} of {} board views in a {}x{} image",
            truth.views.len(),
            scene.views,
            scene.width,
            scene.height
        )));
    }
    // A narrow view of the floor from the ceiling holds no whole board: a calibration from
    // these views would have no floor, which `track` needs. (Some placed of more asked is
    // warned about by `synth calib`.)
    if scene.floor_views > 0 && truth.floor_views.is_empty() {
        // Under the camera a square is at its largest: too few pixels there is too small a
        // square (a wide lens or a small image), not too narrow a view.
        let square_px = truth.camera.intrinsics.fx * scene.board.square_m / scene.camera_height_m;
        let min_px = crate::board::min_corner_spacing_px(scene.width);
        let why = if square_px < min_px {
            format!(
                "its squares are {square_px:.0} px across under the camera, fewer than the {min_px:.0} px a board is found at; give a larger --square (at least {:.2} m), a larger image, a narrower --hfov, or --floor-views 0",
                (scene.board.square_m * min_px / square_px * 100.0).ceil() / 100.0
            )
        } else {
            "the floor it sees holds no whole board there; give a wider --hfov, a smaller --square, or --floor-views 0".to_string()
        };
        return Err(CalibSetError::Settings(format!(
            "could place none of the {} floor views in a {}x{} image of a {}° camera {} m up: {why}",
            scene.floor_views, scene.width, scene.height, scene.hfov_deg, scene.camera_height_m,
        )));
    }
    std::fs::create_dir_all(out).map_err(|e| CalibSetError::Write {
        path: out.display().to_string(),
        reason: e.to_string(),
    })?;
    let pattern =
        BoardPattern::new(&scene.board).map_err(|e| CalibSetError::Settings(e.to_string()))?;
    let grid = RayGrid::new(&truth.camera, scene.supersample);
    let jobs: Vec<_> = truth
        .views
        .iter()
        .map(|v| (v, None))
        .chain(
            truth
                .floor_views
                .iter()
                .map(|v| (v, Some(&truth.floor_to_camera))),
        )
        .enumerate()
        .collect();
    jobs.par_iter()
        .try_for_each(|(i, (view, floor))| -> Result<(), CalibSetError> {
            let img = render_view(
                &grid,
                scene,
                &pattern,
                &view.board_to_camera,
                *floor,
                seed.wrapping_mul(1000).wrapping_add(*i as u64),
            );
            let path = out.join(&view.image);
            let mut png = Vec::new();
            img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                .map_err(|e| CalibSetError::Write {
                    path: path.display().to_string(),
                    reason: e.to_string(),
                })?;
            write(&path, &png)?;
            on_view();
            Ok(())
        })?;
    write_json(&out.join("truth.json"), &truth)?;
    let floor = FloorPlane {
        floor_to_camera: truth.floor_to_camera,
        plane_rms_m: 0.0,
        camera_height_m: scene.camera_height_m,
        views: vec![],
    };
    write_json(
        &out.join("camera_true.json"),
        &CameraFile::from_model(truth.camera, Some(floor)),
    )?;
    Ok(truth)
}
