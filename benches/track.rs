//! Benchmark of the tracker on one default-scene 1280×720 video (30 fps, robot
//! at 0.2–0.7 m/s, noise σ = 2, 4 ms motion blur): frames per second of
//! tracking alone (frames already in memory) and of decode + tracking (MJPG AVI
//! and, when this OpenCV can write it, MP4/H.264), for ROI tracking and for
//! full-frame detection, with each mode's accuracy against the truth.
//!
//! Run: `cargo bench --bench track` (set `TRACK_BENCH_FRAMES` to change the
//! frame count, default 300: a 10 s video).

mod common;

use common::{cpu_s, median};
use std::time::Instant;

use odocal_core::wrap_angle;
use odocal_synth::scene::{
    demo_trajectory, frame_times, nadir, render_video, FrameTruth, SceneConfig, SceneRenderer,
    VideoFormat,
};
use odocal_tracker::{
    open_source, track_source, Frame, FrameSource, GrayFrame, MemorySource, SourceOptions,
    TrackOptions, TrackResult,
};

const REPS: usize = 3;
/// Alternating pairs of decoding alone and decoding + tracking.
const PAIRS: usize = 5;

fn accuracy(r: &TrackResult, truths: &[FrameTruth]) -> (f64, f64, usize) {
    let (mut sp, mut sh, mut n) = (0.0, 0.0, 0);
    for (rec, f) in r.fixes() {
        let t = &truths[rec.index];
        sp += (f.pose.position() - t.pose.position()).norm_squared();
        sh += wrap_angle(f.pose.theta_rad - t.pose.theta_rad).powi(2);
        n += 1;
    }
    (
        (sp / n as f64).sqrt() * 1e3,
        (sh / n as f64).sqrt().to_degrees(),
        n,
    )
}

fn run(
    cfg: &SceneConfig,
    make: &dyn Fn() -> Box<dyn FrameSource>,
    opts: &TrackOptions,
    reps: usize,
) -> (f64, f64, TrackResult) {
    let mut times = Vec::new();
    let mut cpus = Vec::new();
    let mut last = None;
    for _ in 0..reps {
        let src = make();
        let c0 = cpu_s();
        let t0 = Instant::now();
        let r = track_source(src, &cfg.camera, &cfg.floor, opts, &mut |_, _| Ok(()))
            .expect("tracking failed");
        times.push(t0.elapsed().as_secs_f64());
        cpus.push(cpu_s() - c0);
        last = Some(r);
    }
    (
        median(times),
        median(cpus),
        last.expect("at least one repetition"),
    )
}

/// "wall frames/s (CPU ms/frame -> frames/s on 2 free cores)".
fn rate(frames: usize, wall_s: f64, cpu_s: f64) -> String {
    let cpu_ms = cpu_s * 1e3 / frames as f64;
    format!(
        "{:8.1} frames/s wall  (CPU {:.2} ms/frame -> {:.0} frames/s on 2 free cores)",
        frames as f64 / wall_s,
        cpu_ms,
        2000.0 / cpu_ms
    )
}

