//! ChArUco boards through OpenCV's aruco module: the board's geometry and its printed image
//! come from OpenCV's `CharucoBoard`, and so does detection up to the sub-pixel step: the ArUco
//! markers first, then the chessboard corners between them interpolated from the markers,
//! which odocal refines to sub-pixel without the markers' pixels.
//!
//! odocal's frame of a ChArUco board is OpenCV's moved to the inner corner with id 0, so that
//! corner is the origin as the first inner corner is a checkerboard's: x along the board's
//! rows, y down the printed board, z into it. Corner ids are OpenCV's: row-major from corner 0,
//! the order of [`crate::board_points`].

use std::fmt;

use nalgebra::{Point2, Point3};
use opencv::aruco::{self, CharucoBoard, CharucoBoardTrait, CharucoBoardTraitConst};
use opencv::core::{self, Mat, Point2f, Ptr, Size, Vector};
use opencv::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{BoardSpec, BoardTarget, CalibError};

/// The fewest corners a ChArUco view must show to be used: Zhang's homography needs 4 points
/// off one line, and a few more keep one bad corner from deciding the view's pose.
pub const MIN_CHARUCO_CORNERS: usize = 6;

/// The share of neighbouring markers that must sit where the board puts them.
const MIN_LAYOUT_AGREEMENT: f64 = 0.9;

/// One of OpenCV's predefined ArUco dictionaries (the family of markers printed on the board).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct ArucoDictionary(usize);

/// OpenCV's predefined dictionaries: odocal's name (OpenCV's without `DICT_`) and OpenCV's id.
const DICTIONARIES: [(&str, i32); 21] = [
    ("4X4_50", aruco::DICT_4X4_50),
    ("4X4_100", aruco::DICT_4X4_100),
    ("4X4_250", aruco::DICT_4X4_250),
    ("4X4_1000", aruco::DICT_4X4_1000),
    ("5X5_50", aruco::DICT_5X5_50),
    ("5X5_100", aruco::DICT_5X5_100),
    ("5X5_250", aruco::DICT_5X5_250),
    ("5X5_1000", aruco::DICT_5X5_1000),
    ("6X6_50", aruco::DICT_6X6_50),
    ("6X6_100", aruco::DICT_6X6_100),
    ("6X6_250", aruco::DICT_6X6_250),
    ("6X6_1000", aruco::DICT_6X6_1000),
    ("7X7_50", aruco::DICT_7X7_50),
    ("7X7_100", aruco::DICT_7X7_100),
    ("7X7_250", aruco::DICT_7X7_250),
    ("7X7_1000", aruco::DICT_7X7_1000),
    ("ARUCO_ORIGINAL", aruco::DICT_ARUCO_ORIGINAL),
    ("APRILTAG_16h5", aruco::DICT_APRILTAG_16h5),
    ("APRILTAG_25h9", aruco::DICT_APRILTAG_25h9),
    ("APRILTAG_36h10", aruco::DICT_APRILTAG_36h10),
    ("APRILTAG_36h11", aruco::DICT_APRILTAG_36h11),
];

impl ArucoDictionary {
    /// The dictionary named `name` (OpenCV's name, with or without `DICT_`, any case).
    pub fn from_name(name: &str) -> Option<Self> {
        let n = name.trim();
        let n = n
            .strip_prefix("DICT_")
            .or_else(|| n.strip_prefix("dict_"))
            .unwrap_or(n);
        DICTIONARIES
            .iter()
            .position(|(d, _)| d.eq_ignore_ascii_case(n))
            .map(Self)
    }

    /// Every dictionary's name, comma-separated (for error messages).
    pub fn names() -> String {
        DICTIONARIES
            .iter()
            .map(|(d, _)| *d)
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// odocal's name of the dictionary (OpenCV's without `DICT_`), e.g. `4X4_50`.
    pub fn name(self) -> &'static str {
        DICTIONARIES[self.0].0
    }

    /// OpenCV's id of the dictionary.
    fn opencv_id(self) -> i32 {
        DICTIONARIES[self.0].1
    }

    /// OpenCV's dictionary.
    fn opencv(self) -> Result<Ptr<aruco::Dictionary>, CalibError> {
        Ok(aruco::get_predefined_dictionary_i32(self.opencv_id())?)
    }

    /// How many distinct markers the dictionary holds (as OpenCV defines it).
    pub fn marker_count(self) -> Result<usize, CalibError> {
        Ok(self.opencv()?.bytes_list().rows().max(0) as usize)
    }
}

impl fmt::Display for ArucoDictionary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl TryFrom<String> for ArucoDictionary {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        Self::from_name(&s).ok_or_else(|| {
            format!(
                "unknown ArUco dictionary {s:?}; one of {}",
                ArucoDictionary::names()
            )
        })
    }
}

impl From<ArucoDictionary> for String {
    fn from(d: ArucoDictionary) -> String {
        d.name().to_string()
    }
}

