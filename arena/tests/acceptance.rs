//! The arena against the synthetic truth: four cameras, each calibrated from its own rendered
//! views, tied into one floor frame by shared floor boards, two robots tracked across them.

use std::path::{Path, PathBuf};

use odocal_arena::{build_arena, detect_shared, fuse_all, track_cameras, FuseOptions};
use odocal_calib::{calibrate_session, CameraFile, LensModel, ModelChoice};
use odocal_core::Trajectory;
use odocal_synth::arena::{write_arena, ArenaScene};
use odocal_tracker::multi::TagSelection;
use odocal_tracker::TrackOptions;

fn pngs(dir: &Path, prefix: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(prefix) && n.ends_with(".png"))
        })
        .collect();
    v.sort();
    v
}

#[test]
fn arena_meets_the_bounds() {
    let scene = ArenaScene {
        width: 640,
        height: 360,
        frames: 190,
        calib_views: 12,
        ..ArenaScene::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let t0 = std::time::Instant::now();
    let written = write_arena(d, &scene, &|| {}).unwrap();
    let truth = written.truth;
    eprintln!(
        "rendered in {:.1} s, {} shared views",
        t0.elapsed().as_secs_f64(),
        truth.shared.len()
    );
    let t0 = std::time::Instant::now();
    let mut files: Vec<CameraFile> = Vec::new();
    for cam in &truth.cameras {
        let cd = d.join(&cam.name);
        let s = calibrate_session(
            &pngs(&cd, "view_"),
            &pngs(&cd, "floor_"),
            &scene.board,
            ModelChoice::Fixed(LensModel::Pinhole5),
            &|| {},
        )
        .unwrap();
        files.push(s.file);
    }
    eprintln!("calibrated in {:.1} s", t0.elapsed().as_secs_f64());
    let paths: Vec<PathBuf> = truth
        .cameras
        .iter()
        .map(|c| d.join(&c.name).join("camera.json"))
        .collect();
    let path_refs: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
    let sizes: Vec<(u32, u32)> = files
        .iter()
        .map(|f| (f.camera.width, f.camera.height))
        .collect();
    let (shared, notes) = detect_shared(&[d.join("shared")], 4, &scene.board, &sizes).unwrap();
    eprintln!("{notes:?}");
    let (arena, solution) = build_arena(&files, &path_refs, &shared, &scene.board).unwrap();
    eprintln!(
        "consistency {:?} pairs {:?} rms_px {:?}",
        arena.consistency, arena.pairs, solution.rms_px
    );
    let t0 = std::time::Instant::now();
    let videos: Vec<PathBuf> = (0..4).map(|k| d.join(format!("video_c{k}"))).collect();
    let opts = TrackOptions {
        tag_size_m: scene.tag_size_m,
        marker_height_m: truth.marker_height_m,
        ..TrackOptions::default()
    };
    let results =
        track_cameras(&arena, &videos, &opts, &TagSelection::Ids(vec![0, 3]), true).unwrap();
    eprintln!("tracked in {:.1} s", t0.elapsed().as_secs_f64());
    let tracking = fuse_all(
        &arena,
        &results,
        truth.marker_height_m,
        &FuseOptions::for_fps(scene.fps),
    )
    .unwrap();
    for (k, c) in truth.cameras.iter().enumerate() {
        eprintln!(
            "camera {k}: offset {:.3} ms (truth {:.3} ms, σ {:.3} ms)",
            tracking.offsets.offset_s[k] * 1e3,
            c.clock_offset_s * 1e3,
            tracking.offsets.sigma_s[k] * 1e3
        );
    }
    for robot in &tracking.robots {
        let rt = truth
            .robots
            .iter()
            .find(|r| r.tag_id == robot.tag_id)
            .unwrap();
        let tt = Trajectory::read_csv(&d.join(&rt.trajectory)).unwrap();
        let mut sq = 0.0;
        let mut n = 0;
        let mut worst: f64 = 0.0;
        for row in &robot.trajectory.rows {
            let p = tt.position_at(row.t_s, 0.01).unwrap();
            let e = (row.pose.position() - p).norm();
            sq += e * e;
            n += 1;
            worst = worst.max(e);
        }
        let jump = robot.handoffs.iter().map(|h| h.jump_m).fold(0.0, f64::max);
        let dis = robot
            .handoffs
            .iter()
            .map(|h| h.disagreement_m)
            .fold(0.0, f64::max);
        eprintln!(
            "robot {}: {} rows, RMS {:.3} mm, max {:.3} mm, {} handoffs, jump max {:.3} mm, disagreement max {:.3} mm",
            robot.tag_id,
            n,
            (sq / n as f64).sqrt() * 1e3,
            worst * 1e3,
            robot.handoffs.len(),
            jump * 1e3,
            dis * 1e3
        );
    }
    panic!("figures");
}
