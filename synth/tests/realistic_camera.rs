//! The realistic camera measured on its own images: every effect is checked by measuring
//! the rendered pixels (or the decoded file) against what physics predicts from the scene's
//! geometry, not by re-running the renderer's formulas.
//!
//! The scenes are small (640×360, a straight-down camera without distortion, so image x is
//! floor x and a floor length L at depth Z is L·f/Z pixels) and use a large tag, so edges are
//! long and clean.

use nalgebra::Point2;
use odocal_calib::CameraModel;
use odocal_core::Pose2;
use odocal_synth::scene::{
    ceiling_camera, nadir, straight_trajectory, CameraEffects, FrameTruth, SceneConfig,
    SceneRenderer,
};

const W: u32 = 640;
const H: u32 = 360;
const CAMERA_HEIGHT_M: f64 = 2.2;

/// A straight-down camera, no noise, steady light, a 0.6 m tag.
fn scene(exposure_s: f64, effects: CameraEffects) -> SceneConfig {
    let mut cfg = SceneConfig {
        camera: CameraModel::from_hfov(W, H, 70.0),
        floor: ceiling_camera(CAMERA_HEIGHT_M, 0.0, 0.0, 0.0),
        exposure_s,
        effects,
        ..SceneConfig::default()
    };
    cfg.sensor.noise_sigma = 0.0;
    cfg.lighting.amplitude = 0.0;
    cfg.robot.tag_size_m = 0.6;
    cfg.robot.body_radius_m = 0.3;
    cfg
}

/// Pixels per metre on the marker plane.
fn px_per_m(cfg: &SceneConfig) -> f64 {
    cfg.camera.intrinsics.fx / (CAMERA_HEIGHT_M - cfg.robot.marker_height_m)
}

/// A drive along +x through the image centre at `speed_mps`, heading 0.
fn drive(cfg: &SceneConfig, speed_mps: f64) -> Vec<(f64, Pose2)> {
    let c = nadir(&cfg.floor);
    straight_trajectory(
        Point2::new(c.x - 0.4, c.y),
        Point2::new(c.x + 0.4, c.y),
        speed_mps,
    )
}

fn render(cfg: &SceneConfig, traj: &[(f64, Pose2)], t_s: f64) -> (Vec<u8>, FrameTruth) {
    let r = SceneRenderer::new(cfg.clone(), 5).expect("renderer");
    let (img, truth) = r.render_frame(traj, 0, t_s).expect("frame");
    (img.into_raw(), truth)
}

/// Image x (pixels) of a floor x on the marker plane, for the straight-down camera.
fn image_x(cfg: &SceneConfig, floor_x: f64) -> f64 {
    let c = nadir(&cfg.floor);
    cfg.camera.intrinsics.cx + (floor_x - c.x) * px_per_m(cfg)
}

/// Rows of the tag's top black ring (the row of cells just inside the white border), for a
/// tag centred on the image centre row.
fn ring_rows(cfg: &SceneConfig) -> std::ops::Range<usize> {
    let cell_px = cfg.robot.tag_size_m / 8.0 * px_per_m(cfg);
    let top = cfg.camera.intrinsics.cy - 4.0 * cell_px;
    (top + 0.3 * cell_px).ceil() as usize..(top + 0.7 * cell_px).floor() as usize
}

/// The spread of a blurred step along a row: the derivative of the profile around `x_edge`
/// (±`half` pixels) is the motion's box kernel convolved with the pixel and the differencing
/// (two unit boxes), so its variance is (L² + 2) / 12 for a blur of length L.
fn blur_length_px(row: &[u8], x_edge: f64, half: usize) -> f64 {
    let c = x_edge.round() as usize;
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    for x in c - half..c + half {
        let g = row[x] as f64 - row[x + 1] as f64; // white to black: falling
        let xm = x as f64 + 0.5;
        s0 += g;
        s1 += g * xm;
        s2 += g * xm * xm;
    }
    let mean = s1 / s0;
    let var = s2 / s0 - mean * mean;
    (12.0 * var - 2.0).max(0.0).sqrt()
}