/// The squares across and down a ChArUco board of `board`'s inner corners.
fn squares(board: &BoardSpec) -> (i32, i32) {
    (board.cols as i32 + 1, board.rows as i32 + 1)
}

/// The marker side and dictionary of a ChArUco board, or an error for a checkerboard.
fn charuco_target(board: &BoardSpec) -> Result<(f64, ArucoDictionary), CalibError> {
    match board.target {
        BoardTarget::Charuco {
            marker_m,
            dictionary,
        } => Ok((marker_m, dictionary)),
        BoardTarget::Checkerboard => Err(CalibError::Input(
            "a checkerboard has no ArUco markers (--target charuco for a ChArUco board)".into(),
        )),
    }
}

/// OpenCV's ChArUco board for `board` (a `BoardTarget::Charuco` spec).
pub fn opencv_board(board: &BoardSpec) -> Result<Ptr<CharucoBoard>, CalibError> {
    let (marker_m, dictionary) = charuco_target(board)?;
    let (sx, sy) = squares(board);
    Ok(CharucoBoard::create(
        sx,
        sy,
        board.square_m as f32,
        marker_m as f32,
        &dictionary.opencv()?,
    )?)
}

/// Checks that OpenCV can make the board: at least 3x3 squares, markers smaller than the
/// squares, and no more markers than the dictionary holds. The message names the option.
pub fn check_board(board: &BoardSpec) -> Result<(), CalibError> {
    let (marker_m, dictionary) = charuco_target(board)?;
    let (sx, sy) = squares(board);
    if sx < 3 || sy < 3 {
        return Err(CalibError::Input(format!(
            "--board {sx}x{sy}: a ChArUco board needs at least 3x3 squares"
        )));
    }
    if !(marker_m.is_finite() && marker_m > 0.0 && marker_m < board.square_m) {
        return Err(CalibError::Input(format!(
            "--marker {marker_m}: the marker side must be more than 0 and less than --square {} (metres; each marker sits inside a white square)",
            board.square_m
        )));
    }
    let needed = (sx * sy / 2) as usize;
    let available = dictionary.marker_count()?;
    if needed > available {
        return Err(CalibError::Input(format!(
            "--board {sx}x{sy} carries {needed} markers but --dictionary {dictionary} has only {available}; use a dictionary with more markers (e.g. 4X4_100 or 5X5_250)"
        )));
    }
    Ok(())
}

/// The board's inner corners in odocal's board frame, metres, indexed by ChArUco id: OpenCV's
/// `chessboardCorners` moved so corner 0 is the origin.
pub fn charuco_points(board: &BoardSpec) -> Result<Vec<Point3<f64>>, CalibError> {
    let cb = opencv_board(board)?;
    let corners = cb.chessboard_corners();
    let first = corners
        .iter()
        .next()
        .ok_or_else(|| CalibError::Input("OpenCV's ChArUco board has no inner corner".into()))?;
    Ok(corners
        .iter()
        .map(|p| {
            Point3::new(
                p.x as f64 - first.x as f64,
                p.y as f64 - first.y as f64,
                p.z as f64 - first.z as f64,
            )
        })
        .collect())
}

/// A printed ChArUco board as OpenCV draws it, with a white margin one square wide, and where
/// odocal's board frame lies on it.
#[derive(Debug, Clone)]
pub struct BoardImage {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Grey levels (0 black, 255 white), row-major.
    pub pixels: Vec<u8>,
    /// Pixels per metre on the board.
    pub px_per_m: f64,
    /// Where the board frame's origin (inner corner 0) is in the image: the pixel edge
    /// coordinates (pixel `i` spans `i..i+1`), so a board point (x, y) lies in pixel
    /// `floor(origin + (x, y) * px_per_m)`.
    pub origin_px: (f64, f64),
}

impl BoardImage {
    /// The grey level printed at board-frame point (x, y), metres; `None` outside the
    /// printed sheet (board and margin).
    pub fn grey_at(&self, x: f64, y: f64) -> Option<u8> {
        let u = (self.origin_px.0 + x * self.px_per_m).floor();
        let v = (self.origin_px.1 + y * self.px_per_m).floor();
        if u < 0.0 || v < 0.0 || u >= self.width as f64 || v >= self.height as f64 {
            return None;
        }
        self.pixels
            .get(v as usize * self.width as usize + u as usize)
            .copied()
    }
}

