//! The renderers against OpenCV: a feature drawn at a known pixel position must be found there
//! by OpenCV's own sub-pixel locator (`cornerSubPix`), whose coordinates put integers at pixel
//! centres (ARCHITECTURE.md, "Pixels").
//!
//! The tracker and the calibration are tested against these renderers, so a renderer that drew
//! everything a fraction of a pixel off (a half-pixel in one axis, sub-samples not centred in
//! their pixel) would make a detector with the same mistake look exact. Here the judge is
//! OpenCV, independent of both: checkerboard saddles (the board renderer, [`RayGrid`]) and the
//! saddles where four cells of a tag meet (the scene renderer, [`RayRows`] and its finer
//! sampling of still edges). A saddle is symmetric under a half turn, so neither blur nor the
//! pixel's area moves it: cornerSubPix finds it unbiased.
//!
//! [`RayGrid`]: odocal_synth::raycast::RayGrid
//! [`RayRows`]: odocal_synth::raycast::RayRows

use nalgebra::{Isometry3, Point2, Translation3, UnitQuaternion, Vector3};
use odocal_calib::{BoardSpec, BoardToCamera};
use odocal_core::Pose2;
use odocal_synth::board::{render_view, true_corners, BoardPattern, CalibScene};
use odocal_synth::raycast::RayGrid;
use odocal_synth::scene::{nadir, tag36h11_pattern, SceneConfig, SceneRenderer};
use opencv::core::{Mat, Point2f, Size, TermCriteria, TermCriteria_Type, Vector};
use opencv::imgproc;
use opencv::prelude::*;

/// Mean and RMS of found − true, per axis, pixels.
struct Offsets {
    mean: [f64; 2],
    rms: [f64; 2],
    n: usize,
}

/// Refines `truth` shifted by a fixed start error with cornerSubPix in the 8-bit image
/// (`width` pixels per row) and compares the result with `truth`.
fn locate(pixels: &[u8], width: usize, truth: &[Point2<f64>], half_window: i32) -> Offsets {
    let row = Mat::from_slice(pixels).expect("an 8-bit image");
    let image = row
        .reshape(1, (pixels.len() / width) as i32)
        .and_then(|m| m.try_clone())
        .expect("an 8-bit image");
    // Start off the truth by most of a pixel in both axes, so the answer is OpenCV's own.
    let mut corners: Vector<Point2f> = truth
        .iter()
        .map(|p| Point2f::new(p.x as f32 + 0.6, p.y as f32 - 0.7))
        .collect();
    imgproc::corner_sub_pix(
        &image,
        &mut corners,
        Size::new(half_window, half_window),
        Size::new(-1, -1),
        TermCriteria::new(
            TermCriteria_Type::COUNT as i32 + TermCriteria_Type::EPS as i32,
            100,
            1e-6,
        )
        .expect("termination criteria"),
    )
    .expect("cornerSubPix");
    let (mut sum, mut sq) = ([0.0; 2], [0.0; 2]);
    for (c, t) in corners.iter().zip(truth) {
        let e = [c.x as f64 - t.x, c.y as f64 - t.y];
        for k in 0..2 {
            sum[k] += e[k];
            sq[k] += e[k] * e[k];
        }
    }
    let n = truth.len();
    Offsets {
        mean: sum.map(|s| s / n as f64),
        rms: sq.map(|s| (s / n as f64).sqrt()),
        n,
    }
}

/// The offsets of several images taken together.
fn pooled(parts: &[Offsets]) -> Offsets {
    let n: usize = parts.iter().map(|o| o.n).sum();
    let weighted = |f: &dyn Fn(&Offsets, usize) -> f64, k: usize| {
        parts.iter().map(|o| f(o, k) * o.n as f64).sum::<f64>() / n as f64
    };
    Offsets {
        mean: [0, 1].map(|k| weighted(&|o, k| o.mean[k], k)),
        rms: [0, 1].map(|k| weighted(&|o, k| o.rms[k] * o.rms[k], k).sqrt()),
        n,
    }
}

fn check(what: &str, o: &Offsets, max_mean_px: f64, max_rms_px: f64) {
    println!(
        "{what}: {} saddles, found − drawn: mean ({:+.4}, {:+.4}) px, RMS ({:.4}, {:.4}) px",
        o.n, o.mean[0], o.mean[1], o.rms[0], o.rms[1]
    );
    for (k, axis) in ["x", "y"].iter().enumerate() {
        assert!(
            o.mean[k].abs() < max_mean_px,
            "{what}: OpenCV finds the saddles {:+.4} px off in {axis} (bound {max_mean_px})",
            o.mean[k]
        );
        assert!(
            o.rms[k] < max_rms_px,
            "{what}: RMS {:.4} px in {axis} (bound {max_rms_px})",
            o.rms[k]
        );
    }
}

