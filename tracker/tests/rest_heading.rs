//! The heading of a robot at rest, which fixes each run's start frame: a 1.5 m run turns a
//! heading error of 1 mrad into 1.5 mm at its end. The error at a still pose does not average
//! away over frames, so it is checked pose by pose across the floor and across angles near
//! the pixel grid's axes, where the corner fit of a small tag is worst.

use odocal_core::{wrap_angle, Pose2};
use odocal_synth::scene::{SceneConfig, SceneRenderer};
use odocal_tracker::{track_source, Frame, GrayFrame, MemorySource, Outcome, TrackOptions};

#[test]
fn heading_at_rest_is_within_a_milliradian() {
    let cfg = SceneConfig::default();
    let renderer = SceneRenderer::new(cfg.clone(), 3).unwrap();
    let mut errors = Vec::new();
    for &(x, y) in &[(-0.7, 0.17), (0.0, 0.0), (0.7, -0.2)] {
        for i in -6..=6 {
            let theta = i as f64 * 0.007;
            let still: Vec<(f64, Pose2)> = (0..50)
                .map(|k| (k as f64 * 0.01, Pose2::new(x, y, theta)))
                .collect();
            let frames: Vec<Frame> = (0..4)
                .map(|k| {
                    let t = k as f64 / 30.0;
                    let (img, _) = renderer.render_frame(&still, k, t).unwrap();
                    let (width, height) = img.dimensions();
                    Frame {
                        index: k,
                        t_s: t,
                        image: GrayFrame {
                            width,
                            height,
                            data: img.into_raw(),
                        },
                    }
                })
                .collect();
            let src = Box::new(MemorySource::new("still", frames));
            let res = track_source(
                src,
                &cfg.camera,
                &cfg.floor,
                &TrackOptions::default(),
                &mut |_, _| Ok(()),
            )
            .unwrap();
            let fixes: Vec<f64> = res
                .records
                .iter()
                .filter_map(|r| match &r.outcome {
                    Outcome::Fix(f) => Some(wrap_angle(f.pose.theta_rad - theta)),
                    _ => None,
                })
                .collect();
            assert_eq!(fixes.len(), 4, "pose ({x}, {y}, {theta}) not tracked");
            errors.push(fixes.iter().sum::<f64>() / fixes.len() as f64);
        }
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let max = errors.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    println!(
        "heading at rest over {} poses: RMS {:.2} mrad, max {:.2} mrad",
        errors.len(),
        rms * 1e3,
        max * 1e3
    );
    assert!(rms < 1.0e-3, "RMS heading error at rest {rms} rad");
    assert!(max < 2.5e-3, "largest heading error at rest {max} rad");
}