/// OpenCV's image of the board (`CharucoBoard::draw`), `px_per_square` pixels per square, with
/// a white margin one square wide.
pub fn board_image(board: &BoardSpec, px_per_square: u32) -> Result<BoardImage, CalibError> {
    check_board(board)?;
    let mut cb = opencv_board(board)?;
    let (sx, sy) = squares(board);
    let pps = px_per_square.max(8) as i32;
    let margin = pps;
    let (w, h) = (sx * pps + 2 * margin, sy * pps + 2 * margin);
    let mut img = Mat::default();
    // The board fills the image inside the margin exactly (same aspect ratio, whole pixels per
    // square), so OpenCV's squares start at whole pixels: square (i, j) covers pixels
    // margin + i * pps .. margin + (i + 1) * pps.
    cb.draw(Size::new(w, h), &mut img, margin, 1)?;
    if img.cols() != w || img.rows() != h || img.typ() != core::CV_8UC1 {
        return Err(CalibError::Input(format!(
            "OpenCV drew a {}x{} ChArUco image of type {}, expected {w}x{h} 8-bit grey",
            img.cols(),
            img.rows(),
            img.typ()
        )));
    }
    let img = if img.is_continuous() {
        img
    } else {
        img.try_clone()?
    };
    let pixels = img.data_bytes()?.to_vec();
    let px_per_m = pps as f64 / board.square_m;
    // Corner 0 is the corner of squares (0, 0) and (1, 1): one square in from the margin.
    let origin = (margin + pps) as f64;
    Ok(BoardImage {
        width: w as u32,
        height: h as u32,
        pixels,
        px_per_m,
        origin_px: (origin, origin),
    })
}

/// The ChArUco corners found in one image.
#[derive(Debug, Clone, PartialEq)]
pub struct CharucoCorners {
    /// Corner positions, pixels.
    pub corners: Vec<Point2<f64>>,
    /// Each corner's ChArUco id (its index among the board's inner corners).
    pub ids: Vec<u32>,
    /// Each corner's position on the board (odocal's board frame, z = 0), metres.
    pub object_points: Vec<Point3<f64>>,
    /// How many of the board's markers were found.
    pub markers: usize,
    /// The board is laid out as OpenCV before 4.6 drew boards of an even number of rows
    /// ([`legacy_marker_ids`]).
    pub legacy_layout: bool,
}

