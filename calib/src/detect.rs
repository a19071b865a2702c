//! Board corner detection: checkerboards (OpenCV findChessboardCorners + cornerSubPix) and
//! ChArUco boards ([`crate::charuco`]).

use std::path::Path;

use nalgebra::{Point2, Point3};
use opencv::core::{self, Mat, Point2f, Size, TermCriteria, Vector};
use opencv::prelude::*;
use opencv::{calib3d, imgcodecs, imgproc};

use crate::{board_points, BoardSpec, BoardTarget, CalibError};

/// The corners detected in one view, each with where it lies on the board.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardView {
    /// The image file.
    pub image: String,
    /// Image size (width, height), pixels.
    pub size: (u32, u32),
    /// Detected inner corners, pixels: for a checkerboard all of them, `board.cols` per row,
    /// first corner nearest the image's top-left; for a ChArUco board the ones found.
    pub corners: Vec<Point2<f64>>,
    /// Each corner's index among the board's inner corners (row-major from the board frame's
    /// origin; OpenCV's ChArUco ids).
    pub ids: Vec<u32>,
    /// Each corner's position on the board (board frame, z = 0), metres.
    pub object_points: Vec<Point3<f64>>,
    /// A ChArUco board laid out as OpenCV before 4.6 drew it (its corners are numbered and
    /// placed as on that board).
    pub legacy_layout: bool,
}

impl BoardView {
    /// A view of a whole checkerboard: `corners` row by row, as [`find_corners`] orders them.
    pub fn checkerboard(
        image: String,
        size: (u32, u32),
        corners: Vec<Point2<f64>>,
        board: &BoardSpec,
    ) -> Self {
        let object_points = board_points(board);
        Self {
            image,
            size,
            ids: (0..corners.len() as u32).collect(),
            object_points: object_points.into_iter().take(corners.len()).collect(),
            corners,
            legacy_layout: false,
        }
    }
}

/// The result of looking for the board in one image.
#[derive(Debug)]
pub enum Detection {
    /// The board was found.
    Found(BoardView),
    /// The image was read but the board was not found in it, or too little of it.
    NotFound {
        /// The image file.
        image: String,
        /// Image size (width, height), pixels.
        size: (u32, u32),
        /// What was missing, e.g. "no 9x6 checkerboard found".
        reason: String,
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
        bad(match odocal_core::file_kind(path) {
            Some(kind) if odocal_core::is_video(kind) => format!(
                "is {kind}, not a photograph: calibrate takes PNG or JPEG images of the board (`ffmpeg -i VIDEO -vf fps=1 view_%03d.png` extracts one a second; keep the sharp ones with the board still)"
            ),
            Some(kind) => format!("is {kind}, not a PNG or JPEG image of the board"),
            None => format!("is not a readable image ({e}); is it a PNG or JPEG?"),
        })
    })?;
    if u64::from(w) * u64::from(h) > MAX_IMAGE_PIXELS || w == 0 || h == 0 {
        return Err(bad(format!(
            "claims to be {w}x{h} pixels, not a camera image (at most {} megapixels)",
            MAX_IMAGE_PIXELS / 1_000_000
        )));
    }
    // Decoded as its content says, as OpenCV reads it: by its name, a PNG called .jpg (or
    // with no extension) was called a damaged PNG.
    if format == Some(image::ImageFormat::Png) {
        image::ImageReader::open(path)
            .and_then(|r| r.with_guessed_format())
            .map_err(|e| bad(format!("cannot be read ({e})")))?
            .decode()
            .map_err(|e| bad(format!("is a damaged PNG ({e})")))?;
    }
    Ok(())
}

/// How odocal reads every image, calibration views and tracked frames alike: 8-bit grey, the
/// pixels as the sensor recorded them. A photo's EXIF orientation only says how to show it
/// (a camera held turned); applied, a view would describe another pixel layout than the
/// camera's video and calibrate a principal point and distortion that fit neither.
pub const IMREAD_SENSOR_GRAY: i32 =
    imgcodecs::IMREAD_GRAYSCALE | imgcodecs::IMREAD_IGNORE_ORIENTATION;