fn main() {
    let n: usize = std::env::var("TRACK_BENCH_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300);
    let fps = 30.0;
    let cfg = SceneConfig::default();
    let traj = demo_trajectory(nadir(&cfg.floor), n as f64 / fps + 0.05, 0.2, 0.7, 5);
    let dir = tempfile::tempdir().expect("temp dir");
    println!(
        "track bench: {n} frames of the default 1280x720 scene, {} threads",
        rayon::current_num_threads()
    );

    let t0 = Instant::now();
    let renderer = SceneRenderer::new(cfg.clone(), 5).expect("scene");
    let mut frames = Vec::new();
    let mut truths = Vec::new();
    for (k, t) in frame_times(&traj, fps).into_iter().take(n).enumerate() {
        let (img, truth) = renderer.render_frame(&traj, k, t).expect("render");
        let (w, h) = img.dimensions();
        frames.push(Frame {
            index: k,
            t_s: t,
            image: GrayFrame {
                width: w,
                height: h,
                data: img.into_raw(),
            },
        });
        truths.push(truth);
    }
    println!("rendered in memory: {:.1} s", t0.elapsed().as_secs_f64());
    let avi = dir.path().join("bench.avi");
    let mp4 = dir.path().join("bench.mp4");
    let t0 = Instant::now();
    let truths_avi = render_video(&avi, VideoFormat::Avi, &cfg, &traj, fps, 5).expect("avi");
    assert_eq!(&truths_avi[..n], &truths[..]);
    let n_video = truths_avi.len();
    println!("rendered MJPG AVI: {:.1} s", t0.elapsed().as_secs_f64());
    let have_mp4 = render_video(&mp4, VideoFormat::Mp4, &cfg, &traj, fps, 5).is_ok();

    let roi = TrackOptions::default();
    let full = TrackOptions {
        use_roi: false,
        ..TrackOptions::default()
    };
    let mem = |frames: &Vec<Frame>| {
        let f = frames.clone();
        move || -> Box<dyn FrameSource> { Box::new(MemorySource::new("memory", f.clone())) }
    };
    let memsrc = mem(&frames);
    let (t_roi, c_roi, r_roi) = run(&cfg, &memsrc, &roi, REPS);
    let (t_full, c_full, r_full) = run(&cfg, &memsrc, &full, 1);
    let (pr, hr, nr) = accuracy(&r_roi, &truths);
    let (pf, hf, nf) = accuracy(&r_full, &truths);
    println!("tracking alone (frames in memory), ROI median of {REPS}, full frame 1 run:");
    println!("  ROI        {}", rate(n, t_roi, c_roi));
    println!("             pos RMS {pr:.3} mm  heading RMS {hr:.3} deg  fixes {nr}/{n}");
    println!("  full frame {}", rate(n, t_full, c_full));
    println!("             pos RMS {pf:.3} mm  heading RMS {hf:.3} deg  fixes {nf}/{n}");
    println!(
        "  ROI speed-up over full frame: {:.1}x wall, {:.1}x CPU",
        t_full / t_roi,
        c_full / c_roi
    );

    // Decoding alone and decoding + tracking alternate, pair by pair, and the ratio is the
    // median over the pairs: a shared machine's speed drifts over a run, and a ratio of
    // neighbours cancels most of that drift.
    // Decoding alone runs as in `track_source`: batches decoded on their own thread and
    // handed over through the same bounded channel, here to a consumer that only counts.
    let decode_alone = |path: &std::path::Path| {
        let c0 = cpu_s();
        let t0 = Instant::now();
        let mut s = open_source(path, &SourceOptions::default()).expect("open video");
        let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<Frame>>(3);
        let k = std::thread::scope(|scope| {
            scope.spawn(move || loop {
                let b = s.next_batch(16).expect("decode");
                if b.is_empty() || tx.send(b).is_err() {
                    break;
                }
            });
            rx.iter().map(|b| b.len()).sum::<usize>()
        });
        assert_eq!(k, n_video);
        (t0.elapsed().as_secs_f64(), cpu_s() - c0)
    };
    let compare = |label: &str, path: &std::path::Path| {
        // Opening the video is timed on both sides.
        let decode_and_track = || {
            let c0 = cpu_s();
            let t0 = Instant::now();
            let src = open_source(path, &SourceOptions::default()).expect("open video");
            let r = track_source(src, &cfg.camera, &cfg.floor, &roi, &mut |_, _| Ok(()))
                .expect("tracking failed");
            (t0.elapsed().as_secs_f64(), cpu_s() - c0, r)
        };
        let (mut dec, mut dec_cpu, mut both, mut both_cpu, mut ratios) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..PAIRS {
            let (t_d, c_d) = decode_alone(path);
            let (t_b, c_b, r) = decode_and_track();
            ratios.push(t_d / t_b);
            dec.push(t_d);
            dec_cpu.push(c_d);
            both.push(t_b);
            both_cpu.push(c_b);
            last = Some(r);
        }
        let r = last.expect("at least one pair");
        let (p, h, nf) = accuracy(&r, &truths_avi);
        let (lo, hi) = ratios
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        println!("{label}, {PAIRS} alternating pairs (medians):");
        println!(
            "  decode alone       {}",
            rate(n_video, median(dec), median(dec_cpu))
        );
        println!(
            "  decode + tracking  {}",
            rate(n_video, median(both), median(both_cpu))
        );
        println!("             pos RMS {p:.3} mm  heading RMS {h:.3} deg  fixes {nf}/{n_video}");
        println!(
            "  throughput of decode + tracking / decode alone ({label}): {:.2} (median of the pairs' ratios, range {lo:.2}-{hi:.2}; wall; target >= 0.8)",
            median(ratios)
        );
    };
    compare("MJPG AVI", &avi);
    let avi_src = || -> Box<dyn FrameSource> {
        open_source(&avi, &SourceOptions::default()).expect("open avi")
    };
    let (t_dfull, c_dfull, _) = run(&cfg, &avi_src, &full, 1);
    println!(
        "  decode + full-frame detection (MJPG AVI), 1 run: {}",
        rate(n_video, t_dfull, c_dfull)
    );
    if have_mp4 {
        compare("MP4/H.264", &mp4);
    } else {
        println!("MP4/H.264: this OpenCV cannot write it; skipped");
    }
    println!(
        "load average while running: {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}