/// Finds the board's ChArUco corners in a grey image: OpenCV's marker detection, a check that
/// the markers sit where the board puts them, OpenCV's interpolation of the chessboard corners
/// between the markers (each corner needs both its neighbouring markers), then odocal's
/// sub-pixel refinement (`refine_corner`: OpenCV 4.6's interpolated corners lie about 0.45
/// px right of and below the true ones, on OpenCV's own drawing as on rendered views, and
/// cornerSubPix alone is pulled by the markers' edges). `Ok(Err(reason))` when the view
/// cannot be used: no marker of the board, markers where the board has none, too few
/// corners, or all on one line.
pub fn find_charuco_corners(
    gray: &Mat,
    board: &BoardSpec,
) -> Result<Result<CharucoCorners, String>, CalibError> {
    let (marker_m, dictionary) = charuco_target(board)?;
    if gray.empty() || gray.typ() != core::CV_8UC1 {
        return Err(CalibError::Input(format!(
            "ChArUco detection needs an 8-bit grey image, got a {}x{} image of OpenCV type {}",
            gray.cols(),
            gray.rows(),
            gray.typ()
        )));
    }
    let cb = opencv_board(board)?;
    let dict = dictionary.opencv()?;
    let params = aruco::DetectorParameters::create()?;
    let mut marker_corners = Vector::<Vector<Point2f>>::new();
    let mut marker_ids = Vector::<i32>::new();
    let mut rejected = Vector::<Vector<Point2f>>::new();
    aruco::detect_markers(
        gray,
        &dict,
        &mut marker_corners,
        &mut marker_ids,
        &params,
        &mut rejected,
    )?;
    // Markers of the same dictionary that are not on this board (another board in view, or an
    // id beyond this board's) would be interpolated into nonsense corners.
    let (sx, sy) = squares(board);
    let n_markers = sx * sy / 2;
    let mut corners_on = Vector::<Vector<Point2f>>::new();
    let mut ids_on = Vector::<i32>::new();
    for (c, id) in marker_corners.iter().zip(marker_ids.iter()) {
        if (0..n_markers).contains(&id) {
            corners_on.push(c);
            ids_on.push(id);
        }
    }
    let markers = ids_on.len();
    if markers == 0 {
        return Ok(Err(match marker_ids.iter().max() {
            Some(top) => format!(
                "{} {dictionary} markers found, ids up to {top}, but a {} carries ids 0-{}: --board counts the squares",
                marker_ids.len(),
                board_name(board),
                n_markers - 1
            ),
            None => match median_side_px(&rejected).filter(|side| *side < MIN_MARKER_SIDE_PX) {
                // Outlines found but no marker read: the markers are there, too small to read.
                Some(side) if rejected.len() >= MIN_UNREAD_OUTLINES => format!(
                    "no {dictionary} marker of the {} could be read: {} square outlines {side:.0} px across (median) were found, too few pixels to read a marker's cells ({MIN_MARKER_SIDE_PX:.0} px or more needed); use larger squares and markers, views from closer, or a higher resolution",
                    board_name(board),
                    rejected.len()
                ),
                _ => format!("no {dictionary} marker of the {} found", board_name(board)),
            },
        }));
    }
    // A stray false detection is left out above; many markers beyond the board's ids mean a
    // larger board than --board says, whose other markers sit elsewhere too.
    let beyond: Vec<i32> = marker_ids.iter().filter(|&i| i >= n_markers).collect();
    if let Some(&top) = beyond.iter().max().filter(|_| beyond.len() >= 2) {
        return Ok(Err(format!(
            "{dictionary} markers with ids up to {top} found, but a {} carries ids 0-{}: is the board larger? --board counts the squares",
            board_name(board),
            n_markers - 1
        )));
    }
    // A board of the layout before OpenCV 4.6 passes the check below on most views (its
    // markers sit a square right of the current layout's, all but one per row pair), but
    // its corners would be misassigned: the layout whose markers agree better is taken.
    let legacy = legacy_marker_ids(&cb, board)?;
    let mut legacy_layout = false;
    let mut agreement = layout_agreement(&cb, &corners_on, &ids_on)?;
    if let Some(to_current) = &legacy {
        let (lc, li) = legacy_to_current(&corners_on, &ids_on, to_current);
        let legacy_agree = layout_agreement(&cb, &lc, &li)?;
        if legacy_agree > agreement {
            legacy_layout = true;
            agreement = legacy_agree;
            corners_on = lc;
            ids_on = li;
        }
    }
    if let Some(agree) = agreement {
        // On the right board all but a stray pair agree (measured 99-100 % on the synthetic
        // views); a wrong width or marker ratio leaves 40-65 %.
        if agree < MIN_LAYOUT_AGREEMENT {
            return Ok(Err(format!(
                "the {markers} markers found do not sit where a {} with {} m squares and {} m markers puts them (only {:.0} % of neighbouring markers agree): check --board (squares), --square and --marker",
                board_name(board),
                board.square_m,
                marker_m,
                agree * 100.0
            )));
        }
    }
    let mut cc = Vector::<Point2f>::new();
    let mut cids = Vector::<i32>::new();
    aruco::interpolate_corners_charuco(
        &corners_on,
        &ids_on,
        gray,
        &cb,
        &mut cc,
        &mut cids,
        &core::no_array(),
        &core::no_array(),
        2,
    )?;
    let object = charuco_points(board)?;
    let copy;
    let gray = if gray.is_continuous() {
        gray
    } else {
        copy = gray.try_clone()?;
        &copy
    };
    let image = GreyImage {
        px: gray.data_bytes()?,
        width: gray.cols().max(0) as usize,
        height: gray.rows().max(0) as usize,
    };
    let nearest = cb.nearest_marker_idx();
    let board_ids = cb.ids();
    let mut corners = Vec::new();
    let mut ids = Vec::new();
    for (p, id) in cc.iter().zip(cids.iter()) {
        let Some(id) = u32::try_from(id)
            .ok()
            .filter(|&i| (i as usize) < object.len())
        else {
            continue;
        };
        // The detected markers in the two white squares at the corner.
        let beside: Vec<Vec<(f64, f64)>> = nearest
            .get(id as usize)
            .map(|v| v.iter().collect::<Vec<i32>>())
            .unwrap_or_default()
            .into_iter()
            .filter_map(|idx| board_ids.get(idx.max(0) as usize).ok())
            .filter_map(|marker| ids_on.iter().position(|m| m == marker))
            .filter_map(|k| corners_on.get(k).ok())
            .map(|quad| {
                quad.iter()
                    .map(|c| (c.x as f64, c.y as f64))
                    .collect::<Vec<_>>()
            })
            .collect();
        let Some(half) = refine_half_window(&beside, board.square_m / marker_m) else {
            continue;
        };
        // A window reaching past the image's edge would see no board there.
        let reach = f64::from(half) + 2.0;
        let (x, y) = (p.x as f64, p.y as f64);
        if x < reach
            || y < reach
            || x > image.width as f64 - 1.0 - reach
            || y > image.height as f64 - 1.0 - reach
        {
            continue;
        }
        if let Some(q) = refine_corner(&image, (x, y), half, &beside) {
            corners.push(Point2::new(q.0, q.1));
            ids.push(id);
        }
    }
    if ids.len() < MIN_CHARUCO_CORNERS {
        // Markers found but too small to place the corners between them is a matter of
        // pixels, not of the options that describe the board.
        let small = median_side_px(&corners_on)
            .filter(|side| *side < MIN_MARKER_SIDE_PX)
            .map(|side| {
                format!(
                    ": its markers are {side:.0} px across (median), too few pixels to place the corners between them ({MIN_MARKER_SIDE_PX:.0} px or more needed); use larger squares and markers, views from closer, or a higher resolution"
                )
            })
            .unwrap_or_default();
        return Ok(Err(format!(
            "only {} ChArUco corner(s) of the {} found ({markers} marker(s)); at least {MIN_CHARUCO_CORNERS} needed{small}",
            ids.len(),
            board_name(board)
        )));
    }
    let id_vec: Vector<i32> = ids.iter().map(|&i| i as i32).collect();
    if aruco::test_charuco_corners_collinear(&cb, &id_vec)? {
        return Ok(Err(format!(
            "the {} ChArUco corners found lie on one line of the board; they cannot fix its pose",
            ids.len()
        )));
    }
    // Back to the printed board's own numbering and frame, so the floor frame is the same
    // corner 0, x along its rows and y down it, whichever layout the board has.
    if legacy_layout {
        for id in &mut ids {
            *id = mirrored_corner(*id, board);
        }
    }
    let object_points = ids.iter().map(|&i| object[i as usize]).collect();
    Ok(Ok(CharucoCorners {
        corners,
        ids,
        object_points,
        markers,
        legacy_layout,
    }))
}

