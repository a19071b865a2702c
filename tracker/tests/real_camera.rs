//! The tracker on video as a real camera records it, against the renderer's truth: the robot
//! at 0.7 m/s in the default 1280×720 scene (70° hfov, camera 2.2 m up, 8 cm tag of about 35
//! pixels), with a 10 ms exposure and a 30 ms rolling-shutter readout; with 9 px of motion blur;
//! with everything at once (7 px blur, light at 35 %, a light gradient, noise σ 6, JPEG 30);
//! with dropped frames; with the tag occluded. Each fix's σ is checked too: the errors divided
//! by σ have an RMS between 0.7 and 1.4 in every condition.
//!
//! The frames are degraded with OpenCV's filters (`common/mod.rs`); AprilTag 3's own
//! detection rate (decimation 2, its defaults) on the same frames is printed beside odocal's.
//! Frame counts are kept small for the test suite's time; `cargo test --release -p
//! odocal-tracker --test real_camera -- --nocapture` prints the figures.

mod common;

use common::*;
use odocal_core::Pose2;
use odocal_synth::scene::{pose_at, CameraEffects, SceneConfig};
use odocal_tracker::{GapReason, Outcome, ShutterEstimate, TrackOptions, TrackResult};

/// The rolling-shutter readout the fixes of `res` show (tracked without one).
fn shutter(cfg: &SceneConfig, res: &TrackResult) -> ShutterEstimate {
    ShutterEstimate::of(res, &cfg.camera, &cfg.floor, &TrackOptions::default())
        .expect("enough moving fixes")
}

/// The RMS of error/σ must show that σ is neither much too small nor much too large.
fn assert_sigma_honest(name: &str, s: &Score) {
    for (what, v) in [("x,y", s.nees_rms_xy), ("θ", s.nees_rms_theta)] {
        assert!(
            (0.7..=1.4).contains(&v),
            "{name}: RMS of error/σ ({what}) is {v:.2}, outside 0.7–1.4"
        );
    }
}

/// Pools the RMS of error/σ of several drives (weighted by their fixes).
fn pooled_nees(scores: &[Score]) -> (f64, f64) {
    let n: f64 = scores.iter().map(|s| s.fixes as f64).sum();
    let pool = |f: &dyn Fn(&Score) -> f64| {
        (scores
            .iter()
            .map(|s| s.fixes as f64 * f(s).powi(2))
            .sum::<f64>()
            / n)
            .sqrt()
    };
    (pool(&|s| s.nees_rms_xy), pool(&|s| s.nees_rms_theta))
}