/// The turn an image's EXIF orientation asks for on display, which odocal does not apply
/// ([`IMREAD_SENSOR_GRAY`]), as "EXIF orientation 3 (turn 180°)"; None when it asks for none
/// or the file has none.
pub fn display_rotation(path: &Path) -> Option<String> {
    use image::{metadata::Orientation, ImageDecoder};
    let mut decoder = image::ImageReader::open(path)
        .ok()?
        .with_guessed_format()
        .ok()?
        .into_decoder()
        .ok()?;
    let orientation = decoder.orientation().ok()?;
    let turn = match orientation {
        Orientation::NoTransforms => return None,
        Orientation::Rotate90 => "turn 90° clockwise",
        Orientation::Rotate180 => "turn 180°",
        Orientation::Rotate270 => "turn 90° counter-clockwise",
        Orientation::FlipHorizontal => "mirror left to right",
        Orientation::FlipVertical => "mirror top to bottom",
        Orientation::Rotate90FlipH => "turn 90° clockwise and mirror",
        Orientation::Rotate270FlipH => "turn 90° counter-clockwise and mirror",
    };
    Some(format!(
        "EXIF orientation {} ({turn})",
        orientation.to_exif()
    ))
}

/// One note naming the images whose display rotation odocal leaves unapplied, or None.
pub fn display_rotation_note<'a>(paths: impl IntoIterator<Item = &'a Path>) -> Option<String> {
    let turned: Vec<String> = paths
        .into_iter()
        .filter_map(|p| Some(format!("{}: {}", p.display(), display_rotation(p)?)))
        .collect();
    let first = turned.first()?;
    let more = match turned.len() {
        1 => String::new(),
        n => format!(" and {} more", n - 1),
    };
    Some(format!(
        "note: {first}{more}: the turn is for display only and is not applied; odocal reads every image's pixels as the sensor recorded them, as it reads the frames it tracks"
    ))
}

/// Reads an image as 8-bit grey, with a clear error for unreadable files.
pub fn read_gray(path: &Path) -> Result<Mat, CalibError> {
    let name = path.display().to_string();
    if path.is_dir() {
        return Err(CalibError::BadFile {
            reason: format!(
                "is a folder, not an image: pass the images in it ({}/*.png)",
                name.trim_end_matches('/')
            ),
            path: name,
        });
    }
    if !path.is_file() {
        return Err(CalibError::BadFile {
            path: name,
            reason: "no such file".into(),
        });
    }
    check_image_file(path)?;
    let img = imgcodecs::imread(path, IMREAD_SENSOR_GRAY)?;
    if img.empty() {
        return Err(CalibError::BadFile {
            path: name,
            reason: "cannot be decoded as an image (corrupt or not PNG/JPEG/PGM?)".into(),
        });
    }
    // A 16-bit image holding fewer bits (numpy's astype(uint16) of 8-bit values; a 10- or
    // 12-bit sensor's raw values) reads as black or a few grey levels when its top 8 bits
    // are taken: it is scaled by its own range instead (10-bit data was refused as a black
    // frame, 12-bit cut to 16 grey levels).
    let mut max = 0.0;
    core::min_max_loc(&img, None, Some(&mut max), None, None, &core::no_array())?;
    if max < 64.0 {
        let deep = imgcodecs::imread(path, IMREAD_SENSOR_GRAY | imgcodecs::IMREAD_ANYDEPTH)?;
        let mut deep_max = 0.0;
        core::min_max_loc(
            &deep,
            None,
            Some(&mut deep_max),
            None,
            None,
            &core::no_array(),
        )?;
        if deep.depth() == core::CV_16U && deep_max >= 2.0 {
            let scale = if deep_max <= 255.0 {
                1.0
            } else {
                // The smallest whole number of bits holding the data, so a dark frame of a
                // 12-bit sensor stays dark.
                let bits = (deep_max + 1.0).log2().ceil();
                255.0 / (2f64.powf(bits) - 1.0)
            };
            let mut as_8bit = Mat::default();
            deep.convert_to(&mut as_8bit, core::CV_8U, scale, 0.0)?;
            return Ok(as_8bit);
        }
    }
    Ok(img)
}

