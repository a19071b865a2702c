//! The realistic camera measured on its own images: every effect is checked by measuring
//! the rendered pixels (or the decoded file) against what physics predicts from the scene's
//! geometry, not by re-running the renderer's formulas.
//!
//! The scenes are small (640×360, a straight-down camera without distortion, so image x is
//! floor x and a floor length L at depth Z is L·f/Z pixels) and use a large tag, so edges are
//! long and clean.

use nalgebra::Point2;
use odocal_calib::CameraModel;
use odocal_core::Pose2;
use odocal_synth::scene::{
    ceiling_camera, nadir, straight_trajectory, CameraEffects, FrameTruth, SceneConfig,
    SceneRenderer,
};

const W: u32 = 640;
const H: u32 = 360;
const CAMERA_HEIGHT_M: f64 = 2.2;

/// A straight-down camera, no noise, steady light, a 0.6 m tag.
fn scene(exposure_s: f64, effects: CameraEffects) -> SceneConfig {
    let mut cfg = SceneConfig {
        camera: CameraModel::from_hfov(W, H, 70.0),
        floor: ceiling_camera(CAMERA_HEIGHT_M, 0.0, 0.0, 0.0),
        exposure_s,
        effects,
        ..SceneConfig::default()
    };
    cfg.sensor.noise_sigma = 0.0;
    cfg.lighting.amplitude = 0.0;
    cfg.robot.tag_size_m = 0.6;
    cfg.robot.body_radius_m = 0.3;
    cfg
}

/// Pixels per metre on the marker plane.
fn px_per_m(cfg: &SceneConfig) -> f64 {
    cfg.camera.intrinsics.fx / (CAMERA_HEIGHT_M - cfg.robot.marker_height_m)
}

/// A drive along +x through the image centre at `speed_mps`, heading 0.
fn drive(cfg: &SceneConfig, speed_mps: f64) -> Vec<(f64, Pose2)> {
    let c = nadir(&cfg.floor);
    straight_trajectory(
        Point2::new(c.x - 0.4, c.y),
        Point2::new(c.x + 0.4, c.y),
        speed_mps,
    )
}

fn render(cfg: &SceneConfig, traj: &[(f64, Pose2)], t_s: f64) -> (Vec<u8>, FrameTruth) {
    let r = SceneRenderer::new(cfg.clone(), 5).expect("renderer");
    let (img, truth) = r.render_frame(traj, 0, t_s).expect("frame");
    (img.into_raw(), truth)
}

/// Image x (pixels) of a floor x on the marker plane, for the straight-down camera.
fn image_x(cfg: &SceneConfig, floor_x: f64) -> f64 {
    let c = nadir(&cfg.floor);
    cfg.camera.intrinsics.cx + (floor_x - c.x) * px_per_m(cfg)
}

/// Rows of the tag's top black ring (the row of cells just inside the white border), for a
/// tag centred on the image centre row.
fn ring_rows(cfg: &SceneConfig) -> std::ops::Range<usize> {
    let cell_px = cfg.robot.tag_size_m / 8.0 * px_per_m(cfg);
    let top = cfg.camera.intrinsics.cy - 4.0 * cell_px;
    (top + 0.3 * cell_px).ceil() as usize..(top + 0.7 * cell_px).floor() as usize
}

/// The spread of a blurred step along a row: the derivative of the profile around `x_edge`
/// (±`half` pixels) is the motion's box kernel convolved with the pixel and the differencing
/// (two unit boxes), so its variance is (L² + 2) / 12 for a blur of length L.
fn blur_length_px(row: &[u8], x_edge: f64, half: usize) -> f64 {
    let c = x_edge.round() as usize;
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    for x in c - half..c + half {
        let g = row[x] as f64 - row[x + 1] as f64; // white to black: falling
        let xm = x as f64 + 0.5;
        s0 += g;
        s1 += g * xm;
        s2 += g * xm * xm;
    }
    let mean = s1 / s0;
    let var = s2 / s0 - mean * mean;
    (12.0 * var - 2.0).max(0.0).sqrt()
}

