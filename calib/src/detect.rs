//! Checkerboard corner detection (OpenCV findChessboardCorners + cornerSubPix).

use std::path::Path;

use nalgebra::Point2;
use opencv::core::{self, Mat, Point2f, Size, TermCriteria, Vector};
use opencv::prelude::*;
use opencv::{calib3d, imgcodecs, imgproc};

use crate::{BoardSpec, CalibError};

/// The detected inner corners of one view, row by row, in pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardView {
    /// The image file.
    pub image: String,
    /// Image size (width, height), pixels.
    pub size: (u32, u32),
    /// Inner corners, `board.cols` per row, first corner nearest the image's top-left.
    pub corners: Vec<Point2<f64>>,
}

/// The result of looking for the board in one image.
#[derive(Debug)]
pub enum Detection {
    /// The board was found.
    Found(BoardView),
    /// The image was read but the board was not found in it.
    NotFound {
        /// The image file.
        image: String,
        /// Image size (width, height), pixels.
        size: (u32, u32),
    },
}

/// The largest image read, pixels (a 100-megapixel camera).
pub const MAX_IMAGE_PIXELS: u64 = 100_000_000;

/// Checks an image file before OpenCV decodes it: a header that says what it is and a size a
/// camera has, and for PNG a complete file, so that a bad file gives one line naming it
/// instead of a decoder's assertion or a multi-gigabyte allocation.
pub fn check_image_file(path: &Path) -> Result<(), CalibError> {
    let bad = |reason: String| CalibError::BadFile {
        path: path.display().to_string(),
        reason,
    };
    let reader = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| bad(format!("cannot be read ({e})")))?;
    let format = reader.format();
    let (w, h) = reader.into_dimensions().map_err(|e| {
        bad(format!(
            "is not a readable image ({e}); is it a PNG or JPEG?"
        ))
    })?;
    if u64::from(w) * u64::from(h) > MAX_IMAGE_PIXELS || w == 0 || h == 0 {
        return Err(bad(format!(
            "claims to be {w}x{h} pixels, not a camera image (at most {} megapixels)",
            MAX_IMAGE_PIXELS / 1_000_000
        )));
    }
    if format == Some(image::ImageFormat::Png) {
        image::open(path).map_err(|e| bad(format!("is a damaged PNG ({e})")))?;
    }
    Ok(())
}

/// Reads an image as 8-bit grey, with a clear error for unreadable files.
pub fn read_gray(path: &Path) -> Result<Mat, CalibError> {
    let name = path.display().to_string();
    if !path.is_file() {
        return Err(CalibError::BadFile {
            path: name,
            reason: "no such file".into(),
        });
    }
    check_image_file(path)?;
    let img = imgcodecs::imread(path, imgcodecs::IMREAD_GRAYSCALE)?;
    if img.empty() {
        return Err(CalibError::BadFile {
            path: name,
            reason: "cannot be decoded as an image (corrupt or not PNG/JPEG/PGM?)".into(),
        });
    }
    Ok(img)
}

/// Finds the inner corners of `board` in a grey image, refined to sub-pixel.
pub fn find_corners(gray: &Mat, board: &BoardSpec) -> Result<Option<Vec<Point2<f64>>>, CalibError> {
    let pattern = Size::new(board.cols as i32, board.rows as i32);
    let mut corners = Vector::<Point2f>::new();
    let flags = calib3d::CALIB_CB_ADAPTIVE_THRESH
        | calib3d::CALIB_CB_NORMALIZE_IMAGE
        | calib3d::CALIB_CB_FAST_CHECK;
    if !calib3d::find_chessboard_corners(gray, pattern, &mut corners, flags)? {
        return Ok(None);
    }
    // The refinement window must stay inside one square: half the smallest
    // corner spacing, at most 11 px.
    let pts: Vec<Point2<f64>> = corners
        .iter()
        .map(|p| Point2::new(p.x as f64, p.y as f64))
        .collect();
    let spacing = min_spacing(&pts, board.cols as usize);
    let half = ((spacing * 0.45).floor() as i32).clamp(2, 11);
    imgproc::corner_sub_pix(
        gray,
        &mut corners,
        Size::new(half, half),
        Size::new(-1, -1),
        TermCriteria::new(
            core::TermCriteria_Type::COUNT as i32 + core::TermCriteria_Type::EPS as i32,
            50,
            1e-4,
        )?,
    )?;
    let mut pts: Vec<Point2<f64>> = corners
        .iter()
        .map(|p| Point2::new(p.x as f64, p.y as f64))
        .collect();
    // OpenCV may start at either end of the board (a 180° ambiguity); fix the
    // order so the first corner is the one nearest the image's top-left.
    let first = pts[0];
    let last = pts[pts.len() - 1];
    if last.x + last.y < first.x + first.y {
        pts.reverse();
    }
    Ok(Some(pts))
}

fn min_spacing(pts: &[Point2<f64>], cols: usize) -> f64 {
    let mut best = f64::INFINITY;
    for (i, p) in pts.iter().enumerate() {
        if (i + 1) % cols != 0 {
            if let Some(q) = pts.get(i + 1) {
                best = best.min((q - p).norm());
            }
        }
        if let Some(q) = pts.get(i + cols) {
            best = best.min((q - p).norm());
        }
    }
    if best.is_finite() {
        best
    } else {
        10.0
    }
}

/// Reads an image and looks for the board in it.
pub fn detect_file(path: &Path, board: &BoardSpec) -> Result<Detection, CalibError> {
    let gray = read_gray(path)?;
    let size = gray.size()?;
    let size = (size.width as u32, size.height as u32);
    let image = path.display().to_string();
    Ok(match find_corners(&gray, board)? {
        Some(corners) => Detection::Found(BoardView {
            image,
            size,
            corners,
        }),
        None => Detection::NotFound { image, size },
    })
}

/// A board one corner wider, taller or both than `board` that is visible in the image, if
/// any: `--board` then counts too few corners and the detected grid is part of the board,
/// which shifts the floor origin by a square.
pub fn larger_board_visible(path: &Path, board: &BoardSpec) -> Option<(u32, u32)> {
    let gray = read_gray(path).ok()?;
    let (c, r) = (board.cols, board.rows);
    [(c + 1, r), (c, r + 1), (c + 1, r + 1)]
        .into_iter()
        .find(|&(cols, rows)| {
            let spec = BoardSpec {
                cols,
                rows,
                square_m: board.square_m,
            };
            matches!(find_corners(&gray, &spec), Ok(Some(_)))
        })
}

/// When no view shows the board, tries nearby sizes on one image to tell the
/// user what they probably miscounted. Returns the size found, if any.
pub fn guess_board_size(path: &Path, board: &BoardSpec) -> Option<(u32, u32)> {
    let gray = read_gray(path).ok()?;
    let (c, r) = (board.cols as i64, board.rows as i64);
    let candidates = [
        (c + 1, r + 1),
        (c - 1, r - 1),
        (r, c),
        (c + 1, r),
        (c, r + 1),
        (c - 1, r),
        (c, r - 1),
    ];
    candidates
        .into_iter()
        .filter(|&(a, b)| a >= 3 && b >= 3 && (a, b) != (c, r))
        .find(|&(a, b)| {
            let spec = BoardSpec {
                cols: a as u32,
                rows: b as u32,
                square_m: board.square_m,
            };
            matches!(find_corners(&gray, &spec), Ok(Some(_)))
        })
        .map(|(a, b)| (a as u32, b as u32))
}