#[test]
fn rolling_shutter_and_10ms_exposure() {
    // The synthetic camera's own rolling shutter: every row exposed at its own time.
    let cfg = SceneConfig {
        exposure_s: 0.010,
        motion_samples: 9,
        effects: CameraEffects {
            rolling_shutter_s: 0.030,
            ..CameraEffects::default()
        },
        ..SceneConfig::default()
    };
    let n = 300;
    // Three drives: error/σ over one 300-frame drive varies by ±25 % from drive to drive (its
    // errors are correlated over many frames), so σ is judged on their pooled fixes.
    let mut scores = Vec::new();
    for seed in [31u64, 32, 33] {
        let traj = fast_trajectory(&cfg, n as f64 / 30.0 + 0.1, seed);
        let (frames, _) = render(&cfg, &traj, 30.0, n, seed, &Degrade::none());
        let at3 = apriltag_rate(&frames, 0);
        let truth_at = |_: usize, t: f64| pose_at(&traj, t).expect("truth");
        let corrected = track(
            &cfg,
            frames.clone(),
            &TrackOptions {
                rolling_shutter_s: 0.030,
                ..TrackOptions::default()
            },
        );
        let s = score_with(&corrected, &truth_at);
        print(
            &format!("drive {seed}: 10 ms exposure, 30 ms rolling shutter, corrected"),
            &s,
            at3,
        );
        let plain = track(&cfg, frames, &TrackOptions::default());
        // Tracked without the readout, the tags' shear gives it away, within 10 %.
        let est = shutter(&cfg, &plain);
        eprintln!("drive {seed}: readout read off the tags' shear: {est:?}");
        assert!(est.shows_rolling_shutter(), "{est:?}");
        assert!((est.readout_s - 0.030).abs() <= 0.003, "{est:?}");
        let u = score_with(&plain, &truth_at);
        print(
            &format!("drive {seed}: 10 ms exposure, 30 ms rolling shutter, not corrected"),
            &u,
            at3,
        );
        // Each fix is timed at the tag centre's row: t = frame time + row / rows × readout.
        for (rec, f) in corrected.fixes() {
            let row = f.corners_px.iter().map(|c| c.y).sum::<f64>() / 4.0;
            let expected = rec.t_s + row / 720.0 * 0.030;
            assert!((f.t_s - expected).abs() < 1e-9, "{} vs {expected}", f.t_s);
        }
        assert!(s.tracked() >= 0.99, "tracked {:.3}", s.tracked());
        assert!(s.pos_rms_mm <= 1.0, "position RMS {:.3} mm", s.pos_rms_mm);
        assert!(
            s.heading_rms_deg <= 0.2,
            "heading RMS {:.3}°",
            s.heading_rms_deg
        );
        assert!(
            u.pos_rms_mm > 2.0 * s.pos_rms_mm,
            "the correction should matter: {:.3} mm without, {:.3} mm with",
            u.pos_rms_mm,
            s.pos_rms_mm
        );
        // No drive's σ is far off on its own.
        assert!(
            (0.55..=1.6).contains(&s.nees_rms_xy) && (0.55..=1.6).contains(&s.nees_rms_theta),
            "drive {seed}: error/σ RMS {:.2} (x,y) {:.2} (θ)",
            s.nees_rms_xy,
            s.nees_rms_theta
        );
        scores.push(s);
    }
    let (xy, theta) = pooled_nees(&scores);
    eprintln!(
        "error/σ RMS over the {} fixes of the three drives: {xy:.2} (x,y) {theta:.2} (θ)",
        scores.iter().map(|s| s.fixes).sum::<usize>()
    );
    for (what, v) in [("x,y", xy), ("θ", theta)] {
        assert!(
            (0.7..=1.4).contains(&v),
            "rolling shutter: pooled RMS of error/σ ({what}) is {v:.2}, outside 0.7–1.4"
        );
    }
}

#[test]
fn nine_pixel_motion_blur() {
    let cfg = SceneConfig::default();
    let n = 90;
    let traj = fast_trajectory(&cfg, n as f64 / 30.0 + 0.1, 21);
    let d = Degrade {
        blur_px: 9.0,
        ..Degrade::none()
    };
    let (frames, truths) = render(&cfg, &traj, 30.0, n, 21, &d);
    let at3 = apriltag_rate(&frames, 0);
    let res = track(&cfg, frames, &TrackOptions::default());
    let s = score_with(&res, &|i, _| truths[i].pose);
    print("9 px motion blur", &s, at3);
    // A global shutter's blur is no shear.
    let est = shutter(&cfg, &res);
    eprintln!("9 px blur, global shutter: readout read off the tags' shear: {est:?}");
    assert!(!est.shows_rolling_shutter(), "{est:?}");
    assert!(s.tracked() >= 0.95, "tracked {:.3}", s.tracked());
    assert!(s.pos_rms_mm <= 1.5, "position RMS {:.3} mm", s.pos_rms_mm);
    assert!(
        s.tracked() > at3,
        "odocal should beat AprilTag 3 alone here"
    );
    assert_sigma_honest("9 px blur", &s);
}