/// Half the side of a corner's sub-pixel window, pixels: 0.4 of the smallest side of a
/// square beside it in the image (from the markers' sides and the square-to-marker ratio),
/// so the window holds the corner's own two edges and nothing of the next squares; at most
/// 11. `None` when that is under [`MIN_HALF_WINDOW_PX`] (squares under 5 px are not measured).
fn refine_half_window(markers: &[Vec<(f64, f64)>], square_per_marker: f64) -> Option<i32> {
    let side = markers
        .iter()
        .flat_map(|q| {
            (0..q.len()).map(move |i| {
                let (a, b) = (q[i], q[(i + 1) % q.len()]);
                (a.0 - b.0).hypot(a.1 - b.1)
            })
        })
        .fold(f64::INFINITY, f64::min);
    if !side.is_finite() {
        return None;
    }
    let half = (0.4 * side * square_per_marker).floor().min(11.0) as i32;
    (half >= MIN_HALF_WINDOW_PX).then_some(half)
}

/// Markers smaller than this (side, pixels) are read, but the corners between them are not
/// placed reliably: the synthetic ChArUco views place them from 13 px markers on.
pub const MIN_MARKER_SIDE_PX: f64 = 12.0;

/// Square outlines that OpenCV found but could not read as markers, fewest that name markers
/// too small to read (rather than a few stray quadrilaterals in a view of no board).
const MIN_UNREAD_OUTLINES: usize = 4;

/// The median side of quadrilaterals (OpenCV's marker corners), pixels; None for none.
fn median_side_px(quads: &Vector<Vector<Point2f>>) -> Option<f64> {
    let mut sides: Vec<f64> = quads
        .iter()
        .map(|q| {
            let q: Vec<Point2f> = q.iter().collect();
            (0..q.len())
                .map(|i| {
                    let (a, b) = (q[i], q[(i + 1) % q.len()]);
                    f64::from(a.x - b.x).hypot(f64::from(a.y - b.y))
                })
                .sum::<f64>()
                / q.len().max(1) as f64
        })
        .collect();
    sides.sort_by(f64::total_cmp);
    sides.get(sides.len() / 2).copied()
}

/// The smallest half window (pixels) that refines a corner: a 5x5 window.
const MIN_HALF_WINDOW_PX: i32 = 2;

/// Pixels whose gradient could hold a marker's edge are left out of a corner's refinement: at
/// least those within this distance (pixels) of a detected marker's outline beyond the one
/// pixel the gradient's stencil reaches (for the marker's blurred edge and the error of its
/// contour-found corners).
const MARKER_GUARD_PX: f64 = 1.0;

/// An 8-bit grey image for sub-pixel sampling.
struct GreyImage<'a> {
    px: &'a [u8],
    width: usize,
    height: usize,
}

impl GreyImage<'_> {
    /// The grey level at (x, y) (integer coordinates at pixel centres), bilinear, clamped at
    /// the edges.
    fn at(&self, x: f64, y: f64) -> f64 {
        let (w, h) = (self.width as f64, self.height as f64);
        let x = x.clamp(0.0, w - 1.0);
        let y = y.clamp(0.0, h - 1.0);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (i, j) = (x0 as usize, y0 as usize);
        let i1 = (i + 1).min(self.width - 1);
        let j1 = (j + 1).min(self.height - 1);
        let g = |u: usize, v: usize| f64::from(self.px[v * self.width + u]);
        (1.0 - fy) * ((1.0 - fx) * g(i, j) + fx * g(i1, j))
            + fy * ((1.0 - fx) * g(i, j1) + fx * g(i1, j1))
    }
}

