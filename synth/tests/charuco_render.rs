//! The renderer draws OpenCV's ChArUco board where odocal's board frame says it is: rendered
//! views, detected by odocal-calib, give every corner where the true camera projects it.

use nalgebra::Vector2;
use odocal_calib::charuco::find_charuco_corners;
use odocal_calib::{ArucoDictionary, BoardSpec, BoardTarget};
use odocal_synth::board::{draw_views, render_view, visible_share, BoardPattern, CalibScene};
use odocal_synth::raycast::RayGrid;
use opencv::core::Mat;
use opencv::prelude::*;

#[test]
fn rendered_charuco_corners_are_found_where_the_camera_projects_them() {
    let scene = CalibScene {
        board: BoardSpec {
            cols: 10,
            rows: 7,
            square_m: 0.04,
            target: BoardTarget::Charuco {
                marker_m: 0.03,
                dictionary: ArucoDictionary::from_name("4X4_50").expect("known dictionary"),
            },
        },
        views: 8,
        floor_views: 2,
        ..CalibScene::default()
    };
    let truth = draw_views(&scene, 3);
    assert_eq!(truth.views.len(), 8);
    let pattern = BoardPattern::new(&scene.board).expect("OpenCV draws the board");
    let grid = RayGrid::new(&truth.camera, scene.supersample);
    let mut errors: Vec<Vector2<f64>> = Vec::new();
    let mut partial = 0;
    for (i, view) in truth.views.iter().chain(&truth.floor_views).enumerate() {
        let floor = (i >= truth.views.len()).then_some(&truth.floor_to_camera);
        let img = render_view(
            &grid,
            &scene,
            &pattern,
            &view.board_to_camera,
            floor,
            i as u64,
        );
        let mat =
            Mat::new_rows_cols_with_data(img.height() as i32, img.width() as i32, img.as_raw())
                .and_then(|m| m.try_clone())
                .expect("image as a Mat");
        let found = find_charuco_corners(&mat, &scene.board)
            .expect("OpenCV runs")
            .unwrap_or_else(|reason| panic!("{}: {reason}", view.image));
        let share = visible_share(&truth.camera, &view.board_to_camera, &scene.board);
        if share <= 2.0 / 3.0 {
            partial += 1;
        }
        for (p, o) in found.corners.iter().zip(&found.object_points) {
            let t = truth
                .camera
                .project(&(view.board_to_camera.0 * o))
                .expect("in front of the camera");
            assert!(
                t.x >= 0.0 && t.y >= 0.0 && t.x <= 1279.0 && t.y <= 719.0,
                "{}: a corner found beyond the image",
                view.image
            );
            errors.push(p - t);
        }
        println!(
            "{}: {} corners ({:.0} % of the board in view)",
            view.image,
            found.ids.len(),
            share * 100.0
        );
    }
    let n = errors.len() as f64;
    let rms = (errors.iter().map(|e| e.norm_squared()).sum::<f64>() / n).sqrt();
    let max = errors.iter().map(|e| e.norm()).fold(0.0, f64::max);
    let mean = errors.iter().sum::<Vector2<f64>>() / n;
    println!(
        "{} corners: error RMS {rms:.3} px, max {max:.3} px, mean ({:.4}, {:.4}) px; {partial} views with a third or more of the board outside",
        errors.len(),
        mean.x,
        mean.y
    );
    assert!(
        partial >= 2,
        "views with a third of the board outside: {partial}"
    );
    assert!(rms < 0.1 && max < 0.5, "RMS {rms} px, max {max} px");
    assert!(mean.norm() < 0.02, "bias {mean:?} px");
}