#[test]
fn everything_combined() {
    let cfg = SceneConfig::default();
    let n = 90;
    let traj = fast_trajectory(&cfg, n as f64 / 30.0 + 0.1, 23);
    let d = Degrade {
        blur_px: 7.0,
        gain: 0.35,
        gradient: 0.3,
        noise_sigma: 6.0,
        jpeg_quality: 30,
        readout_s: 0.0,
    };
    let (frames, truths) = render(&cfg, &traj, 30.0, n, 23, &d);
    let at3 = apriltag_rate(&frames, 0);
    let res = track(&cfg, frames, &TrackOptions::default());
    let s = score_with(&res, &|i, _| truths[i].pose);
    print("combined", &s, at3);
    let est = shutter(&cfg, &res);
    eprintln!("combined, global shutter: readout read off the tags' shear: {est:?}");
    assert!(!est.shows_rolling_shutter(), "{est:?}");
    assert!(
        s.tracked() >= MIN_COMBINED_TRACKED,
        "tracked {:.3}",
        s.tracked()
    );
    assert!(s.pos_rms_mm <= 2.0, "position RMS {:.3} mm", s.pos_rms_mm);
    assert!(s.pos_max_mm <= 10.0, "worst fix {:.2} mm off", s.pos_max_mm);
    assert_sigma_honest("combined", &s);
}

const MIN_COMBINED_TRACKED: f64 = 0.95;

#[test]
fn dropped_frames_keep_their_times() {
    let cfg = SceneConfig::default();
    let n = 30;
    let traj = fast_trajectory(&cfg, n as f64 / 30.0 + 0.1, 41);
    let (frames, truths) = render(&cfg, &traj, 30.0, n, 41, &Degrade::none());
    // Frames 10–14 never arrive: the source's indices and times skip them.
    let kept: Vec<_> = frames
        .into_iter()
        .filter(|f| !(10..15).contains(&f.index))
        .collect();
    let res = track(&cfg, kept, &TrackOptions::default());
    let tr = res.trajectory().expect("trajectory");
    assert_eq!(tr.rows.len(), n - 5);
    for row in &tr.rows {
        let truth = truths
            .iter()
            .find(|t| t.t_s == row.t_s)
            .expect("every fix at a frame's own time, exactly");
        assert!((row.pose.position() - truth.pose.position()).norm() < 1e-3);
    }
    // The robot moves 12 cm while the frames are missing: no jump rejection after the drop.
    assert_eq!(
        res.records
            .iter()
            .filter(|r| matches!(r.outcome, Outcome::Gap(_)))
            .count(),
        0
    );
}

#[test]
fn occlusion_is_a_flagged_gap_without_poses() {
    let cfg = SceneConfig::default();
    let n = 60;
    let traj = fast_trajectory(&cfg, n as f64 / 30.0 + 0.1, 43);
    let (mut frames, truths) = render(&cfg, &traj, 30.0, n, 43, &Degrade::none());
    // A person walks through: frames 20–49 (one second) have the robot covered.
    let occluded = 20..50;
    for f in frames.iter_mut().filter(|f| occluded.contains(&f.index)) {
        let p = cfg
            .camera
            .floor_to_pixel(
                &cfg.floor,
                &truths[f.index].pose.position(),
                cfg.robot.marker_height_m,
            )
            .expect("in view");
        let w = f.image.width as i64;
        for y in (p.y as i64 - 60).max(0)..(p.y as i64 + 60).min(f.image.height as i64) {
            for x in (p.x as i64 - 60).max(0)..(p.x as i64 + 60).min(w) {
                f.image.data[(y * w + x) as usize] = 90;
            }
        }
    }
    let res = track(&cfg, frames, &TrackOptions::default());
    let gaps = res.gaps();
    assert_eq!(gaps.len(), 1, "{gaps:?}");
    assert_eq!((gaps[0].first_index, gaps[0].last_index), (20, 49));
    assert_eq!(
        gaps[0].reasons.get(GapReason::NotDetected.as_str()),
        Some(&30)
    );
    let tr = res.trajectory().expect("trajectory");
    assert_eq!(tr.rows.len(), n - 30);
    assert!(tr
        .rows
        .iter()
        .all(|r| !(truths[20].t_s..=truths[49].t_s).contains(&r.t_s)));
    // Tracked again right after, and right.
    let Outcome::Fix(f) = res.records[50].outcome else {
        panic!("frame 50 not tracked")
    };
    let truth: Pose2 = truths[50].pose;
    assert!((f.pose.position() - truth.position()).norm() < 1e-3);
}