/// Why a grey image holds nothing to detect: every pixel within a grey level of one value
/// (a blank or black frame). The detectors spend minutes on a large one finding nothing.
pub fn uniform_image(gray: &Mat) -> Result<Option<String>, CalibError> {
    let (mut mean, mut sd) = (Mat::default(), Mat::default());
    core::mean_std_dev(gray, &mut mean, &mut sd, &core::no_array())?;
    let (mean, sd) = (*mean.at::<f64>(0)?, *sd.at::<f64>(0)?);
    Ok((sd < 1.0).then(|| {
        format!(
            "the image is uniform (every pixel about {mean:.0} of 255): a blank {} frame shows no board",
            if mean < 8.0 { "or black" } else { "or overexposed" }
        )
    }))
}

/// Finds the inner corners of `board` in a grey image, refined to sub-pixel.
pub fn find_corners(gray: &Mat, board: &BoardSpec) -> Result<Option<Vec<Point2<f64>>>, CalibError> {
    let pattern = Size::new(board.cols as i32, board.rows as i32);
    let mut corners = Vector::<Point2f>::new();
    let flags = calib3d::CALIB_CB_ADAPTIVE_THRESH
        | calib3d::CALIB_CB_NORMALIZE_IMAGE
        | calib3d::CALIB_CB_FAST_CHECK;
    // The classic detector needs straight rows of squares; a board far out in a wide lens's
    // image is bent too much for it, so fall back to OpenCV's sector-based detector, which
    // follows curved rows. Both are refined the same way below.
    if !calib3d::find_chessboard_corners(gray, pattern, &mut corners, flags)?
        && !calib3d::find_chessboard_corners_sb(
            gray,
            pattern,
            &mut corners,
            calib3d::CALIB_CB_NORMALIZE_IMAGE | calib3d::CALIB_CB_EXHAUSTIVE,
        )?
    {
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
    if let Some(reason) = uniform_image(&gray)? {
        return Ok(Detection::NotFound {
            image,
            size,
            reason,
        });
    }
    if let BoardTarget::Charuco { .. } = board.target {
        return Ok(match crate::charuco::find_charuco_corners(&gray, board)? {
            Ok(found) => Detection::Found(BoardView {
                image,
                size,
                corners: found.corners,
                ids: found.ids,
                object_points: found.object_points,
                legacy_layout: found.legacy_layout,
            }),
            Err(reason) => Detection::NotFound {
                image,
                size,
                reason,
            },
        });
    }
    Ok(match find_corners(&gray, board)? {
        Some(corners) => Detection::Found(BoardView::checkerboard(image, size, corners, board)),
        None => Detection::NotFound {
            image,
            size,
            reason: format!("no {}x{} checkerboard found", board.cols, board.rows),
        },
    })
}

/// Squares a grid is followed past its found corners, at most: larger boards are rare, and
/// linear extrapolation drifts under a lens's distortion.
const MAX_EXTRA_SQUARES: usize = 12;

/// The size of the board the detected grid belongs to, when it is larger than `board`: a
/// `--board` short of the real one finds part of the board, at a different place in each view,
/// which shifts the floor origin by squares and gives views that fit no one camera. The grid
/// extends past a side when the points a square beyond that side's corners are chessboard
/// corners too (saddles: diagonal quadrants alike, neighbouring ones in contrast); it is
/// followed square by square to where the board's plain margin begins. Looking at the image
/// around the corners already found takes microseconds, where asking OpenCV for a board of
/// every larger size takes tens of seconds when the size is wrong.
pub fn larger_board_around(
    path: &Path,
    board: &BoardSpec,
    corners: &[Point2<f64>],
) -> Option<(u32, u32)> {
    board_around(&read_gray(path).ok()?, board, corners)
}

/// The board the image at `path` shows, from the size `seen` around a part of it (see
/// [`larger_board_around`]), checked by the detector as [`quick_board_size_check`]'s is.
pub fn board_size_confirmed(path: &Path, seen: (u32, u32), board: &BoardSpec) -> BoardSizeSeen {
    match read_gray(path) {
        Ok(gray) => confirmed_size(&gray, seen, board),
        Err(_) => BoardSizeSeen {
            size: seen,
            confirmed: false,
        },
    }
}

/// [`larger_board_around`] in an image already read.
fn board_around(gray: &Mat, board: &BoardSpec, corners: &[Point2<f64>]) -> Option<(u32, u32)> {
    let (cols, rows) = (board.cols as usize, board.rows as usize);
    if cols < 2 || rows < 2 || corners.len() != cols * rows {
        return None;
    }
    let grid: Vec<nalgebra::Vector2<f64>> = corners.iter().map(|p| p.coords).collect();
    // OpenCV can also take every other corner of a larger board for a smaller one: then the
    // points halfway between neighbours are corners too, and the grid is filled in first.
    let (grid, cols2, rows2) = fill_skipped_corners(gray, grid, cols, rows);
    let (wider, taller) = extend_grid(gray, &grid, cols2, rows2);
    let (c, r) = ((cols2 + wider) as u32, (rows2 + taller) as u32);
    ((c, r) != (board.cols, board.rows)).then_some((c, r))
}

/// Whether `line`'s points are mostly chessboard corners (60 %), each with its grid's two
/// square-spanning vectors.
fn mostly_saddles(
    gray: &Mat,
    line: impl Iterator<
        Item = (
            nalgebra::Vector2<f64>,
            nalgebra::Vector2<f64>,
            nalgebra::Vector2<f64>,
        ),
    >,
) -> bool {
    let (mut n, mut saddles) = (0usize, 0usize);
    for (p, u, v) in line {
        n += 1;
        if is_saddle(gray, p, u, v) == Some(true) {
            saddles += 1;
        }
    }
    n > 0 && saddles as f64 >= 0.6 * n as f64
}

/// The grid with the corners OpenCV skipped put back: along an axis whose neighbours'
/// midpoints are chessboard corners, a corner is inserted between every two.
fn fill_skipped_corners(
    gray: &Mat,
    grid: Vec<nalgebra::Vector2<f64>>,
    cols: usize,
    rows: usize,
) -> (Vec<nalgebra::Vector2<f64>>, usize, usize) {
    let at = |g: &[nalgebra::Vector2<f64>], c: usize, r: usize| g[r * cols + c];
    // The step to the neighbouring corner across the axis tested: down a column when
    // `down`, along a row otherwise.
    let other = |g: &[nalgebra::Vector2<f64>], c: usize, r: usize, down: bool| {
        if down {
            let r2 = if r + 1 < rows { r + 1 } else { r - 1 };
            at(g, c, r2) - at(g, c, r)
        } else {
            let c2 = if c + 1 < cols { c + 1 } else { c - 1 };
            at(g, c2, r) - at(g, c, r)
        }
    };
    let skip_cols = mostly_saddles(
        gray,
        (0..rows)
            .flat_map(|r| (0..cols - 1).map(move |c| (c, r)))
            .map(|(c, r)| {
                let half = (at(&grid, c + 1, r) - at(&grid, c, r)) / 2.0;
                (at(&grid, c, r) + half, half, other(&grid, c, r, true))
            }),
    );
    let skip_rows = mostly_saddles(
        gray,
        (0..cols)
            .flat_map(|c| (0..rows - 1).map(move |r| (c, r)))
            .map(|(c, r)| {
                let half = (at(&grid, c, r + 1) - at(&grid, c, r)) / 2.0;
                (at(&grid, c, r) + half, half, other(&grid, c, r, false))
            }),
    );
    if !skip_cols && !skip_rows {
        return (grid, cols, rows);
    }
    let cols2 = if skip_cols { 2 * cols - 1 } else { cols };
    let rows2 = if skip_rows { 2 * rows - 1 } else { rows };
    // Bilinear in the found grid's cells: the filled-in corners lie halfway.
    let mut out = Vec::with_capacity(cols2 * rows2);
    for r2 in 0..rows2 {
        for c2 in 0..cols2 {
            let (fc, fr) = (
                if skip_cols {
                    c2 as f64 / 2.0
                } else {
                    c2 as f64
                },
                if skip_rows {
                    r2 as f64 / 2.0
                } else {
                    r2 as f64
                },
            );
            let (c0, r0) = ((fc as usize).min(cols - 1), (fr as usize).min(rows - 1));
            let (c1, r1) = ((c0 + 1).min(cols - 1), (r0 + 1).min(rows - 1));
            let (wc, wr) = (fc - c0 as f64, fr - r0 as f64);
            let top = at(&grid, c0, r0) * (1.0 - wc) + at(&grid, c1, r0) * wc;
            let bottom = at(&grid, c0, r1) * (1.0 - wc) + at(&grid, c1, r1) * wc;
            out.push(top * (1.0 - wr) + bottom * wr);
        }
    }
    (out, cols2, rows2)
}

/// Columns and rows the grid goes on past its sides: square by square, while most of a
/// side's points one square further out are chessboard corners. Each step starts from the
/// corners found the step before, refined to sub-pixel, so the growing squares of a board
/// seen in perspective are followed rather than extrapolated from the first.
fn extend_grid(
    gray: &Mat,
    grid: &[nalgebra::Vector2<f64>],
    cols: usize,
    rows: usize,
) -> (usize, usize) {
    let at = |r: usize, c: usize| grid[r * cols + c];
    let side = |line: &[(usize, usize)], inward: (isize, isize)| -> usize {
        // Per point of the side: where it is, the step out, and the step along the side.
        let mut front: Vec<_> = line
            .iter()
            .map(|&(r, c)| {
                let (ri, ci) = (
                    (r as isize + inward.0) as usize,
                    (c as isize + inward.1) as usize,
                );
                let (ra, ca) = if inward.0 == 0 {
                    (if r + 1 < rows { r + 1 } else { r - 1 }, c)
                } else {
                    (r, if c + 1 < cols { c + 1 } else { c - 1 })
                };
                (at(r, c), at(r, c) - at(ri, ci), at(ra, ca) - at(r, c))
            })
            .collect();
        let mut extra = 0;
        while extra < MAX_EXTRA_SQUARES {
            let next: Vec<_> = front
                .iter()
                .map(|&(p, out, along)| {
                    let q = refine_corner(gray, p + out, out.norm().min(along.norm()));
                    (q, q - p, along)
                })
                .collect();
            if !mostly_saddles(gray, next.iter().map(|&(q, out, along)| (q, out, along))) {
                break;
            }
            front = next;
            extra += 1;
        }
        extra
    };
    let right: Vec<(usize, usize)> = (0..rows).map(|r| (r, cols - 1)).collect();
    let left: Vec<(usize, usize)> = (0..rows).map(|r| (r, 0)).collect();
    let bottom: Vec<(usize, usize)> = (0..cols).map(|c| (rows - 1, c)).collect();
    let top: Vec<(usize, usize)> = (0..cols).map(|c| (0, c)).collect();
    (
        side(&right, (0, -1)) + side(&left, (0, 1)),
        side(&bottom, (-1, 0)) + side(&top, (1, 0)),
    )
}

/// `p` moved to the chessboard corner near it (OpenCV's cornerSubPix, a window a third of
/// the `square_px` wide); `p` itself when it lies too near the image's edge or the search
/// fails.
fn refine_corner(gray: &Mat, p: nalgebra::Vector2<f64>, square_px: f64) -> nalgebra::Vector2<f64> {
    let half = ((square_px / 3.0).floor() as i32).clamp(2, 11);
    let (w, h) = (gray.cols() as f64, gray.rows() as f64);
    let margin = half as f64 + 2.0;
    if !(p.x > margin && p.y > margin && p.x < w - margin && p.y < h - margin) {
        return p;
    }
    let mut pts = Vector::<Point2f>::from_iter([Point2f::new(p.x as f32, p.y as f32)]);
    let refined = TermCriteria::new(
        core::TermCriteria_Type::COUNT as i32 + core::TermCriteria_Type::EPS as i32,
        20,
        1e-3,
    )
    .and_then(|tc| {
        imgproc::corner_sub_pix(gray, &mut pts, Size::new(half, half), Size::new(-1, -1), tc)
    });
    match (refined, pts.get(0)) {
        (Ok(()), Ok(q)) if ((q.x as f64 - p.x).hypot(q.y as f64 - p.y)) < square_px / 3.0 => {
            nalgebra::Vector2::new(q.x as f64, q.y as f64)
        }
        _ => p,
    }
}

/// Whether the image at `p` looks like a chessboard corner whose squares are spanned by `u`
/// and `v` (pixels): the mean grey of the four quadrants, sampled by OpenCV a third of a
/// square away along the diagonals. None when a sample falls outside the image.
fn is_saddle(
    gray: &Mat,
    p: nalgebra::Vector2<f64>,
    u: nalgebra::Vector2<f64>,
    v: nalgebra::Vector2<f64>,
) -> Option<bool> {
    let (w, h) = (gray.cols() as f64, gray.rows() as f64);
    let half = ((u.norm().min(v.norm()) * 0.15).round() as i32).max(1);
    let mut q = [0.0f64; 4];
    for (k, (a, b)) in [(1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0)]
        .iter()
        .enumerate()
    {
        let c = p + (u * *a + v * *b) / 3.0;
        if c.x < half as f64
            || c.y < half as f64
            || c.x >= w - half as f64
            || c.y >= h - half as f64
        {
            return None;
        }
        let mut patch = Mat::default();
        imgproc::get_rect_sub_pix(
            gray,
            Size::new(2 * half + 1, 2 * half + 1),
            Point2f::new(c.x as f32, c.y as f32),
            &mut patch,
            -1,
        )
        .ok()?;
        q[k] = core::mean(&patch, &core::no_array()).ok()?[0];
    }
    let contrast = ((q[0] + q[2]) - (q[1] + q[3])).abs() / 2.0;
    let unlike = (q[0] - q[2]).abs().max((q[1] - q[3]).abs());
    Some(contrast > 40.0 && unlike < 0.5 * contrast)
}

/// OpenCV's sector-based detector alone, unrefined: a tenth of a second on a 1280x720 view,
/// where the classic detector spends seventeen seconds when the size is wrong.
fn find_corners_quick(gray: &Mat, cols: u32, rows: u32) -> Option<Vec<Point2<f64>>> {
    let mut corners = Vector::<Point2f>::new();
    let found = calib3d::find_chessboard_corners_sb(
        gray,
        Size::new(cols as i32, rows as i32),
        &mut corners,
        calib3d::CALIB_CB_NORMALIZE_IMAGE,
    )
    .ok()?;
    found.then(|| {
        corners
            .iter()
            .map(|p| Point2::new(p.x as f64, p.y as f64))
            .collect()
    })
}

/// Largest factor between neighbouring corner spacings along a grid's axis: perspective and a
/// wide lens's distortion change them smoothly, a skipped row of squares doubles one.
const MAX_SPACING_STEP: f64 = 1.6;

/// The longest run of `spacings` in which neighbours differ by less than
/// [`MAX_SPACING_STEP`]: its first index and its number of spacings.
fn regular_run(spacings: &[f64]) -> (usize, usize) {
    let (mut best, mut start) = ((0, 0), 0);
    for i in 0..spacings.len() {
        if i > start {
            let r = spacings[i] / spacings[i - 1];
            if !(1.0 / MAX_SPACING_STEP..=MAX_SPACING_STEP).contains(&r) {
                start = i;
            }
        }
        if i + 1 - start > best.1 {
            best = (start, i + 1 - start);
        }
    }
    best
}

/// The regular part of a `cols`×`rows` grid of corners (row-major): the longest runs of
/// columns and of rows whose spacings change smoothly, with its size. OpenCV's sector-based
/// detector, asked for a board smaller than the one in view, can return corners of columns
/// that are not neighbours (387, 362, 337, 283 and 162 px across a 9x6 board for 6x5).
fn regular_part(
    corners: &[Point2<f64>],
    cols: usize,
    rows: usize,
) -> (Vec<Point2<f64>>, usize, usize) {
    let at = |r: usize, c: usize| corners[r * cols + c];
    let along_rows: Vec<f64> = (0..cols - 1)
        .map(|c| {
            (0..rows)
                .map(|r| (at(r, c + 1) - at(r, c)).norm())
                .sum::<f64>()
                / rows as f64
        })
        .collect();
    let down_cols: Vec<f64> = (0..rows - 1)
        .map(|r| {
            (0..cols)
                .map(|c| (at(r + 1, c) - at(r, c)).norm())
                .sum::<f64>()
                / cols as f64
        })
        .collect();
    let (c0, nc) = regular_run(&along_rows);
    let (r0, nr) = regular_run(&down_cols);
    let (cols2, rows2) = (nc + 1, nr + 1);
    let part = (r0..r0 + rows2)
        .flat_map(|r| (c0..c0 + cols2).map(move |c| (r, c)))
        .map(|(r, c)| at(r, c))
        .collect();
    (part, cols2, rows2)
}

/// A quick look at one image before every view is searched for `board`: the size of the
/// board it shows when that is not `board` (oriented as `board`'s sides are), from the fast
/// detector and the squares around what it finds. A `--board` typo otherwise costs the
/// classic detector tens of seconds per view before the error says anything.
pub fn quick_board_size_check(path: &Path, board: &BoardSpec) -> Option<BoardSizeSeen> {
    if board.is_charuco() {
        return None;
    }
    let gray = read_gray(path).ok()?;
    let size = board_size_seen(&gray, board)?;
    Some(confirmed_size(&gray, size, board))
}

/// The board size `seen` (followed square by square from a part of the board) checked by the
/// detector: followed that way, a grid may stop short of a worn or shadowed edge, or run a
/// square past the last one when OpenCV took every other corner, so the sizes around it are
/// tried too (nearest first, a tenth of a second each at 1280x720); a size is named as the
/// board's only when the detector finds a whole, regular board of it with no more squares
/// around it.
fn confirmed_size(gray: &Mat, seen: (u32, u32), board: &BoardSpec) -> BoardSizeSeen {
    let whole = |(c, r): (u32, u32)| {
        find_corners_quick(gray, c, r).is_some_and(|corners| {
            let (_, c2, r2) = regular_part(&corners, c as usize, r as usize);
            let spec = BoardSpec::checkerboard(c, r, board.square_m);
            (c2, r2) == (c as usize, r as usize) && board_around(gray, &spec, &corners).is_none()
        })
    };
    let (c, r) = (seen.0 as i64, seen.1 as i64);
    let mut around: Vec<(i64, i64)> = (-1..=CONFIRM_MORE_SQUARES)
        .flat_map(|dc| (-1..=CONFIRM_MORE_SQUARES).map(move |dr| (dc, dr)))
        .collect();
    around.sort_by_key(|&(dc, dr)| (dc.abs() + dr.abs(), dc.abs().max(dr.abs())));
    around
        .into_iter()
        .map(|(dc, dr)| (c + dc, r + dr))
        .filter(|&(a, b)| a >= 2 && b >= 2)
        .map(|(a, b)| (a as u32, b as u32))
        .filter(|&size| size != (board.cols, board.rows))
        .find(|&size| whole(size))
        .map_or(
            BoardSizeSeen {
                size: seen,
                confirmed: false,
            },
            |size| BoardSizeSeen {
                size: oriented_like(size, board),
                confirmed: true,
            },
        )
}

/// Squares past a grid followed from part of the board that its true size is looked for.
const CONFIRM_MORE_SQUARES: i64 = 3;

/// `size` with its sides in the order `board` gives its own (OpenCV finds a board either way
/// round).
pub fn oriented_like(size: (u32, u32), board: &BoardSpec) -> (u32, u32) {
    let (a, b) = size;
    if (a >= b) == (board.cols >= board.rows) {
        (a, b)
    } else {
        (b, a)
    }
}

/// A board size read off an image by [`quick_board_size_check`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardSizeSeen {
    /// Inner corners, in the order `--board` gave its sides.
    pub size: (u32, u32),
    /// Whether a board of that size was found; else the board is at least that large.
    pub confirmed: bool,
}