/// The board renderer (every pixel supersampled through [`RayGrid`], the calibration views):
/// a tilted board with the default lens distortion and optical blur, no noise.
#[test]
fn checkerboard_corners_are_drawn_where_opencv_finds_them() {
    let scene = CalibScene {
        width: 640,
        height: 360,
        board: BoardSpec::checkerboard(9, 6, 0.05),
        noise_sigma: 0.0,
        ..CalibScene::default()
    };
    let camera = scene.camera();
    let grid = RayGrid::new(&camera, scene.supersample);
    let b = scene.board;
    let pattern = BoardPattern::new(&b).unwrap();
    let centre = Vector3::new(
        (b.cols - 1) as f64 * b.square_m / 2.0,
        (b.rows - 1) as f64 * b.square_m / 2.0,
        0.0,
    );
    // Three poses: square-on and tilted both ways, at irrational-looking offsets so corners
    // fall everywhere within their pixels.
    let poses = [(0.0, 0.0, 0.05), (0.35, -0.2, -0.3), (-0.25, 0.4, 0.6)].map(|(rx, ry, rz)| {
        let rot = UnitQuaternion::from_euler_angles(rx, ry, rz);
        let at = Vector3::new(0.0123, -0.0311, 0.62);
        BoardToCamera(Isometry3::from_parts(
            Translation3::from(at - rot * centre),
            rot,
        ))
    });
    let views: Vec<Offsets> = poses
        .iter()
        .map(|pose| {
            let img = render_view(&grid, &scene, &pattern, pose, None, 1);
            let corners = true_corners(&camera, pose, &b);
            assert_eq!(corners.len(), (b.cols * b.rows) as usize);
            let o = locate(img.as_raw(), camera.width as usize, &corners, 5);
            check("one board view", &o, 0.03, 0.1);
            o
        })
        .collect();
    check("board renderer", &pooled(&views), 0.01, 0.1);
}

/// Pixel positions of the saddles of a tag's cells (four cells meeting with equal colours on a
/// diagonal) for a robot at `pose` under `cfg`'s camera.
fn tag_saddles(cfg: &SceneConfig, pose: &Pose2) -> Vec<Point2<f64>> {
    let (cells, n, at_border) = tag36h11_pattern(cfg.robot.tag_id).expect("tag pattern");
    let cell_m = cfg.robot.tag_size_m / at_border as f64;
    let half = cell_m * n as f64 / 2.0;
    let white = |col: usize, row: usize| cells[row * n + col];
    let mut out = Vec::new();
    // Vertex (i, j) is the top-left corner of cell (col i, row j); rows count down the tag
    // (robot frame y up), as the renderer draws them.
    for j in 1..n {
        for i in 1..n {
            let tl = white(i - 1, j - 1);
            if tl == white(i, j) && tl != white(i, j - 1) && tl != white(i - 1, j) {
                let body = Point2::new(-half + i as f64 * cell_m, half - j as f64 * cell_m);
                let floor = pose.transform_point(&body);
                let px = cfg
                    .camera
                    .floor_to_pixel(&cfg.floor, &floor, cfg.robot.marker_height_m)
                    .expect("the tag is in front of the camera");
                out.push(px);
            }
        }
    }
    out
}

/// The scene renderer (the tracker's synthetic videos): a robot at rest, whose still edges are
/// drawn with the renderer's finer sampling, under the default camera (distortion, 2° tilt).
#[test]
fn tag_cells_in_a_scene_frame_are_drawn_where_opencv_finds_them() {
    let mut cfg = SceneConfig::default();
    cfg.sensor.noise_sigma = 0.0;
    cfg.lighting.amplitude = 0.0;
    // A large tag, so a cell spans about 17 px and the saddles' windows see four cells only.
    cfg.robot.tag_size_m = 0.32;
    cfg.robot.body_radius_m = 0.15;
    let renderer = SceneRenderer::new(cfg.clone(), 11).expect("scene");
    let c = nadir(&cfg.floor);
    let mut found = Vec::new();
    // Twelve poses across the middle of the image, turned in steps of about 30°.
    for k in 0..12 {
        let pose = Pose2::new(
            c.x - 0.3 + 0.0513 * k as f64,
            c.y + 0.25 - 0.0417 * k as f64,
            0.37 + 0.53 * k as f64,
        );
        let at_rest = [(0.0, pose), (10.0, pose)];
        let (img, _) = renderer.render_frame(&at_rest, k, 1.0).expect("frame");
        let saddles = tag_saddles(&cfg, &pose);
        assert!(saddles.len() >= 4, "{} saddles", saddles.len());
        let o = locate(img.as_raw(), cfg.camera.width as usize, &saddles, 5);
        // Four saddles per frame: the mean of four noisy corners wanders a few hundredths of a
        // pixel; the pooled mean below is the convention check.
        check("one scene frame", &o, 0.08, 0.1);
        found.push(o);
    }
    check("scene renderer", &pooled(&found), 0.015, 0.06);
}