/// The distance from `p` to the convex polygon `poly` (0 inside), pixels.
fn distance_to_polygon(p: (f64, f64), poly: &[(f64, f64)]) -> f64 {
    let n = poly.len();
    let mut inside = n >= 3;
    let mut sign = 0.0f64;
    let mut best = f64::INFINITY;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let (ex, ey) = (b.0 - a.0, b.1 - a.1);
        let (px, py) = (p.0 - a.0, p.1 - a.1);
        let cross = ex * py - ey * px;
        if sign == 0.0 {
            sign = cross.signum();
        } else if cross * sign < 0.0 {
            inside = false;
        }
        let len2 = ex * ex + ey * ey;
        let t = if len2 > 0.0 {
            ((px * ex + py * ey) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        best = best.min((px - t * ex).hypot(py - t * ey));
    }
    if inside {
        0.0
    } else {
        best
    }
}

/// Refines a chessboard corner to sub-pixel as OpenCV's cornerSubPix does (the corner is the
/// point every edge pixel's gradient is perpendicular to, weighted by a Gaussian over the
/// window, iterated to 0.001 px), but leaving out the pixels at the markers beside the corner:
/// a ChArUco marker's border sits (square − marker) / 2 from the corner, close enough to pull
/// cornerSubPix's estimate by pixels on a board seen at a slant. `None` when the window holds
/// no corner (a single edge, or the estimate runs off).
fn refine_corner(
    image: &GreyImage<'_>,
    start: (f64, f64),
    half: i32,
    markers: &[Vec<(f64, f64)>],
) -> Option<(f64, f64)> {
    let h = f64::from(half);
    // The white channel between the corner's edges and a marker is (square - marker) / 2
    // wide, and the marker's nearest corner lies diagonally across it from the corner. Pixels
    // beyond the channel's middle see the marker's edge more than the corner's: they are left
    // out, and always those whose gradient stencil reaches within a pixel of the marker.
    let channel = markers
        .iter()
        .map(|m| distance_to_polygon(start, m))
        .fold(f64::INFINITY, f64::min)
        / std::f64::consts::SQRT_2;
    let guard = (channel / 2.0).max(1.0 + MARKER_GUARD_PX);
    let mut c = start;
    for _ in 0..50 {
        let (mut a, mut b, mut d) = (0.0, 0.0, 0.0);
        let (mut bx, mut by) = (0.0, 0.0);
        for j in -half..=half {
            for i in -half..=half {
                let (dx, dy) = (f64::from(i), f64::from(j));
                let x = (c.0 + dx, c.1 + dy);
                if markers.iter().any(|m| distance_to_polygon(x, m) < guard) {
                    continue;
                }
                let gx = (image.at(x.0 + 1.0, x.1) - image.at(x.0 - 1.0, x.1)) / 2.0;
                let gy = (image.at(x.0, x.1 + 1.0) - image.at(x.0, x.1 - 1.0)) / 2.0;
                let w = (-(dx * dx + dy * dy) / (h * h)).exp();
                let (gxx, gxy, gyy) = (w * gx * gx, w * gx * gy, w * gy * gy);
                a += gxx;
                b += gxy;
                d += gyy;
                bx += gxx * x.0 + gxy * x.1;
                by += gxy * x.0 + gyy * x.1;
            }
        }
        // Two edges crossing make both eigenvalues of the gradients' scatter large; one edge
        // alone leaves the corner free to slide along it.
        let det = a * d - b * b;
        let tr = a + d;
        let disc = ((a - d) * (a - d) + 4.0 * b * b).sqrt();
        let (lmin, lmax) = ((tr - disc) / 2.0, (tr + disc) / 2.0);
        if !(det > 0.0 && lmax > 0.0 && lmin / lmax > MIN_EDGE_BALANCE) {
            return None;
        }
        let q = ((d * bx - b * by) / det, (a * by - b * bx) / det);
        let moved = (q.0 - c.0).hypot(q.1 - c.1);
        c = q;
        if (c.0 - start.0).hypot(c.1 - start.1) > h.max(2.0) {
            return None;
        }
        if moved < 1e-3 {
            return Some(c);
        }
    }
    Some(c)
}

/// The smallest ratio of the two eigenvalues of a corner window's gradient scatter: below it
/// the window sees one edge, not two crossing (edges 15° apart give 0.02).
const MIN_EDGE_BALANCE: f64 = 0.01;

/// OpenCV 4.6 changed the layout of ChArUco boards with an even number of rows of squares
/// (opencv_contrib#3291): before it, the top-left square is white and holds marker 0; from it,
/// black. Boards printed with an older OpenCV (or a newer one's `setLegacyPattern`, or
/// calib.io's legacy option) are the current board mirrored top to bottom with its markers
/// renumbered row by row from the top: the legacy board's marker squares mirrored are the
/// current board's (an odd number of rows, less one, keeps the squares' colours). For each
/// legacy marker id, the current board's id of the marker at its mirrored square; `None` for
/// an odd number of rows, where the layouts are one.
fn legacy_marker_ids(
    cb: &Ptr<CharucoBoard>,
    board: &BoardSpec,
) -> Result<Option<Vec<i32>>, CalibError> {
    let (_, sy) = squares(board);
    if sy % 2 != 0 {
        return Ok(None);
    }
    let square = cb.get_square_length()? as f64;
    let mut mirrored = Vec::new();
    for (obj, id) in cb.obj_points().iter().zip(cb.ids().iter()) {
        let (x, y) = obj.iter().fold((0.0, 0.0), |a, p| {
            (a.0 + p.x as f64 / 4.0, a.1 + p.y as f64 / 4.0)
        });
        let (qx, qy) = ((x / square).floor() as i32, (y / square).floor() as i32);
        mirrored.push(((sy - 1 - qy, qx), id));
    }
    mirrored.sort_by_key(|(square, _)| *square);
    Ok(Some(mirrored.into_iter().map(|(_, id)| id).collect()))
}

/// Markers of a legacy board as the current board's: ids renumbered, and each outline's
/// corners reordered so the first is again the top-left on the mirrored board.
fn legacy_to_current(
    corners: &Vector<Vector<Point2f>>,
    ids: &Vector<i32>,
    to_current: &[i32],
) -> (Vector<Vector<Point2f>>, Vector<i32>) {
    let mut out_corners = Vector::<Vector<Point2f>>::new();
    let mut out_ids = Vector::<i32>::new();
    for (quad, id) in corners.iter().zip(ids.iter()) {
        let Some(&current) = usize::try_from(id).ok().and_then(|i| to_current.get(i)) else {
            continue;
        };
        let q: Vec<Point2f> = quad.iter().collect();
        if q.len() != 4 {
            continue;
        }
        out_corners.push([q[3], q[2], q[1], q[0]].into_iter().collect());
        out_ids.push(current);
    }
    (out_corners, out_ids)
}

/// The id of the inner corner at the mirrored place (top to bottom): corner ids are row-major.
fn mirrored_corner(id: u32, board: &BoardSpec) -> u32 {
    let (r, c) = (id / board.cols, id % board.cols);
    (board.rows - 1 - r) * board.cols + c
}

/// The fraction of neighbouring marker pairs that sit where the board says: each marker's
/// own corners give the homography of its square of the board, which predicts where its
/// diagonal neighbours' centres must be (near enough for lens distortion not to matter). A
/// wrong `--board` (OpenCV numbers the markers row by row, so another width moves them) or a
/// board of the other layout puts them a square or more away, and a marker-to-square ratio
/// wrong by a third of itself half a square; within half a square, the midpoint, a neighbour
/// agrees. Half a marker side was too
/// tight for markers a few pixels across, whose corners are found to a pixel or so: that
/// error, carried a marker and a half by the homography, failed pairs of 960x640 views and
/// made 480x320 views read as of the other layout. `None` when no two markers are
/// neighbours.
fn layout_agreement(
    board: &Ptr<CharucoBoard>,
    corners: &Vector<Vector<Point2f>>,
    ids: &Vector<i32>,
) -> Result<Option<f64>, CalibError> {
    let objects = board.obj_points();
    let board_ids = board.ids();
    let square = board.get_square_length()? as f64;
    let square_per_marker = square / board.get_marker_length()? as f64;
    let mut markers = Vec::new();
    for (quad, id) in corners.iter().zip(ids.iter()) {
        let Some(k) = board_ids.iter().position(|b| b == id) else {
            continue;
        };
        let obj = objects.get(k)?;
        if obj.len() != 4 || quad.len() != 4 {
            continue;
        }
        let src: Vector<Point2f> = obj.iter().map(|p| Point2f::new(p.x, p.y)).collect();
        let h = opencv::imgproc::get_perspective_transform(&src, &quad, core::DECOMP_LU)?;
        let mut m = [[0.0f64; 3]; 3];
        for (r, row) in m.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = *h.at_2d::<f64>(r as i32, c as i32)?;
            }
        }
        let centre_obj = obj.iter().fold((0.0, 0.0), |a, p| {
            (a.0 + p.x as f64 / 4.0, a.1 + p.y as f64 / 4.0)
        });
        let centre_img = quad.iter().fold((0.0, 0.0), |a, p| {
            (a.0 + p.x as f64 / 4.0, a.1 + p.y as f64 / 4.0)
        });
        let side_px = (0..4)
            .map(|i| {
                let (a, b) = (quad.get(i)?, quad.get((i + 1) % 4)?);
                Ok(((a.x - b.x) as f64).hypot((a.y - b.y) as f64))
            })
            .sum::<Result<f64, opencv::Error>>()?
            / 4.0;
        markers.push((m, centre_obj, centre_img, side_px));
    }
    let (mut pairs, mut agree) = (0usize, 0usize);
    for (i, (h, oi, _, _)) in markers.iter().enumerate() {
        for (j, (_, oj, cj, side)) in markers.iter().enumerate() {
            let d = (oi.0 - oj.0).hypot(oi.1 - oj.1);
            if i == j || d > 1.5 * square {
                continue;
            }
            let w = h[2][0] * oj.0 + h[2][1] * oj.1 + h[2][2];
            if w.abs() < 1e-12 {
                continue;
            }
            let u = (h[0][0] * oj.0 + h[0][1] * oj.1 + h[0][2]) / w;
            let v = (h[1][0] * oj.0 + h[1][1] * oj.1 + h[1][2]) / w;
            pairs += 1;
            if (u - cj.0).hypot(v - cj.1) < 0.5 * side * square_per_marker {
                agree += 1;
            }
        }
    }
    Ok((pairs > 0).then(|| agree as f64 / pairs as f64))
}