impl BoardSizeSeen {
    /// The one-line refusal of `--board` for `image`, which shows this board instead.
    pub fn refusal(&self, image: &Path, board: &BoardSpec) -> String {
        let (c, r) = self.size;
        if self.confirmed {
            format!(
                "{} shows a {c}x{r} board, not the {}x{} of --board: pass --board {c}x{r} (--board counts INNER corners: one fewer than the squares along each side)",
                image.display(),
                board.cols,
                board.rows
            )
        } else {
            format!(
                "{} shows a board of at least {c}x{r} inner corners, not the {}x{} of --board: count its INNER corners (one fewer than the squares along each side) and pass them as --board",
                image.display(),
                board.cols,
                board.rows
            )
        }
    }
}

/// The size of the board `gray` shows when it is not `board`'s, oriented like `board`.
fn board_size_seen(gray: &Mat, board: &BoardSpec) -> Option<(u32, u32)> {
    let oriented = |size| oriented_like(size, board);
    if let Some(corners) = find_corners_quick(gray, board.cols, board.rows) {
        let (part, c, r) = regular_part(&corners, board.cols as usize, board.rows as usize);
        let spec = BoardSpec::checkerboard(c as u32, r as u32, board.square_m);
        return board_around(gray, &spec, &part)
            .map(oriented)
            .filter(|&size| size != (board.cols, board.rows));
    }
    let (c, r) = (board.cols as i64, board.rows as i64);
    [
        (c + 1, r + 1),
        (c - 1, r - 1),
        (c + 1, r),
        (c, r + 1),
        (c - 1, r),
        (c, r - 1),
        (c + 2, r + 1),
        (c - 2, r - 1),
    ]
    .into_iter()
    .filter(|&(a, b)| a >= 3 && b >= 3)
    .find_map(|(a, b)| {
        let (a, b) = (a as u32, b as u32);
        let corners = find_corners_quick(gray, a, b)?;
        let (part, c, r) = regular_part(&corners, a as usize, b as usize);
        let spec = BoardSpec::checkerboard(c as u32, r as u32, board.square_m);
        Some(oriented(
            board_around(gray, &spec, &part).unwrap_or((c as u32, r as u32)),
        ))
    })
    .filter(|&size| size != (board.cols, board.rows) && size != (board.rows, board.cols))
}