/// Motion blur: the edge between the tag's white border and its black ring, moving across
/// the image, is smeared over speed × exposure (in pixels) with the box profile of a true
/// integration over the exposure.
#[test]
fn motion_blur_length_is_speed_times_exposure() {
    for (speed_mps, exposure_s) in [(0.7, 0.010), (1.5, 0.028)] {
        let effects = CameraEffects {
            blur_step_px: Some(0.5),
            ..CameraEffects::default()
        };
        let cfg = scene(exposure_s, effects);
        let traj = drive(&cfg, speed_mps);
        let t = 0.4 / speed_mps; // tag centred in the image
        let (img, truth) = render(&cfg, &traj, t);
        let expected_px = speed_mps * exposure_s * px_per_m(&cfg);
        let pose = truth.pose;
        // Left edge of the black square at this time.
        let x_edge = image_x(&cfg, pose.x_m - cfg.robot.tag_size_m / 2.0);
        let half = (expected_px / 2.0 + 4.0).ceil() as usize;
        let rows = ring_rows(&cfg);
        let lengths: Vec<f64> = rows
            .clone()
            .map(|y| {
                let row = &img[y * W as usize..(y + 1) * W as usize];
                blur_length_px(row, x_edge, half)
            })
            .collect();
        let measured = lengths.iter().sum::<f64>() / lengths.len() as f64;
        println!(
            "{speed_mps} m/s, {} ms: blur measured {measured:.3} px over {} rows, speed × exposure {expected_px:.3} px, truth {:.3} px",
            exposure_s * 1e3,
            lengths.len(),
            truth.blur_px
        );
        assert!(
            (measured - expected_px).abs() < 0.25,
            "measured {measured} px, expected {expected_px} px"
        );
        assert!(
            (truth.blur_px - expected_px).abs() < 0.05,
            "{}",
            truth.blur_px
        );
    }
}

/// The x where a row crosses from the white border to the black ring (the mid grey level),
/// searched from `x0` rightwards; linear interpolation between pixels.
fn falling_crossing(row: &[u8], x0: usize, level: f64) -> Option<f64> {
    (x0..row.len() - 1).find_map(|x| {
        let (a, b) = (row[x] as f64, row[x + 1] as f64);
        (a >= level && b < level).then(|| x as f64 + (a - level) / (a - b))
    })
}

