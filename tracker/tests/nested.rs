//! Frame sources decode on threads of their own, so tracking works from inside a parallel loop
//! (a tracker blocks its worker while it waits for frames; decoding queued on that same pool
//! would never run).

use std::sync::mpsc;
use std::time::Duration;

use odocal_synth::scene::{demo_trajectory, nadir, render_video, SceneConfig, VideoFormat};
use odocal_tracker::{open_source, track_source, SourceOptions, TrackOptions};
use rayon::prelude::*;

#[test]
fn tracking_inside_a_parallel_loop_does_not_deadlock() {
    let cfg = SceneConfig::default();
    let dir = tempfile::tempdir().unwrap();
    let traj = demo_trajectory(nadir(&cfg.floor), 1.0, 0.2, 0.5, 5);
    let avi = dir.path().join("v.avi");
    let png = dir.path().join("frames");
    render_video(&avi, VideoFormat::Avi, &cfg, &traj, 30.0, 1).unwrap();
    render_video(&png, VideoFormat::Png, &cfg, &traj, 30.0, 1).unwrap();
    let (tx, rx) = mpsc::channel();
    let (camera, floor) = (cfg.camera, cfg.floor);
    std::thread::spawn(move || {
        // Every worker of the global pool tracks: the old design, decoding on that pool, hung.
        let jobs = 2 * rayon::current_num_threads();
        let fixes: Vec<usize> = (0..jobs)
            .into_par_iter()
            .map(|k| {
                let path = if k % 2 == 0 { &avi } else { &png };
                let src = open_source(path, &SourceOptions::default()).unwrap();
                let res = track_source(
                    src,
                    &camera,
                    &floor,
                    &TrackOptions::default(),
                    &mut |_, _| Ok(()),
                )
                .unwrap();
                res.fixes().count()
            })
            .collect();
        let _ = tx.send(fixes);
    });
    let fixes = rx
        .recv_timeout(Duration::from_secs(300))
        .expect("tracking inside a one-worker parallel loop did not finish (deadlock?)");
    assert!(fixes.iter().all(|&n| n >= 25), "{fixes:?}");
}
