//! ChArUco detection checked against OpenCV alone: OpenCV draws its own ChArUco board
//! (`CharucoBoard::draw`, not odocal's renderer), the image is warped by a known homography,
//! and odocal must find every corner where OpenCV's board geometry and the homography put it.

use nalgebra::{Matrix3, Point2, Vector2, Vector3};
use odocal_calib::charuco::{find_charuco_corners, CharucoCorners};
use odocal_calib::{ArucoDictionary, BoardSpec, BoardTarget};
use opencv::aruco::{self, CharucoBoardTrait, CharucoBoardTraitConst};
use opencv::core::{self, Mat, Point2f, Scalar, Size, Vector};
use opencv::imgproc;
use opencv::prelude::*;

const SQUARES: (i32, i32) = (11, 8);
const SQUARE_M: f32 = 0.04;
const MARKER_M: f32 = 0.03;
/// Pixels per square of OpenCV's drawing, and its white margin.
const PPS: i32 = 40;

fn spec() -> BoardSpec {
    BoardSpec {
        cols: SQUARES.0 as u32 - 1,
        rows: SQUARES.1 as u32 - 1,
        square_m: SQUARE_M as f64,
        target: BoardTarget::Charuco {
            marker_m: MARKER_M as f64,
            dictionary: ArucoDictionary::from_name("4X4_50").expect("known dictionary"),
        },
    }
}

/// OpenCV's drawing of the board and its inner corners in OpenCV's board frame (metres).
fn opencv_board() -> (Mat, Vec<(f64, f64)>) {
    let dict = aruco::get_predefined_dictionary_i32(aruco::DICT_4X4_50).expect("dictionary");
    let mut board = aruco::CharucoBoard::create(SQUARES.0, SQUARES.1, SQUARE_M, MARKER_M, &dict)
        .expect("board");
    let mut img = Mat::default();
    let size = Size::new(SQUARES.0 * PPS + 2 * PPS, SQUARES.1 * PPS + 2 * PPS);
    board.draw(size, &mut img, PPS, 1).expect("draw");
    let corners = board
        .chessboard_corners()
        .iter()
        .map(|p| (p.x as f64, p.y as f64))
        .collect();
    (img, corners)
}

/// Where the whole board's outer corners go in a view that tilts it in perspective, pixels.
const WHOLE_BOARD_TILTED: [(f32, f32); 4] = [
    (180.0, 110.0),
    (1100.0, 60.0),
    (1190.0, 660.0),
    (120.0, 620.0),
];

/// The homography taking the drawing's four outer corners to `quad` (pixels).
fn homography(img: &Mat, quad: [(f32, f32); 4]) -> Matrix3<f64> {
    let (w, h) = (img.cols() as f32 - 0.5, img.rows() as f32 - 0.5);
    let src: Vector<Point2f> = [(-0.5, -0.5), (w, -0.5), (w, h), (-0.5, h)]
        .iter()
        .map(|&(x, y)| Point2f::new(x, y))
        .collect();
    let dst: Vector<Point2f> = quad.iter().map(|&(x, y)| Point2f::new(x, y)).collect();
    let m = imgproc::get_perspective_transform(&src, &dst, core::DECOMP_LU).expect("homography");
    Matrix3::from_fn(|r, c| *m.at_2d::<f64>(r as i32, c as i32).expect("element"))
}

/// The drawing warped by `h` into a 1280x720 grey image, blurred like a lens (σ 1 px).
fn warp(img: &Mat, h: &Matrix3<f64>) -> Mat {
    let hm = Mat::from_slice_2d(&[
        [h[(0, 0)], h[(0, 1)], h[(0, 2)]],
        [h[(1, 0)], h[(1, 1)], h[(1, 2)]],
        [h[(2, 0)], h[(2, 1)], h[(2, 2)]],
    ])
    .expect("matrix");
    let mut out = Mat::default();
    imgproc::warp_perspective(
        img,
        &mut out,
        &hm,
        Size::new(1280, 720),
        imgproc::INTER_LINEAR,
        core::BORDER_CONSTANT,
        Scalar::all(128.0),
    )
    .expect("warp");
    let mut blurred = Mat::default();
    imgproc::gaussian_blur(
        &out,
        &mut blurred,
        Size::new(0, 0),
        1.0,
        1.0,
        core::BORDER_REPLICATE,
    )
    .expect("blur");
    blurred
}

/// Where corner (x, y) of OpenCV's board frame (metres) lies in the warped image: OpenCV draws
/// square (i, j) over pixels PPS + i PPS .. PPS + (i + 1) PPS of the drawing, so a board point
/// lies at pixel-centre coordinate PPS + x / square PPS − 0.5, then through `h`.
fn predicted(h: &Matrix3<f64>, (x, y): (f64, f64)) -> Point2<f64> {
    let s = PPS as f64 / SQUARE_M as f64;
    let p = h * Vector3::new(PPS as f64 + x * s - 0.5, PPS as f64 + y * s - 0.5, 1.0);
    Point2::new(p.x / p.z, p.y / p.z)
}