/// How many markers of each predefined dictionary the image at `path` shows, in the
/// dictionaries' order (None when the image cannot be read).
fn marker_counts(path: &std::path::Path) -> Option<Vec<(ArucoDictionary, usize)>> {
    let gray = crate::detect::read_gray(path).ok()?;
    let params = aruco::DetectorParameters::create().ok()?;
    let count = |d: ArucoDictionary| -> Option<usize> {
        let dict = d.opencv().ok()?;
        let mut corners = Vector::<Vector<Point2f>>::new();
        let mut ids = Vector::<i32>::new();
        let mut rejected = Vector::<Vector<Point2f>>::new();
        aruco::detect_markers(&gray, &dict, &mut corners, &mut ids, &params, &mut rejected).ok()?;
        Some(ids.len())
    };
    Some(
        (0..DICTIONARIES.len())
            .map(ArucoDictionary)
            .filter_map(|d| count(d).map(|n| (d, n)))
            .collect(),
    )
}

/// The predefined dictionary whose markers are most numerous in the image at `path`, with
/// their count, when it finds more than `given` does (and more than three): a hint when no
/// board of the given dictionary is found.
pub fn guess_dictionary(
    path: &std::path::Path,
    given: ArucoDictionary,
) -> Option<(ArucoDictionary, usize)> {
    let counts = marker_counts(path)?;
    let floor = counts
        .iter()
        .find(|(d, _)| *d == given)
        .map_or(0, |(_, n)| *n)
        .max(3);
    most_numerous(&counts).filter(|(_, n)| *n > floor)
}