/// The inner corners of a plain checkerboard that the image at `path` shows, looked for at
/// `board`'s size and around it: for images given as a ChArUco board's that show no marker,
/// whose grid of squares `board` counts alike.
pub fn checkerboard_shown(path: &Path, board: &BoardSpec) -> Option<(u32, u32)> {
    let gray = read_gray(path).ok()?;
    let plain = BoardSpec::checkerboard(board.cols, board.rows, board.square_m);
    if let Some(corners) = find_corners_quick(&gray, board.cols, board.rows) {
        let (part, c, r) = regular_part(&corners, board.cols as usize, board.rows as usize);
        let spec = BoardSpec::checkerboard(c as u32, r as u32, board.square_m);
        let whole = board_around(&gray, &spec, &part).unwrap_or((c as u32, r as u32));
        return Some(oriented_like(whole, &plain));
    }
    board_size_seen(&gray, &plain)
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
        .find_map(|(a, b)| {
            let spec = BoardSpec::checkerboard(a as u32, b as u32, board.square_m);
            let corners = find_corners(&gray, &spec).ok()??;
            // A nearby size may itself be part of the board: name the whole of it.
            let whole = board_around(&gray, &spec, &corners).unwrap_or((a as u32, b as u32));
            Some(oriented_like(whole, board))
        })
        .filter(|&size| size != (board.cols, board.rows))
}