/// RMS and largest distance (pixels) of the found corners from their predicted places, and
/// the mean offset (a bias would show there).
fn errors(
    found: &CharucoCorners,
    h: &Matrix3<f64>,
    corners: &[(f64, f64)],
) -> (f64, f64, Vector2<f64>) {
    let d: Vec<Vector2<f64>> = found
        .corners
        .iter()
        .zip(&found.ids)
        .map(|(p, &id)| p - predicted(h, corners[id as usize]))
        .collect();
    let n = d.len() as f64;
    let rms = (d.iter().map(|v| v.norm_squared()).sum::<f64>() / n).sqrt();
    let max = d.iter().map(|v| v.norm()).fold(0.0, f64::max);
    (rms, max, d.iter().sum::<Vector2<f64>>() / n)
}

#[test]
fn opencv_drawn_board_is_found_where_opencv_geometry_puts_it() {
    let (img, corners) = opencv_board();
    let first = corners[0];
    let h = homography(&img, WHOLE_BOARD_TILTED);
    let view = warp(&img, &h);
    let found = find_charuco_corners(&view, &spec())
        .expect("OpenCV runs")
        .expect("board found");
    assert_eq!(found.ids.len(), corners.len(), "every inner corner found");
    let (rms, max, mean) = errors(&found, &h, &corners);
    println!(
        "whole board: {} corners, error RMS {rms:.4} px, max {max:.4} px, mean ({:.4}, {:.4}) px",
        found.ids.len(),
        mean.x,
        mean.y
    );
    assert!(rms < 0.06 && max < 0.15, "RMS {rms} px, max {max} px");
    assert!(mean.norm() < 0.02, "bias {mean:?} px");
    // Each corner's board position is OpenCV's, moved to corner 0.
    for (p, &id) in found.object_points.iter().zip(&found.ids) {
        let (x, y) = corners[id as usize];
        assert!((p.x - (x - first.0)).abs() < 1e-9 && (p.y - (y - first.1)).abs() < 1e-9);
        assert_eq!(p.z, 0.0);
    }

    // A third of the board beyond the image's right edge: the corners inside are found, with
    // their ids, and nothing beyond the edge.
    let h = homography(
        &img,
        [
            (700.0, 150.0),
            (1500.0, 120.0),
            (1560.0, 640.0),
            (660.0, 600.0),
        ],
    );
    let view = warp(&img, &h);
    let found = find_charuco_corners(&view, &spec())
        .expect("OpenCV runs")
        .expect("part of the board found");
    let inside = corners
        .iter()
        .filter(|&&c| {
            let p = predicted(&h, c);
            p.x > 10.0 && p.x < 1270.0 && p.y > 10.0 && p.y < 710.0
        })
        .count();
    let (rms, max, _) = errors(&found, &h, &corners);
    println!(
        "partial board: {} of {} corners found ({inside} inside the image), error RMS {rms:.4} px, max {max:.4} px",
        found.ids.len(),
        corners.len()
    );
    assert!(
        found.ids.len() * 10 >= inside * 8,
        "most corners in view found"
    );
    for &id in &found.ids {
        let p = predicted(&h, corners[id as usize]);
        assert!(
            p.x < 1280.0,
            "corner {id} found, but it lies beyond the image at {p}"
        );
    }
    assert!(rms < 0.06 && max < 0.15, "RMS {rms} px, max {max} px");
}

/// Views holding too little of the board are skipped with their reason: a sliver with one
/// marker gives no corner, one with a single column of corners cannot fix the board's pose.
#[test]
fn a_sliver_of_the_board_is_too_little() {
    let (img, _) = opencv_board();
    // Only the board's leftmost squares stay inside the image's right edge: about half a
    // square, then about two.
    for (left, needle) in [(1150.0, "at least 6 needed"), (1000.0, "lie on one line")] {
        let h = homography(
            &img,
            [
                (left, 150.0),
                (left + 1150.0, 120.0),
                (left + 1210.0, 640.0),
                (left - 40.0, 600.0),
            ],
        );
        let reason = find_charuco_corners(&warp(&img, &h), &spec())
            .expect("OpenCV runs")
            .expect_err("too little of the board");
        println!("{reason}");
        assert!(reason.contains(needle), "{reason}");
    }
}

