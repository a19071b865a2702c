//! Benchmark of tracking an arena's four videos (the synthetic arena, 1280×720, 30 fps, two
//! robots, PNG frames): the four tracked in parallel (a thread per video) against one after
//! another, in the same process, with the ratio of frames per second (the target is ≥ 1.6×,
//! 80 % of perfect scaling on 2 cores). On a machine with more cores, run it on two:
//! `taskset -c 0,1 cargo bench --bench arena`. The cameras' true poses stand in for a calibration:
//! the tracking work is the same.
//!
//! Run: `cargo bench --bench arena` (set `ARENA_BENCH_FRAMES` to change the frames per
//! video, default 120).

mod common;

use common::timed;

use odocal_arena::{track_cameras, ArenaCamera, ArenaFile, Consistency, ARENA_FORMAT};
use odocal_calib::{CameraFile, FloorPlane};
use odocal_synth::arena::{write_arena, ArenaScene};
use odocal_tracker::multi::TagSelection;
use odocal_tracker::TrackOptions;

const REPS: usize = 3;

fn main() {
    let frames: usize = std::env::var("ARENA_BENCH_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(120);
    let dir = tempfile::tempdir().expect("temporary folder");
    let d = dir.path();
    let scene = ArenaScene {
        frames,
        calib_views: 6,
        ..ArenaScene::default()
    };
    let truth = write_arena(d, &scene, &|| {})
        .expect("render the arena")
        .truth;
    let arena = ArenaFile {
        format: ARENA_FORMAT.into(),
        cameras: truth
            .cameras
            .iter()
            .map(|c| {
                let floor = FloorPlane {
                    floor_to_camera: c.arena_to_camera,
                    plane_rms_m: 0.0,
                    camera_height_m: c.arena_to_camera.0.inverse().translation.vector.z,
                    views: vec![],
                };
                ArenaCamera {
                    source: c.name.clone(),
                    calibration: CameraFile::from_model(c.camera, Some(floor)),
                    arena_to_camera: c.arena_to_camera,
                    shared_views: 0,
                    rms_px: 0.0,
                    pose_covariance: None,
                }
            })
            .collect(),
        shared_views: vec![],
        consistency: Consistency {
            rms_mm: 0.0,
            max_mm: 0.0,
            points: 0,
        },
        pairs: vec![],
        frame_placement: None,
    };
    let videos: Vec<_> = (0..4).map(|k| d.join(format!("video_c{k}"))).collect();
    let opts = TrackOptions {
        tag_size_m: scene.tag_size_m,
        marker_height_m: truth.marker_height_m,
        ..TrackOptions::default()
    };
    let tags = TagSelection::Ids(vec![0, 3]);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let total = (4 * frames) as f64;
    let run = |parallel: bool| {
        let r = track_cameras(&arena, &videos, &opts, &tags, parallel).expect("tracking");
        let fixes: usize = r
            .iter()
            .flat_map(|per_id| per_id.values())
            .map(|t| t.fixes().count())
            .sum();
        assert!(fixes > 0);
    };
    let (seq_wall, seq_cpu) = timed(REPS, || run(false));
    let (par_wall, par_cpu) = timed(REPS, || run(true));
    println!(
        "arena tracking, 4 videos of {frames} frames (1280x720 PNG, 2 tags), medians of {REPS} runs on {cores} cores:"
    );
    println!(
        "  one after another: {:.2} s wall ({:.1} frames/s), {:.2} s CPU",
        seq_wall,
        total / seq_wall,
        seq_cpu
    );
    println!(
        "  in parallel:       {:.2} s wall ({:.1} frames/s), {:.2} s CPU",
        par_wall,
        total / par_wall,
        par_cpu
    );
    println!(
        "  parallel / sequential frames per second: {:.2}x (target >= 1.6x on 2 cores; other load on the machine lowers it)",
        seq_wall / par_wall
    );
    if cores != 2 {
        println!("  note: the target is for 2 cores; this machine has {cores}: taskset -c 0,1 cargo bench --bench arena");
    }
}
