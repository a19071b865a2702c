//! Benchmark of tracking a whole experiment's videos: 131 default-scene 1280×720 videos of 150
//! frames (30 fps, the robot at 0.2–0.7 m/s: a 1.5 m run with a second's rest either side
//! lasts 4.4–9.8 s at the reference protocol's speeds), tracked as `odocal dataset`
//! tracks a manifest's runs (one video per thread at a time, each tracker with its decoder
//! thread), against decoding the same videos alone the same way, in the same process: the
//! ratio of frames per second (the target is ≥ 0.8), MJPG AVI and, when this OpenCV can
//! write it, MP4/H.264.
//!
//! With several videos at once decoding alone already keeps every core busy, so unlike one
//! video (`benches/track.rs`, where tracking fills the core the decoder leaves idle) the
//! ratio here is the decoder's share of the CPU time: tracking must cost under a quarter of
//! decoding per frame.
//!
//! Each video's tracking starts with a whole-frame search and a new detector, which a short
//! video pays for over few frames: at 45 frames a video the ratio drops to 0.76 (MJPG).
//! To keep the rendering short, 12 distinct runs are rendered and hard-linked to make up the
//! 131 files; decoding and tracking each file is the same work either way.
//!
//! Run: `cargo bench --bench track_many` (set `TRACK_MANY_VIDEOS` and `TRACK_MANY_FRAMES`
//! to change the count, default 131 videos of 150 frames; `TRACK_MANY_FORMATS=avi` for MJPG
//! only).

mod common;

use common::timed;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use odocal_synth::scene::{demo_trajectory, nadir, render_video, SceneConfig, VideoFormat};
use odocal_tracker::{open_source, track_source, SourceOptions, TrackOptions};

/// Alternating pairs of decoding alone and decoding + tracking.
const PAIRS: usize = 2;
/// Distinct runs rendered; the other files are copies of them.
const DISTINCT: usize = 12;

fn env(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Runs `work` on every video, `threads` videos at a time; returns the frames handled.
fn each_video(videos: &[PathBuf], threads: usize, work: &(dyn Fn(&Path) -> usize + Sync)) -> usize {
    let next = AtomicUsize::new(0);
    let frames = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                while let Some(v) = videos.get(next.fetch_add(1, Ordering::Relaxed)) {
                    frames.fetch_add(work(v), Ordering::Relaxed);
                }
            });
        }
    });
    frames.into_inner()
}

fn main() {
    let n_videos = env("TRACK_MANY_VIDEOS", 131);
    let n_frames = env("TRACK_MANY_FRAMES", 150);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let fps = 30.0;
    let cfg = SceneConfig::default();
    let dir = tempfile::tempdir().expect("temporary folder");
    println!("track bench, many videos: {n_videos} videos of {n_frames} frames (1280x720), {threads} at a time on {threads} cores");
    let opts = TrackOptions::default();
    let formats = std::env::var("TRACK_MANY_FORMATS").unwrap_or_else(|_| "avi,mp4".into());
    for (format, ext) in [(VideoFormat::Avi, "avi"), (VideoFormat::Mp4, "mp4")] {
        if !formats.split(',').any(|f| f == ext) {
            continue;
        }
        let mut videos = Vec::new();
        let t0 = std::time::Instant::now();
        let mut ok = true;
        for k in 0..n_videos {
            let path = dir.path().join(format!("run{k:03}.{ext}"));
            if k < DISTINCT {
                let traj = demo_trajectory(
                    nadir(&cfg.floor),
                    n_frames as f64 / fps + 0.05,
                    0.2,
                    0.7,
                    k as u64,
                );
                if render_video(&path, format, &cfg, &traj, fps, k as u64).is_err() {
                    ok = false;
                    break;
                }
            } else {
                // A hard link: the same bytes to decode, without writing gigabytes.
                let run: &PathBuf = &videos[k % DISTINCT];
                if std::fs::hard_link(run, &path).is_err() {
                    std::fs::copy(run, &path).expect("copy a rendered run");
                }
            }
            videos.push(path);
        }
        if !ok {
            println!("{ext}: this OpenCV cannot write it; skipped");
            continue;
        }
        println!("rendered {ext}: {:.1} s", t0.elapsed().as_secs_f64());
        let decode = |v: &Path| {
            let mut s = open_source(v, &SourceOptions::default()).expect("open video");
            let mut k = 0;
            loop {
                let b = s.next_batch(16).expect("decode");
                if b.is_empty() {
                    break k;
                }
                k += b.len();
            }
        };
        let track = |v: &Path| {
            let s = open_source(v, &SourceOptions::default()).expect("open video");
            let r = track_source(s, &cfg.camera, &cfg.floor, &opts, &mut |_, _| Ok(()))
                .expect("tracking");
            assert!(
                r.fixes().count() * 10 >= r.records.len() * 9,
                "{} tracked badly",
                v.display()
            );
            r.records.len()
        };
        let total = each_video(&videos, threads, &decode);
        // Decoding alone and decoding + tracking alternate: a shared machine's speed drifts
        // over minutes, and each pair's ratio compares neighbours.
        let (mut dec, mut trk, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..PAIRS {
            let d = timed(1, || {
                each_video(&videos, threads, &decode);
            });
            let t = timed(1, || {
                each_video(&videos, threads, &track);
            });
            ratios.push(d.0 / t.0);
            dec.push(d);
            trk.push(t);
        }
        let per = |t: f64| total as f64 / t;
        for (k, ((td, cd), (tt, ct))) in dec.iter().zip(&trk).enumerate() {
            println!(
                "  pair {}: decode alone {:7.1} frames/s wall (CPU {:.2} ms/frame), decode + tracking {:7.1} frames/s wall (CPU {:.2} ms/frame)",
                k + 1,
                per(*td),
                cd * 1e3 / total as f64,
                per(*tt),
                ct * 1e3 / total as f64
            );
        }
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        let shown: Vec<String> = ratios.iter().map(|r| format!("{r:.2}")).collect();
        println!(
            "  throughput of decode + tracking / decode alone ({ext}, {n_videos} videos): {mean:.2} (mean of the pairs' ratios {}; wall; target >= 0.8)",
            shown.join(", ")
        );
    }
    println!(
        "load average while running: {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}
