//! Benchmark of calibration: board detection per view (one thread and all
//! cores) and Zhang calibration of 20 views, on the default 1280x720 scene.
//! Run with `cargo bench --bench calib`.

mod common;

use common::median;
use std::time::Instant;

use odocal_calib::{calibrate, detect_file, fit_floor, BoardView, Detection};
use odocal_synth::board::{draw_views, render_view, BoardPattern, CalibScene};
use odocal_synth::raycast::RayGrid;
use rayon::prelude::*;

fn main() {
    let scene = CalibScene::default();
    let truth = draw_views(&scene, 1);
    let dir = std::env::temp_dir().join(format!("odocal-bench-calib-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let grid = RayGrid::new(&truth.camera, scene.supersample);
    let pattern = BoardPattern::new(&scene.board).expect("board pattern");
    let t = Instant::now();
    let mut paths = Vec::new();
    for (i, v) in truth.views.iter().chain(&truth.floor_views).enumerate() {
        let floor = (i >= truth.views.len()).then_some(&truth.floor_to_camera);
        let img = render_view(&grid, &scene, &pattern, &v.board_to_camera, floor, i as u64);
        let p = dir.join(&v.image);
        img.save(&p).expect("write view");
        paths.push(p);
    }
    let render_s = t.elapsed().as_secs_f64();
    let (hand, floor) = paths.split_at(truth.views.len());

    let detect = |p: &std::path::PathBuf| match detect_file(p, &scene.board) {
        Ok(Detection::Found(v)) => Some(v),
        _ => None,
    };
    let mut seq = Vec::new();
    let mut par = Vec::new();
    let mut views: Vec<BoardView> = Vec::new();
    for _ in 0..3 {
        let t = Instant::now();
        views = hand.iter().filter_map(detect).collect();
        seq.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let _: Vec<BoardView> = hand.par_iter().filter_map(detect).collect();
        par.push(t.elapsed().as_secs_f64());
    }
    let (seq, par) = (median(seq), median(par));
    let mut cal_t = Vec::new();
    let mut cal = None;
    for _ in 0..3 {
        let t = Instant::now();
        cal = calibrate(&views, &scene.board, odocal_calib::LensModel::Pinhole5).ok();
        cal_t.push(t.elapsed().as_secs_f64());
    }
    let cal_s = median(cal_t);
    // OpenCV's own calibrateCamera on the same corners, the baseline odocal's calibration
    // (OpenCV's fit plus odocal's covariance and residuals) is judged against.
    let opencv_s = median(
        (0..3)
            .map(|_| {
                let t = Instant::now();
                opencv_calibrate(&views, &scene.board);
                t.elapsed().as_secs_f64()
            })
            .collect(),
    );
    let floor_views: Vec<BoardView> = floor.iter().filter_map(detect).collect();
    let t = Instant::now();
    if let Some(c) = &cal {
        let _ = fit_floor(
            &c.camera,
            &floor_views,
            &scene.board,
            c.rms_px / std::f64::consts::SQRT_2,
        );
    }
    let floor_s = t.elapsed().as_secs_f64();
    let n = hand.len() as f64;
    println!(
        "calibration benchmark, {} views of {}x{} (rendering them took {render_s:.1} s)",
        hand.len(),
        scene.width,
        scene.height
    );
    println!(
        "  board detection, 1 thread:  {:8.1} ms per view",
        seq / n * 1e3
    );
    println!(
        "  board detection, {} threads: {:8.1} ms per view ({:.2}x the 1-thread rate)",
        rayon::current_num_threads(),
        par / n * 1e3,
        seq / par
    );
    println!(
        "  Zhang calibration, {} views: {:8.1} ms total",
        views.len(),
        cal_s * 1e3
    );
    println!(
        "  OpenCV calibrateCamera alone: {:8.1} ms total; odocal / OpenCV = {:.3} (target <= 1.10)",
        opencv_s * 1e3,
        cal_s / opencv_s
    );
    println!(
        "  floor plane, {} views:       {:8.1} ms",
        floor_views.len(),
        floor_s * 1e3
    );
    println!(
        "  detect + calibrate, all cores: {:.2} s for {} views",
        par + cal_s,
        hand.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// OpenCV's calibrateCamera (five coefficients) on the views' corners, nothing else.
fn opencv_calibrate(views: &[BoardView], board: &odocal_calib::BoardSpec) {
    use opencv::core::{Mat, Point2f, Point3f, Size, Vector};
    let obj: Vector<Point3f> = odocal_calib::board_points(board)
        .iter()
        .map(|p| Point3f::new(p.x as f32, p.y as f32, 0.0))
        .collect();
    let mut op = Vector::<Vector<Point3f>>::new();
    let mut ip = Vector::<Vector<Point2f>>::new();
    for v in views {
        op.push(obj.clone());
        ip.push(
            v.corners
                .iter()
                .map(|p| Point2f::new(p.x as f32, p.y as f32))
                .collect(),
        );
    }
    let (mut k, mut d) = (Mat::default(), Mat::default());
    let (mut r, mut t) = (Vector::<Mat>::new(), Vector::<Mat>::new());
    let criteria = opencv::core::TermCriteria::new(
        opencv::core::TermCriteria_Type::COUNT as i32 + opencv::core::TermCriteria_Type::EPS as i32,
        100,
        f64::EPSILON,
    )
    .expect("criteria");
    let size = views.first().map_or((0, 0), |v| v.size);
    opencv::calib3d::calibrate_camera(
        &op,
        &ip,
        Size::new(size.0 as i32, size.1 as i32),
        &mut k,
        &mut d,
        &mut r,
        &mut t,
        0,
        criteria,
    )
    .expect("OpenCV calibration");
}