/// Rolling shutter: a vertical edge moving sideways is skewed, one row later seeing it
/// `speed · readout / rows` further on; the truth's tag-row time puts the edge exactly where
/// the image shows it.
#[test]
fn rolling_shutter_skews_a_moving_vertical_edge() {
    let speed_mps = 1.5;
    for readout_s in [0.0, 0.030] {
        let effects = CameraEffects {
            blur_step_px: Some(0.5),
            rolling_shutter_s: readout_s,
            ..CameraEffects::default()
        };
        let cfg = scene(0.0005, effects);
        let traj = drive(&cfg, speed_mps);
        let t = 0.4 / speed_mps - readout_s / 2.0; // tag centred at mid-readout
        let (img, truth) = render(&cfg, &traj, t);
        let s = cfg.robot.tag_size_m;
        let ppm = px_per_m(&cfg);
        let cell_px = s / 8.0 * ppm;
        let cy = cfg.camera.intrinsics.cy;
        // Rows of the black square, away from its top and bottom edges.
        let rows: Vec<usize> =
            ((cy - 3.5 * cell_px).ceil() as usize..(cy + 3.5 * cell_px) as usize).collect();
        let x_guess = image_x(&cfg, truth.pose.x_m - s / 2.0);
        let level = (220.0 + 22.0) / 2.0;
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter_map(|&y| {
                let row = &img[y * W as usize..(y + 1) * W as usize];
                let x0 = (x_guess - 0.6 * cell_px).max(0.0) as usize;
                falling_crossing(row, x0, level).map(|x| (y as f64, x))
            })
            .collect();
        assert!(pts.len() > 100, "{} rows with an edge", pts.len());
        let n = pts.len() as f64;
        let (my, mx) = (
            pts.iter().map(|p| p.0).sum::<f64>() / n,
            pts.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let slope = pts.iter().map(|p| (p.0 - my) * (p.1 - mx)).sum::<f64>()
            / pts.iter().map(|p| (p.0 - my).powi(2)).sum::<f64>();
        let expected = speed_mps * ppm * readout_s / H as f64;
        println!(
            "readout {} ms: edge skew {slope:.5} px/row, expected {expected:.5} px/row ({:.2} px over the tag)",
            readout_s * 1e3,
            expected * 8.0 * cell_px
        );
        assert!(
            (slope - expected).abs() < 0.02 * expected.abs() + 0.0005,
            "skew {slope} px/row, expected {expected}"
        );
        // The truth's tag row and its time: the edge in that row is where the pose at that
        // time puts it.
        let x_at_row = mx + slope * (truth.tag_row_px - my);
        let x_truth = image_x(&cfg, truth.pose_tag_row.x_m - s / 2.0);
        let expected_t = t + truth.tag_row_px * readout_s / H as f64;
        println!(
            "  tag row {:.2}: edge at {x_at_row:.3} px, pose at the row's time {x_truth:.3} px",
            truth.tag_row_px
        );
        assert!((truth.t_tag_row_s - expected_t).abs() < 1e-12);
        assert!((truth.tag_row_px - cy).abs() < 1.0, "{}", truth.tag_row_px);
        assert!(
            (x_at_row - x_truth).abs() < 0.1,
            "edge {x_at_row} px, truth {x_truth} px"
        );
    }
}

mod video {
    //! Dropped frames and H.264 read back through OpenCV's own decoder.

    use super::*;
    use odocal_synth::scene::{render_video, VideoFormat};
    use opencv::prelude::*;
    use opencv::videoio;

    /// A 40-frame drive at 30 frames/s in a small scene with noise.
    fn small(effects: CameraEffects) -> (SceneConfig, Vec<(f64, Pose2)>) {
        let mut cfg = scene(0.004, effects);
        cfg.robot.tag_size_m = 0.2;
        cfg.robot.body_radius_m = 0.12;
        cfg.sensor.noise_sigma = 2.0;
        let c = nadir(&cfg.floor);
        let traj = straight_trajectory(
            Point2::new(c.x - 0.5, c.y - 0.1),
            Point2::new(c.x + 0.5, c.y + 0.1),
            0.7,
        );
        let traj: Vec<_> = traj.into_iter().filter(|s| s.0 <= 1.32).collect();
        (cfg, traj)
    }

    /// Every frame of a video through OpenCV's FFmpeg backend: its presentation time
    /// (seconds) and grey image.
    fn decode(path: &std::path::Path) -> Vec<(f64, Vec<u8>)> {
        let mut cap = videoio::VideoCapture::from_file(path.to_str().unwrap(), videoio::CAP_FFMPEG)
            .expect("VideoCapture");
        assert!(cap.is_opened().unwrap(), "OpenCV cannot open {path:?}");
        let mut out = Vec::new();
        let mut m = opencv::core::Mat::default();
        while cap.read(&mut m).unwrap() && !m.empty() {
            let t = cap.get(videoio::CAP_PROP_POS_MSEC).unwrap() / 1000.0;
            let mut grey = opencv::core::Mat::default();
            opencv::imgproc::cvt_color(&m, &mut grey, opencv::imgproc::COLOR_BGR2GRAY, 0).unwrap();
            out.push((t, grey.data_bytes().unwrap().to_vec()));
        }
        out
    }

    /// Dropped frames are missing from the file and every other frame keeps its true time,
    /// as OpenCV's VideoCapture (the decoder odocal tracks with) reads it back, in MJPG AVI,
    /// H.264 MP4 and a PNG folder.
    #[test]
    fn dropped_frames_are_missing_and_the_rest_keep_their_times() {
        let effects = CameraEffects {
            drop_rate: 0.12,
            ..CameraEffects::default()
        };
        let (cfg, traj) = small(effects);
        let dir = tempfile::tempdir().unwrap();
        for (name, format) in [
            ("v.avi", VideoFormat::Avi),
            ("v.mp4", VideoFormat::Mp4),
            ("frames", VideoFormat::Png),
        ] {
            let path = dir.path().join(name);
            let truths = render_video(&path, format, &cfg, &traj, 30.0, 3).expect("render");
            assert_eq!(truths.len(), 40, "frames rendered");
            let kept: Vec<&FrameTruth> = truths.iter().filter(|t| !t.dropped).collect();
            let dropped: Vec<usize> = truths
                .iter()
                .filter(|t| t.dropped)
                .map(|t| t.index)
                .collect();
            assert!(
                (2..=10).contains(&dropped.len()) && !dropped.contains(&0),
                "dropped {dropped:?}"
            );
            if format == VideoFormat::Png {
                let csv = std::fs::read_to_string(path.join("timestamps.csv")).unwrap();
                for t in &truths {
                    assert_eq!(
                        path.join(odocal_synth::scene::png_name(t.index)).exists(),
                        !t.dropped
                    );
                }
                let times: Vec<f64> = csv
                    .lines()
                    .skip(1)
                    .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
                    .collect();
                assert_times(name, "timestamps.csv", &times, &kept);
                continue;
            }
            let decoded: Vec<f64> = decode(&path).iter().map(|f| f.0).collect();
            println!(
                "{name}: frames {dropped:?} dropped, {} of 40 in the file",
                decoded.len()
            );
            assert_eq!(decoded.len(), kept.len(), "{name}: frames in the file");
            // OpenCV gives no time (0) for the few frames its threaded H.264 decoder releases
            // only at the end of the file; FFmpeg's own reader gives every frame's.
            let timed = decoded.iter().skip(1).take_while(|&&t| t > 0.0).count() + 1;
            assert!(
                timed + 3 >= decoded.len() && decoded[timed..].iter().all(|&t| t == 0.0),
                "{name}: OpenCV times {decoded:?}"
            );
            assert_times(name, "OpenCV", &decoded[..timed], &kept[..timed]);
            assert_times(name, "ffprobe", &ffprobe_times(&path), &kept);
        }
    }

    /// Presentation times of every frame, from FFmpeg's own reader.
    fn ffprobe_times(path: &std::path::Path) -> Vec<f64> {
        let out = std::process::Command::new("ffprobe")
            .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
            .args(["frame=pts_time", "-of", "csv=p=0"])
            .arg(path)
            .output()
            .expect("ffprobe comes with ffmpeg (`make deps`)");
        String::from_utf8_lossy(&out.stdout)
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter_map(|x| x.parse().ok())
            .collect()
    }

    /// The file's times are the kept frames' true times: containers store them to the
    /// millisecond or finer, while a frame counted in the wrong place would be off by a whole
    /// frame period (33 ms).
    fn assert_times(name: &str, reader: &str, times: &[f64], kept: &[&FrameTruth]) {
        assert_eq!(times.len(), kept.len(), "{name} ({reader}): frames");
        for (t, truth) in times.iter().zip(kept) {
            assert!(
                (t - truth.t_s).abs() < 1e-3,
                "{name} ({reader}): frame {} at {t} s, true {} s",
                truth.index,
                truth.t_s
            );
        }
    }

    fn psnr_db(a: &[u8], b: &[u8]) -> f64 {
        let mse = a
            .iter()
            .zip(b)
            .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
            .sum::<f64>()
            / a.len() as f64;
        10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10()
    }

    /// H.264 at a camera's bitrate decodes through OpenCV with every frame, a file size that
    /// follows the bitrate, and the loss of a real camera's compression: a PSNR against the
    /// rendered frames that is plausible and grows with the bitrate.
    #[test]
    fn h264_at_a_bitrate_decodes_with_plausible_loss() {
        let dir = tempfile::tempdir().unwrap();
        let mut results = Vec::new();
        for kbps in [300.0, 2000.0] {
            let effects = CameraEffects {
                h264_bitrate_kbps: Some(kbps),
                ..CameraEffects::default()
            };
            let (cfg, traj) = small(effects);
            let path = dir.path().join(format!("v{kbps}.mp4"));
            let truths = render_video(&path, VideoFormat::Mp4, &cfg, &traj, 30.0, 4).unwrap();
            let decoded = decode(&path);
            assert_eq!(decoded.len(), truths.len(), "frames decoded");
            let renderer = SceneRenderer::new(cfg.clone(), 4).unwrap();
            let psnr: Vec<f64> = decoded
                .iter()
                .zip(&truths)
                .map(|((_, img), truth)| {
                    let (orig, _) = renderer
                        .render_frame(&traj, truth.index, truth.t_s)
                        .unwrap();
                    psnr_db(img, orig.as_raw())
                })
                .collect();
            let mean = psnr.iter().sum::<f64>() / psnr.len() as f64;
            let bytes = std::fs::metadata(&path).unwrap().len() as f64;
            let actual_kbps = bytes * 8.0 / 1000.0 / (truths.len() as f64 / 30.0);
            println!(
                "H.264 at {kbps} kbit/s: file {actual_kbps:.0} kbit/s, PSNR mean {mean:.1} dB (min {:.1})",
                psnr.iter().cloned().fold(f64::MAX, f64::min)
            );
            assert!(
                actual_kbps < 1.5 * kbps && actual_kbps > 0.3 * kbps,
                "{actual_kbps} kbit/s for a {kbps} kbit/s target"
            );
            results.push(mean);
        }
        // Sensor noise of σ 2 grey levels caps what any codec keeps at about 42 dB.
        assert!((28.0..40.0).contains(&results[0]), "{results:?}");
        assert!(
            results[1] > results[0] + 1.0 && results[1] < 48.0,
            "{results:?}"
        );
    }

    /// Same seed, same bytes, with every effect on (FFmpeg's encoders are bit-exact for one
    /// version of FFmpeg and libx264).
    #[test]
    fn realistic_videos_are_reproducible() {
        let mut effects = CameraEffects::realistic();
        effects.occlusion_s = 0.3;
        let (mut cfg, traj) = small(effects);
        cfg.exposure_s = odocal_synth::scene::REALISTIC_EXPOSURE_S;
        let dir = tempfile::tempdir().unwrap();
        let mut files = Vec::new();
        for (name, seed) in [("a.mp4", 8), ("b.mp4", 8), ("c.mp4", 9)] {
            let path = dir.path().join(name);
            let truths = render_video(&path, VideoFormat::Mp4, &cfg, &traj, 30.0, seed).unwrap();
            files.push((std::fs::read(&path).unwrap(), truths));
        }
        assert!(files[0].0 == files[1].0, "same seed, different bytes");
        assert_eq!(files[0].1, files[1].1);
        assert!(files[0].0 != files[2].0, "another seed, same bytes");
    }
}

mod light {
    //! Flicker, auto-exposure, vignetting, the light gradient and the paper tag, measured as
    //! the ratio of a frame to the same frame rendered under ideal light.

    use super::*;
    use odocal_synth::scene::{AutoExposure, Flicker, PaperTag, LAMP_FROM_CAMERA_M};

    /// The robot parked at `at` (floor metres), heading 0.
    fn parked(at: Point2<f64>) -> Vec<(f64, Pose2)> {
        let p = Pose2::new(at.x, at.y, 0.0);
        vec![(0.0, p), (100.0, p)]
    }

    /// A scene rendered with its effects and under ideal light.
    struct Pair(SceneRenderer, SceneRenderer);

    impl Pair {
        fn new(cfg: &SceneConfig) -> Self {
            let ideal = SceneConfig {
                effects: CameraEffects::default(),
                ..cfg.clone()
            };
            Self(
                SceneRenderer::new(cfg.clone(), 2).unwrap(),
                SceneRenderer::new(ideal, 2).unwrap(),
            )
        }

        /// Per-pixel ratio of frame `index` at `t_s` with the effects to the same frame
        /// without (NaN where the ideal frame is too dark to divide by).
        fn ratio(&self, traj: &[(f64, Pose2)], index: usize, t_s: f64) -> Vec<f64> {
            let (x, _) = self.0.render_frame(traj, index, t_s).unwrap();
            let (y, _) = self.1.render_frame(traj, index, t_s).unwrap();
            x.as_raw()
                .iter()
                .zip(y.as_raw())
                .map(|(&p, &q)| {
                    if q > 40 {
                        p as f64 / q as f64
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        }
    }

    fn ratio(cfg: &SceneConfig, traj: &[(f64, Pose2)], index: usize, t_s: f64) -> Vec<f64> {
        Pair::new(cfg).ratio(traj, index, t_s)
    }

    fn mean(v: impl Iterator<Item = f64>) -> f64 {
        let (s, n) = v
            .filter(|x| x.is_finite())
            .fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
        s / n as f64
    }

    /// Amplitude and frequency (within `freqs`) of the strongest sinusoid in `series`
    /// sampled at `rate` samples per unit.
    fn strongest(series: &[f64], rate: f64, freqs: impl Iterator<Item = f64>) -> (f64, f64) {
        let m = series.iter().sum::<f64>() / series.len() as f64;
        freqs
            .map(|f| {
                let (mut c, mut s) = (0.0, 0.0);
                for (k, v) in series.iter().enumerate() {
                    let a = std::f64::consts::TAU * f * k as f64 / rate;
                    c += (v - m) * a.cos();
                    s += (v - m) * a.sin();
                }
                (2.0 * c.hypot(s) / series.len() as f64, f)
            })
            .fold((0.0, 0.0), |best, x| if x.0 > best.0 { x } else { best })
    }

    /// 100 Hz flicker seen at 30 frames/s: the frames' brightness beats at the alias
    /// |100 − 3·30| = 10 Hz, with the depth a box exposure of length e leaves of a sinusoid
    /// (sin(πfe)/(πfe)); a 10 ms exposure spans one whole period and cancels it.
    #[test]
    fn flicker_beats_at_its_alias_and_a_10_ms_exposure_cancels_it() {
        let c = Point2::new(0.3, -0.2);
        for (exposure_s, depth) in [(0.002, 0.3), (0.010, 0.3)] {
            let effects = CameraEffects {
                flicker: Flicker {
                    frequency_hz: 100.0,
                    depth,
                },
                ..CameraEffects::default()
            };
            let mut cfg = scene(exposure_s, effects);
            cfg.robot.tag_size_m = 0.1;
            let traj = parked(nadir(&cfg.floor) + c.coords);
            let pair = Pair::new(&cfg);
            let series: Vec<f64> = (0..30)
                .map(|k| mean(pair.ratio(&traj, k, k as f64 / 30.0).into_iter()))
                .collect();
            let (amp, f) = strongest(&series, 30.0, (2..=60).map(|i| i as f64 * 0.25));
            let x = std::f64::consts::PI * 100.0 * exposure_s;
            let expected = depth * x.sin() / x;
            println!(
                "exposure {} ms: brightness beats at {f} Hz with amplitude {amp:.4} (expected {expected:.4})",
                exposure_s * 1e3
            );
            if expected > 0.05 {
                assert!((f - 10.0).abs() < 0.3, "beat at {f} Hz");
                assert!((amp - expected).abs() < 0.03 * expected, "amplitude {amp}");
            } else {
                assert!(amp < 0.01, "a whole period in the exposure leaves {amp}");
            }
        }
    }

    /// Under a rolling shutter the rows are exposed at different times, so 100 Hz flicker
    /// draws horizontal bands: f · readout of them per frame (3 for 30 ms).
    #[test]
    fn flicker_under_a_rolling_shutter_draws_bands() {
        let effects = CameraEffects {
            rolling_shutter_s: 0.030,
            flicker: Flicker {
                frequency_hz: 100.0,
                depth: 0.3,
            },
            ..CameraEffects::default()
        };
        let cfg = scene(0.002, effects);
        let traj = parked(nadir(&cfg.floor) + nalgebra::Vector2::new(0.6, 0.3));
        let r = ratio(&cfg, &traj, 0, 0.0);
        let rows: Vec<f64> = (0..H as usize)
            .map(|y| mean(r[y * W as usize..(y + 1) * W as usize].iter().cloned()))
            .collect();
        // Bands per frame height: frequency in cycles per H rows.
        let (amp, bands) = strongest(&rows, H as f64, (20..=200).map(|i| i as f64 * 0.05));
        println!("{bands} bands per frame, amplitude {amp:.3}");
        assert!((bands - 3.0).abs() < 0.1, "{bands} bands");
        assert!(amp > 0.2, "amplitude {amp}");
    }

    /// Vignetting darkens the corners to 1 − v of the centre; the gradient spans 1 ± g from
    /// one side of the image to the other; auto-exposure drifts the whole frame smoothly.
    #[test]
    fn vignetting_gradient_and_exposure_drift_shade_the_frame() {
        let at = Point2::new(0.6, 0.3);
        let patch = |r: &[f64], x0: usize, y0: usize| {
            mean(
                (y0..y0 + 5).flat_map(|y| r[y * W as usize + x0..y * W as usize + x0 + 5].to_vec()),
            )
        };
        // Vignetting alone.
        let mut cfg = scene(
            0.002,
            CameraEffects {
                vignetting: 0.3,
                ..CameraEffects::default()
            },
        );
        let traj = parked(nadir(&cfg.floor) + at.coords);
        let r = ratio(&cfg, &traj, 0, 0.0);
        let (w, h) = (W as usize, H as usize);
        let centre = patch(&r, w / 2 - 2, h / 2 - 2);
        let corners = [
            patch(&r, 0, 0),
            patch(&r, w - 5, 0),
            patch(&r, 0, h - 5),
            patch(&r, w - 5, h - 5),
        ];
        println!("vignetting 0.3: centre {centre:.3}, corners {corners:.3?}");
        assert!((centre - 1.0).abs() < 0.01);
        for c in corners {
            // The 5×5 patch is a few pixels in from the corner itself.
            assert!((c - 0.70).abs() < 0.015, "corner {c}");
        }
        // The gradient alone: a plane fitted to the ratio spans 1 ± g over the image.
        cfg.effects = CameraEffects {
            gradient: 0.3,
            ..CameraEffects::default()
        };
        let r = ratio(&cfg, &traj, 0, 0.0);
        let mut ata = nalgebra::Matrix3::<f64>::zeros();
        let mut atb = nalgebra::Vector3::<f64>::zeros();
        for y in (0..h).step_by(3) {
            for x in (0..w).step_by(3) {
                let v = r[y * w + x];
                if v.is_finite() {
                    let a = nalgebra::Vector3::new(1.0, x as f64, y as f64);
                    ata += a * a.transpose();
                    atb += a * v;
                }
            }
        }
        let p = ata.try_inverse().unwrap() * atb;
        let plane = |x: f64, y: f64| p[0] + p[1] * x + p[2] * y;
        let at_corners = [
            plane(0.0, 0.0),
            plane(w as f64, 0.0),
            plane(0.0, h as f64),
            plane(w as f64, h as f64),
        ];
        let (lo, hi) = at_corners
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        println!(
            "gradient 0.3: fitted plane from {lo:.3} to {hi:.3}, {:.3} at the centre",
            plane(w as f64 / 2.0, h as f64 / 2.0)
        );
        assert!(
            (lo - 0.7).abs() < 0.02 && (hi - 1.3).abs() < 0.02,
            "{lo} .. {hi}"
        );
        // Auto-exposure alone: one gain for the whole frame, drifting slowly between frames.
        cfg.effects = CameraEffects {
            auto_exposure: AutoExposure {
                sigma: 0.05,
                period_s: 1.0,
            },
            ..CameraEffects::default()
        };
        let pair = Pair::new(&cfg);
        let gains: Vec<f64> = (0..30)
            .map(|k| {
                let r = pair.ratio(&traj, k, k as f64 / 30.0);
                let m = mean(r.iter().cloned());
                let spread = mean(r.iter().map(|v| (v - m).powi(2))).sqrt();
                assert!(
                    spread < 0.01,
                    "frame {k}: the gain varies over the frame by {spread}"
                );
                m
            })
            .collect();
        let logs: Vec<f64> = gains.iter().map(|g| g.ln()).collect();
        let sd = (logs.iter().map(|l| l * l).sum::<f64>() / logs.len() as f64).sqrt();
        let step = logs
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        println!("auto-exposure σ 0.05: log gain RMS {sd:.3} over 1 s, largest frame-to-frame step {step:.4}");
        assert!(sd > 0.01 && sd < 0.15, "log gain RMS {sd}");
        assert!(step < 0.02, "step {step}");
    }

    /// Mean of the pixels of a 0.6 m tag's cells, the white border's and the black ring's
    /// (their middle halves), and the brightest white pixel, for a tag centred at pixel
    /// (cx, cy), heading 0.
    fn white_and_black(img: &[u8], cfg: &SceneConfig, (cx, cy): (f64, f64)) -> (f64, f64, f64) {
        let cell = cfg.robot.tag_size_m / 8.0 * px_per_m(cfg);
        let band = |from_cells: f64| -> Vec<f64> {
            // Pixels of the square ring from_cells..from_cells+1 cells out from the black
            // square's edge (negative: inside), its middle half only.
            let inner = 4.0 * cell + from_cells * cell + 0.25 * cell;
            let outer = inner + 0.5 * cell;
            let mut v = Vec::new();
            for y in (cy - outer) as usize..=(cy + outer) as usize {
                for x in (cx - outer) as usize..=(cx + outer) as usize {
                    let d = (x as f64 - cx).abs().max((y as f64 - cy).abs());
                    if d > inner && d < outer {
                        v.push(img[y * W as usize + x] as f64);
                    }
                }
            }
            v
        };
        let white = band(0.0);
        let black = band(-1.0);
        // The brightest pixel of the plate (a white cell: black + highlight stays far darker).
        let half = 4.5 * cell;
        let max_white = ((cy - half) as usize..=(cy + half) as usize)
            .flat_map(|y| ((cx - half) as usize..=(cx + half) as usize).map(move |x| (x, y)))
            .map(|(x, y)| img[y * W as usize + x] as f64)
            .fold(0.0, f64::max);
        (mean(white.into_iter()), mean(black.into_iter()), max_white)
    }

    /// A tag printed on paper has the print contrast asked for, and shows the lamp's soft
    /// highlight where the mirror geometry puts it (found here independently: the line from
    /// the camera's mirror image in the tag's plane to the lamp).
    #[test]
    fn paper_tag_has_its_contrast_and_a_highlight_where_the_lamp_reflects() {
        let paper = CameraEffects {
            paper: Some(PaperTag {
                contrast: 0.7,
                gloss: 0.15,
            }),
            ..CameraEffects::default()
        };
        let mut cfg = scene(0.002, paper);
        let c = cfg.floor.0.inverse().translation.vector;
        let m = cfg.robot.marker_height_m;
        let lamp = c + nalgebra::Vector3::from(LAMP_FROM_CAMERA_M);
        let mirror = nalgebra::Vector3::new(c.x, c.y, 2.0 * m - c.z);
        let s = (m - mirror.z) / (lamp.z - mirror.z);
        let spot = Point2::new(
            mirror.x + s * (lamp.x - mirror.x),
            mirror.y + s * (lamp.y - mirror.y),
        );
        let mut measure = |at: Point2<f64>, effects: CameraEffects| {
            cfg.effects = effects;
            let traj = parked(at);
            let r = SceneRenderer::new(cfg.clone(), 1).unwrap();
            let (img, _) = r.render_frame(&traj, 0, 0.0).unwrap();
            let px = cfg.camera.floor_to_pixel(&cfg.floor, &at, m).unwrap();
            white_and_black(img.as_raw(), &cfg, (px.x, px.y))
        };
        let far = Point2::new(c.x, c.y);
        let (w_ideal, b_ideal, _) = measure(far, CameraEffects::default());
        let (w, b, _) = measure(
            far,
            CameraEffects {
                paper: Some(PaperTag {
                    contrast: 0.7,
                    gloss: 0.0,
                }),
                ..CameraEffects::default()
            },
        );
        println!(
            "ideal tag: white {w_ideal:.1}, black {b_ideal:.1}, contrast {:.3}; paper: white {w:.1}, black {b:.1}, contrast {:.3}",
            (w_ideal - b_ideal) / w_ideal,
            (w - b) / w
        );
        assert!(
            ((w - b) / w - 0.7).abs() < 0.02,
            "paper contrast {}",
            (w - b) / w
        );
        assert!((w_ideal - b_ideal) / w_ideal > 0.85);
        let (_, _, peak_at_spot) = measure(spot, paper);
        let (_, _, peak_far) = measure(Point2::new(c.x - 0.8, c.y - 0.2), paper);
        println!(
            "highlight: brightest white {peak_at_spot:.1} with the tag at the lamp's mirror point {:.3?}, {peak_far:.1} 1.1 m away",
            (spot.x - c.x, spot.y - c.y)
        );
        let expected = 0.15 * 255.0;
        assert!(
            (peak_at_spot - w - expected).abs() < 0.15 * expected,
            "highlight {} grey levels over the paper's white, expected about {expected}",
            peak_at_spot - w
        );
        assert!(peak_far - w < 3.0, "far from the spot: {peak_far}");
    }
}

mod person {
    //! A person walking through: the truth's occluded frames are the frames whose tag the
    //! image shows covered.

    use super::*;

    #[test]
    fn a_person_hides_the_tag_for_about_the_time_asked_and_the_truth_says_when() {
        let effects = CameraEffects {
            blur_step_px: Some(0.5),
            occlusion_s: 1.0,
            ..CameraEffects::default()
        };
        let mut cfg = scene(0.008, effects);
        cfg.robot.tag_size_m = 0.1;
        cfg.robot.body_radius_m = 0.07;
        let c = nadir(&cfg.floor);
        let traj = straight_trajectory(
            Point2::new(c.x - 0.6, c.y - 0.2),
            Point2::new(c.x + 0.6, c.y + 0.1),
            0.4,
        );
        let ideal = SceneConfig {
            effects: CameraEffects {
                occlusion_s: 0.0,
                ..effects
            },
            ..cfg.clone()
        };
        let with = SceneRenderer::new(cfg.clone(), 3).unwrap();
        let without = SceneRenderer::new(ideal, 3).unwrap();
        let fps = 30.0;
        let n = (traj.last().unwrap().0 * fps) as usize;
        let plate_px = cfg.robot.tag_size_m * 10.0 / 8.0 * px_per_m(&cfg);
        let mut hidden = Vec::new();
        let mut covered = Vec::new();
        for k in 0..n {
            let t = k as f64 / fps;
            let (a, truth) = with.render_frame(&traj, k, t).unwrap();
            let (b, _) = without.render_frame(&traj, k, t).unwrap();
            // Pixels of the plate's inner 80 % that the person changes.
            let p = cfg
                .camera
                .floor_to_pixel(
                    &cfg.floor,
                    &truth.pose.position(),
                    cfg.robot.marker_height_m,
                )
                .unwrap();
            let r = 0.4 * plate_px;
            let (mut changed, mut all) = (0, 0);
            for y in (p.y - r) as u32..=(p.y + r) as u32 {
                for x in (p.x - r) as u32..=(p.x + r) as u32 {
                    all += 1;
                    changed += usize::from(
                        (a.get_pixel(x, y).0[0] as i32 - b.get_pixel(x, y).0[0] as i32).abs() > 8,
                    );
                }
            }
            hidden.push(truth.hidden_fraction);
            covered.push(changed as f64 / all as f64);
        }
        let occluded: Vec<usize> = (0..n).filter(|&k| hidden[k] > 0.0).collect();
        let first = *occluded.first().expect("the person hides the tag");
        let last = *occluded.last().unwrap();
        let span_s = (last - first + 1) as f64 / fps;
        println!(
            "occluded frames {first}..={last} ({span_s:.2} s), fully hidden {} frames, of {n}",
            hidden.iter().filter(|&&h| h >= 1.0).count()
        );
        assert_eq!(
            occluded.len(),
            last - first + 1,
            "one occlusion, without breaks"
        );
        assert!((0.7..1.5).contains(&span_s), "occlusion lasts {span_s} s");
        for k in 0..n {
            let settled = (k.saturating_sub(1)..(k + 2).min(n))
                .all(|j| (hidden[j] > 0.0) == (hidden[k] > 0.0));
            if !settled {
                continue; // the person's blurred edge crosses the tag
            }
            if hidden[k] >= 1.0 {
                assert!(
                    covered[k] > 0.9,
                    "frame {k}: truth hidden, image {:.2} covered",
                    covered[k]
                );
            } else if hidden[k] == 0.0 {
                assert!(
                    covered[k] == 0.0,
                    "frame {k}: truth visible, image {:.2} covered",
                    covered[k]
                );
            }
        }
    }
}