/// Motion blur: the edge between the tag's white border and its black ring, moving across
/// the image, is smeared over speed × exposure (in pixels) with the box profile of a true
/// integration over the exposure.
#[test]
fn motion_blur_length_is_speed_times_exposure() {
    for (speed_mps, exposure_s) in [(0.7, 0.010), (1.5, 0.028)] {
        let effects = CameraEffects {
            blur_step_px: Some(0.5),
            ..CameraEffects::default()
        };
        let cfg = scene(exposure_s, effects);
        let traj = drive(&cfg, speed_mps);
        let t = 0.4 / speed_mps; // tag centred in the image
        let (img, truth) = render(&cfg, &traj, t);
        let expected_px = speed_mps * exposure_s * px_per_m(&cfg);
        let pose = truth.pose;
        // Left edge of the black square at this time.
        let x_edge = image_x(&cfg, pose.x_m - cfg.robot.tag_size_m / 2.0);
        let half = (expected_px / 2.0 + 4.0).ceil() as usize;
        let rows = ring_rows(&cfg);
        let lengths: Vec<f64> = rows
            .clone()
            .map(|y| {
                let row = &img[y * W as usize..(y + 1) * W as usize];
                blur_length_px(row, x_edge, half)
            })
            .collect();
        let measured = lengths.iter().sum::<f64>() / lengths.len() as f64;
        println!(
            "{speed_mps} m/s, {} ms: blur measured {measured:.3} px over {} rows, speed × exposure {expected_px:.3} px, truth {:.3} px",
            exposure_s * 1e3,
            lengths.len(),
            truth.blur_px
        );
        assert!(
            (measured - expected_px).abs() < 0.25,
            "measured {measured} px, expected {expected_px} px"
        );
        assert!(
            (truth.blur_px - expected_px).abs() < 0.05,
            "{}",
            truth.blur_px
        );
    }
}

/// The x where a row crosses from the white border to the black ring (the mid grey level),
/// searched from `x0` rightwards; linear interpolation between pixels.
fn falling_crossing(row: &[u8], x0: usize, level: f64) -> Option<f64> {
    (x0..row.len() - 1).find_map(|x| {
        let (a, b) = (row[x] as f64, row[x + 1] as f64);
        (a >= level && b < level).then(|| x as f64 + (a - level) / (a - b))
    })
}

/// Rolling shutter: a vertical edge moving sideways is skewed, one row later seeing it
/// `speed · readout / rows` further on; the truth's tag-row time puts the edge exactly where
/// the image shows it.
#[test]
fn rolling_shutter_skews_a_moving_vertical_edge() {
    let speed_mps = 1.5;
    for readout_s in [0.0, 0.030] {
        let effects = CameraEffects {
            blur_step_px: Some(0.5),
            rolling_shutter_s: readout_s,
            ..CameraEffects::default()
        };
        let cfg = scene(0.0005, effects);
        let traj = drive(&cfg, speed_mps);
        let t = 0.4 / speed_mps - readout_s / 2.0; // tag centred at mid-readout
        let (img, truth) = render(&cfg, &traj, t);
        let s = cfg.robot.tag_size_m;
        let ppm = px_per_m(&cfg);
        let cell_px = s / 8.0 * ppm;
        let cy = cfg.camera.intrinsics.cy;
        // Rows of the black square, away from its top and bottom edges.
        let rows: Vec<usize> =
            ((cy - 3.5 * cell_px).ceil() as usize..(cy + 3.5 * cell_px) as usize).collect();
        let x_guess = image_x(&cfg, truth.pose.x_m - s / 2.0);
        let level = (220.0 + 22.0) / 2.0;
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter_map(|&y| {
                let row = &img[y * W as usize..(y + 1) * W as usize];
                let x0 = (x_guess - 0.6 * cell_px).max(0.0) as usize;
                falling_crossing(row, x0, level).map(|x| (y as f64, x))
            })
            .collect();
        assert!(pts.len() > 100, "{} rows with an edge", pts.len());
        let n = pts.len() as f64;
        let (my, mx) = (
            pts.iter().map(|p| p.0).sum::<f64>() / n,
            pts.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let slope = pts.iter().map(|p| (p.0 - my) * (p.1 - mx)).sum::<f64>()
            / pts.iter().map(|p| (p.0 - my).powi(2)).sum::<f64>();
        let expected = speed_mps * ppm * readout_s / H as f64;
        println!(
            "readout {} ms: edge skew {slope:.5} px/row, expected {expected:.5} px/row ({:.2} px over the tag)",
            readout_s * 1e3,
            expected * 8.0 * cell_px
        );
        assert!(
            (slope - expected).abs() < 0.02 * expected.abs() + 0.0005,
            "skew {slope} px/row, expected {expected}"
        );
        // The truth's tag row and its time: the edge in that row is where the pose at that
        // time puts it.
        let x_at_row = mx + slope * (truth.tag_row_px - my);
        let x_truth = image_x(&cfg, truth.pose_tag_row.x_m - s / 2.0);
        let expected_t = t + truth.tag_row_px * readout_s / H as f64;
        println!(
            "  tag row {:.2}: edge at {x_at_row:.3} px, pose at the row's time {x_truth:.3} px",
            truth.tag_row_px
        );
        assert!((truth.t_tag_row_s - expected_t).abs() < 1e-12);
        assert!((truth.tag_row_px - cy).abs() < 1.0, "{}", truth.tag_row_px);
        assert!(
            (x_at_row - x_truth).abs() < 0.1,
            "edge {x_at_row} px, truth {x_truth} px"
        );
    }
}