/// The predefined dictionary whose markers are most numerous in the image at `path`, with
/// their count, when there are more than three: a checkerboard's image that shows a ChArUco
/// board's markers.
pub fn markers_seen(path: &std::path::Path) -> Option<(ArucoDictionary, usize)> {
    most_numerous(&marker_counts(path)?).filter(|(_, n)| *n > 3)
}

/// Smaller dictionaries come first and are prefixes of the larger ones of their family: the
/// first that finds the most markers.
fn most_numerous(counts: &[(ArucoDictionary, usize)]) -> Option<(ArucoDictionary, usize)> {
    let mut best: Option<(ArucoDictionary, usize)> = None;
    for &(d, n) in counts {
        if best.is_none_or(|(_, b)| n > b) {
            best = Some((d, n));
        }
    }
    best
}

/// "11x8 ChArUco board" (squares) or "9x6 checkerboard" (inner corners).
pub fn board_name(board: &BoardSpec) -> String {
    match board.target {
        BoardTarget::Checkerboard => format!("{}x{} checkerboard", board.cols, board.rows),
        BoardTarget::Charuco { .. } => {
            let (sx, sy) = squares(board);
            format!("{sx}x{sy} ChArUco board")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> BoardSpec {
        BoardSpec {
            cols: 10,
            rows: 7,
            square_m: 0.04,
            target: BoardTarget::Charuco {
                marker_m: 0.03,
                dictionary: ArucoDictionary::from_name("4X4_50").expect("known"),
            },
        }
    }

    #[test]
    fn dictionary_names_round_trip() {
        for (name, _) in DICTIONARIES {
            let d = ArucoDictionary::from_name(name).expect("known");
            assert_eq!(d.name(), name);
            let json = serde_json::to_string(&d).expect("json");
            assert_eq!(
                serde_json::from_str::<ArucoDictionary>(&json).expect("back"),
                d
            );
        }
        assert_eq!(
            ArucoDictionary::from_name("dict_4x4_50"),
            ArucoDictionary::from_name("4X4_50")
        );
        assert!(ArucoDictionary::from_name("4X4_51").is_none());
        assert_eq!(
            ArucoDictionary::from_name("4X4_50").map(|d| d.marker_count().ok()),
            Some(Some(50))
        );
    }

    /// OpenCV's corners, moved to corner 0, are odocal's grid of inner corners.
    #[test]
    fn opencv_corners_are_the_inner_corner_grid() {
        let b = spec();
        let ours = crate::board_points(&b);
        let opencv = charuco_points(&b).expect("board");
        assert_eq!(ours.len(), opencv.len());
        for (a, c) in ours.iter().zip(&opencv) {
            assert!((a - c).norm() < 1e-6, "{a} vs {c}");
        }
    }

    #[test]
    fn bad_boards_name_the_option() {
        let mut b = spec();
        b.target = BoardTarget::Charuco {
            marker_m: 0.05,
            dictionary: ArucoDictionary::from_name("4X4_50").expect("known"),
        };
        assert!(check_board(&b)
            .unwrap_err()
            .to_string()
            .contains("--marker"));
        let mut b = spec();
        b.cols = 1;
        assert!(check_board(&b).unwrap_err().to_string().contains("3x3"));
        let mut b = spec();
        b.cols = 14;
        b.rows = 9;
        let e = check_board(&b).unwrap_err().to_string();
        assert!(e.contains("75 markers") && e.contains("only 50"), "{e}");
    }
}