/// OpenCV's own ChArUco board given as a checkerboard, or with another dictionary: the error
/// names the target and the dictionary the image shows.
#[test]
fn a_charuco_board_given_as_another_target_is_named() {
    let (img, _) = opencv_board();
    // A third of the board outside the image, as wide-lens sessions take it: no whole
    // checkerboard is in view (a whole ChArUco board is one, and is found as one).
    let h = homography(
        &img,
        [
            (-420.0, 110.0),
            (900.0, 60.0),
            (990.0, 660.0),
            (-480.0, 620.0),
        ],
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("view.png");
    opencv::imgcodecs::imwrite(
        path.to_str().expect("utf-8 path"),
        &warp(&img, &h),
        &Vector::new(),
    )
    .expect("png written");
    let images = [path];
    let calibrate = |board: &BoardSpec| {
        odocal_calib::calibrate_session(
            &images,
            &[],
            board,
            None,
            odocal_calib::ModelChoice::Auto,
            &|| {},
        )
        .err()
        .expect("no board of this kind")
        .to_string()
    };
    // Named from the first view's markers, before any slow checkerboard search.
    let e = calibrate(&BoardSpec::checkerboard(10, 7, 0.04));
    assert!(
        e.contains("shows a ChArUco board (")
            && e.contains("not a plain checkerboard: pass --target charuco --dictionary 4X4_50"),
        "{e}"
    );
    let mut other = spec();
    other.target = BoardTarget::Charuco {
        marker_m: MARKER_M as f64,
        dictionary: ArucoDictionary::from_name("5X5_100").expect("known dictionary"),
    };
    let e = calibrate(&other);
    assert!(
        e.contains("of dictionary 4X4_50 were found: pass --dictionary 4X4_50"),
        "{e}"
    );
}

/// The board as OpenCV before 4.6 drew it (and 4.7's `setLegacyPattern`): with an even number
/// of rows, the top-left square white and holding marker 0, markers numbered row by row in
/// the white squares. Drawn here marker by marker with OpenCV's `drawMarker`, independently
/// of odocal's reading of the layout.
fn legacy_board() -> Mat {
    let dict = aruco::get_predefined_dictionary_i32(aruco::DICT_4X4_50).expect("dictionary");
    let size = Size::new(SQUARES.0 * PPS + 2 * PPS, SQUARES.1 * PPS + 2 * PPS);
    let mut img =
        Mat::new_size_with_default(size, core::CV_8UC1, Scalar::all(255.0)).expect("canvas");
    let side = (MARKER_M / SQUARE_M * PPS as f32).round() as i32;
    let inset = (PPS - side) / 2;
    let mut id = 0;
    for y in 0..SQUARES.1 {
        for x in 0..SQUARES.0 {
            let (u, v) = (PPS + x * PPS, PPS + y * PPS);
            if (x + y) % 2 == 1 {
                imgproc::rectangle(
                    &mut img,
                    core::Rect::new(u, v, PPS, PPS),
                    Scalar::all(0.0),
                    -1,
                    imgproc::LINE_8,
                    0,
                )
                .expect("square");
                continue;
            }
            let mut marker = Mat::default();
            aruco::draw_marker(&dict, id, side, &mut marker, 1).expect("marker");
            let mut roi = Mat::roi_mut(&mut img, core::Rect::new(u + inset, v + inset, side, side))
                .expect("roi");
            marker.copy_to(&mut roi).expect("copy");
            id += 1;
        }
    }
    img
}

/// A board of the layout before OpenCV 4.6 (an even number of rows) is read on its own
/// corners: the current layout's corners would be a square off (and the markers at the row
/// ends misplaced), which calibrated views of such a board to 12.8 px RMS and fx 11 % off.
#[test]
fn a_board_of_the_layout_before_opencv_4_6_is_read_on_its_own_corners() {
    let (_, corners) = opencv_board();
    let first = corners[0];
    let img = legacy_board();
    let h = homography(&img, WHOLE_BOARD_TILTED);
    let found = find_charuco_corners(&warp(&img, &h), &spec())
        .expect("OpenCV runs")
        .expect("board found");
    assert!(found.legacy_layout, "the layout before 4.6 is named");
    assert_eq!(found.ids.len(), corners.len(), "every inner corner found");
    let (rms, max, _) = errors(&found, &h, &corners);
    println!(
        "legacy board: {} corners, error RMS {rms:.4} px, max {max:.4} px",
        found.ids.len()
    );
    assert!(rms < 0.06 && max < 0.15, "RMS {rms} px, max {max} px");
    for (p, &id) in found.object_points.iter().zip(&found.ids) {
        let (x, y) = corners[id as usize];
        assert!((p.x - (x - first.0)).abs() < 1e-9 && (p.y - (y - first.1)).abs() < 1e-9);
    }
    // OpenCV's own drawing of the current layout is not taken for the old one.
    let (img, _) = opencv_board();
    let found = find_charuco_corners(&warp(&img, &h), &spec())
        .expect("OpenCV runs")
        .expect("board found");
    assert!(!found.legacy_layout);
}
