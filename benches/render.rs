//! Benchmark of the ceiling-video renderer on the default 1280×720 scene: the
//! per-video setup (floor pre-render; the camera's rays are computed once per
//! process), the per-frame render of a robot at rest and driving at 0.7 m/s,
//! and a whole MJPG AVI (render + FFmpeg encode) of one run of the experiment
//! (1 s at rest, 1.5 m at 0.7 m/s, 1 s at rest), in wall and CPU time. The
//! baseline is the cold setup of the first video of a process.
//!
//! Run: `cargo bench --bench render`.

mod common;

use common::timed;

use nalgebra::Point2;
use odocal_core::Pose2;
use odocal_synth::scene::{
    frame_times, nadir, render_video, straight_trajectory, SceneConfig, SceneRenderer, VideoFormat,
};

const REPS: usize = 3;

/// One run of the experiment: at rest, a straight 1.5 m at `speed_mps`, at rest.
fn run_trajectory(start: Point2<f64>, speed_mps: f64) -> Vec<(f64, Pose2)> {
    let end = start + nalgebra::Vector2::new(1.5, 0.0);
    let drive = straight_trajectory(start, end, speed_mps);
    let t_drive = drive.last().map(|s| s.0).unwrap_or(0.0);
    let mut traj = vec![(0.0, drive[0].1)];
    traj.extend(drive.iter().map(|&(t, p)| (t + 1.0, p)));
    traj.push((t_drive + 2.0, drive[drive.len() - 1].1));
    traj
}

fn main() {
    let fps = 30.0;
    let cfg = SceneConfig::default();
    let c = nadir(&cfg.floor);
    let traj = run_trajectory(Point2::new(c.x - 0.75, c.y), 0.7);
    let times = frame_times(&traj, fps);
    println!(
        "render bench: default 1280x720 scene, {} frames per run, {} threads",
        times.len(),
        rayon::current_num_threads()
    );

    let (cold, cold_cpu) = timed(1, || {
        SceneRenderer::new(cfg.clone(), 1).expect("scene");
    });
    let (warm, warm_cpu) = timed(REPS, || {
        SceneRenderer::new(cfg.clone(), 2).expect("scene");
    });
    println!("setup of a video (floor pre-render):");
    println!(
        "  first in the process  {:7.1} ms wall  {:7.1} ms CPU  (baseline)",
        cold * 1e3,
        cold_cpu * 1e3
    );
    println!(
        "  later (rays shared)   {:7.1} ms wall  {:7.1} ms CPU  ({:.2}x the baseline's CPU)",
        warm * 1e3,
        warm_cpu * 1e3,
        warm_cpu / cold_cpu
    );

    let renderer = SceneRenderer::new(cfg.clone(), 3).expect("scene");
    // Warm the rays along the whole drive, then time frames at rest and moving.
    for (k, &t) in times.iter().enumerate() {
        renderer.render_frame(&traj, k, t).expect("render");
    }
    let rest: Vec<(usize, f64)> = times.iter().copied().enumerate().take(20).collect();
    let moving: Vec<(usize, f64)> = times
        .iter()
        .copied()
        .enumerate()
        .filter(|&(_, t)| t > 1.2 && t < 2.9)
        .take(20)
        .collect();
    for (what, frames) in [("at rest", &rest), ("moving 0.7 m/s", &moving)] {
        let (wall, cpu) = timed(REPS, || {
            for &(k, t) in frames.iter() {
                renderer.render_frame(&traj, k, t).expect("render");
            }
        });
        let n = frames.len() as f64;
        println!(
            "frame {what:15} {:6.2} ms wall  {:6.2} ms CPU per frame  ({:.3}x the baseline's CPU)",
            wall * 1e3 / n,
            cpu * 1e3 / n,
            cpu / n / cold_cpu
        );
    }

    let dir = tempfile::tempdir().expect("temp dir");
    let avi = dir.path().join("run.avi");
    let (wall, cpu) = timed(REPS, || {
        render_video(&avi, VideoFormat::Avi, &cfg, &traj, fps, 4).expect("avi");
    });
    let n = times.len() as f64;
    println!(
        "MJPG AVI of the run (render + encode): {:.2} s wall, {:.2} ms wall and {:.2} ms CPU per frame -> {:.0} frames/s on {} threads",
        wall,
        wall * 1e3 / n,
        cpu * 1e3 / n,
        n / wall,
        rayon::current_num_threads()
    );
}
