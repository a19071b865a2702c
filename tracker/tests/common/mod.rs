//! Degraded synthetic video for the robustness tests: frames rendered from a known camera and
//! trajectory, then degraded with OpenCV's filters the way a real camera degrades them (motion
//! blur along the tag's image motion, dimming, a light gradient, sensor noise, JPEG), or read
//! out row by row (rolling shutter), with AprilTag 3's own detection rate on the same frames.
#![allow(dead_code)]

use nalgebra::Vector2;
use odocal_core::{wrap_angle, Pose2};
use odocal_synth::scene::{frame_times, pose_at, FrameTruth, SceneConfig, SceneRenderer};
use odocal_tracker::{
    track_source, Frame, GrayFrame, MemorySource, TagDetector, TrackOptions, TrackResult,
};
use opencv::core::{Mat, Point, Scalar, Vector, CV_32F, CV_8U};
use opencv::prelude::*;
use opencv::{core, imgcodecs, imgproc};
use rayon::prelude::*;

/// A robot driving at 0.7 m/s on a closed path in view of the default camera.
pub fn fast_trajectory(cfg: &SceneConfig, duration_s: f64, seed: u64) -> Vec<(f64, Pose2)> {
    odocal_synth::scene::demo_trajectory(
        odocal_synth::scene::nadir(&cfg.floor),
        duration_s,
        0.7,
        0.7,
        seed,
    )
}

/// How frames are degraded after rendering.
#[derive(Debug, Clone, Copy, Default)]
pub struct Degrade {
    /// Length of a line blur along the tag's image motion, pixels (0: none).
    pub blur_px: f64,
    /// Light multiplied by this (1: unchanged).
    pub gain: f64,
    /// A horizontal light gradient: gain from 1 - g at the left edge to 1 + g at the right.
    pub gradient: f64,
    /// Additive Gaussian noise, grey levels.
    pub noise_sigma: f64,
    /// JPEG quality (0: no JPEG).
    pub jpeg_quality: i32,
    /// Rolling shutter: row y is read `y / rows · readout_s` after the frame time (0: global shutter).
    pub readout_s: f64,
}

impl Degrade {
    pub fn none() -> Self {
        Self {
            gain: 1.0,
            ..Self::default()
        }
    }
}

/// The image direction of the tag centre's motion at time `t_s`, unit vector (x right, y down).
fn image_motion(cfg: &SceneConfig, traj: &[(f64, Pose2)], t_s: f64) -> Vector2<f64> {
    let at = |t: f64| {
        let p = pose_at(traj, t).expect("trajectory");
        cfg.camera
            .floor_to_pixel(&cfg.floor, &p.position(), cfg.robot.marker_height_m)
            .expect("in view")
    };
    let d = at(t_s + 0.005) - at(t_s - 0.005);
    if d.norm() < 1e-9 {
        Vector2::new(1.0, 0.0)
    } else {
        d / d.norm()
    }
}

fn to_mat(img: &[u8], w: u32, h: u32) -> Mat {
    Mat::new_rows_cols_with_data(h as i32, w as i32, img)
        .expect("mat")
        .try_clone()
        .expect("mat")
}

fn from_mat(m: &Mat) -> Vec<u8> {
    m.data_bytes().expect("bytes").to_vec()
}

/// Applies `d` (except the rolling shutter) to one 8-bit frame with OpenCV's filters.
pub fn degrade(
    img: &[u8],
    w: u32,
    h: u32,
    d: &Degrade,
    motion: Vector2<f64>,
    seed: u64,
) -> Vec<u8> {
    let mut m = Mat::default();
    to_mat(img, w, h)
        .convert_to(&mut m, CV_32F, 1.0, 0.0)
        .expect("convert");
    if d.blur_px > 0.0 {
        // A line kernel of the given length along the motion, drawn anti-aliased by OpenCV.
        let k = (d.blur_px.ceil() as i32 + 2) | 1;
        let mut kernel = Mat::zeros(k, k, CV_32F)
            .expect("kernel")
            .to_mat()
            .expect("kernel");
        let c = (k / 2) as f64;
        let half = motion * (d.blur_px - 1.0) / 2.0;
        let shift = 8;
        let s = (1 << shift) as f64;
        let p0 = Point::new(
            ((c - half.x) * s).round() as i32,
            ((c - half.y) * s).round() as i32,
        );
        let p1 = Point::new(
            ((c + half.x) * s).round() as i32,
            ((c + half.y) * s).round() as i32,
        );
        imgproc::line(
            &mut kernel,
            p0,
            p1,
            Scalar::all(1.0),
            1,
            imgproc::LINE_AA,
            shift,
        )
        .expect("line");
        let sum = core::sum_elems(&kernel).expect("sum")[0];
        let mut norm = Mat::default();
        kernel
            .convert_to(&mut norm, CV_32F, 1.0 / sum, 0.0)
            .expect("norm");
        let mut out = Mat::default();
        imgproc::filter_2d(
            &m,
            &mut out,
            -1,
            &norm,
            Point::new(-1, -1),
            0.0,
            core::BORDER_REFLECT,
        )
        .expect("filter");
        m = out;
    }
    if d.gain != 1.0 || d.gradient != 0.0 {
        let mut ramp =
            Mat::new_rows_cols_with_default(h as i32, w as i32, CV_32F, Scalar::all(0.0))
                .expect("ramp");
        for y in 0..h as i32 {
            for x in 0..w as i32 {
                let g = d.gain * (1.0 + d.gradient * (2.0 * x as f64 / w as f64 - 1.0));
                *ramp.at_2d_mut::<f32>(y, x).expect("ramp") = g as f32;
            }
        }
        let mut out = Mat::default();
        core::multiply(&m, &ramp, &mut out, 1.0, -1).expect("multiply");
        m = out;
    }
    if d.noise_sigma > 0.0 {
        let mut noise =
            Mat::new_rows_cols_with_default(h as i32, w as i32, CV_32F, Scalar::all(0.0))
                .expect("noise");
        let mut rng = core::RNG::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1).expect("rng");
        rng.fill(
            &mut noise,
            core::RNG_NORMAL,
            &Scalar::all(0.0),
            &Scalar::all(d.noise_sigma),
            false,
        )
        .expect("randn");
        let mut out = Mat::default();
        core::add(&m, &noise, &mut out, &core::no_array(), -1).expect("add");
        m = out;
    }
    let mut out8 = Mat::default();
    m.convert_to(&mut out8, CV_8U, 1.0, 0.0).expect("to 8 bit");
    if d.jpeg_quality > 0 {
        let mut buf = Vector::<u8>::new();
        let params = Vector::from_slice(&[imgcodecs::IMWRITE_JPEG_QUALITY, d.jpeg_quality]);
        imgcodecs::imencode(".jpg", &out8, &mut buf, &params).expect("jpeg");
        out8 = imgcodecs::imdecode(&buf, imgcodecs::IMREAD_GRAYSCALE).expect("jpeg");
    }
    from_mat(&out8)
}

/// One rendered frame; with a rolling shutter the rows near the tag are rendered at their own
/// read-out times in bands of `band` rows (the rest of the image, the static floor, does not
/// change), the truth is the pose at the frame time.
fn render_one(
    r: &SceneRenderer,
    traj: &[(f64, Pose2)],
    k: usize,
    t: f64,
    readout_s: f64,
) -> (Vec<u8>, FrameTruth) {
    let cfg = r.config();
    let (img, truth) = r.render_frame(traj, k, t).expect("render");
    if readout_s <= 0.0 {
        return (img.into_raw(), truth);
    }
    let (w, h) = (cfg.camera.width as usize, cfg.camera.height as usize);
    let mut out = img.into_raw();
    // The rows the robot can cover during the readout.
    let (mut y0, mut y1) = (h as f64, 0.0f64);
    for i in 0..=20 {
        let tt = t + readout_s * i as f64 / 20.0;
        let Some(p) = pose_at(traj, tt) else { continue };
        for c in r.tag_corners(&p) {
            if let Some(px) = cfg
                .camera
                .floor_to_pixel(&cfg.floor, &c, cfg.robot.marker_height_m)
            {
                y0 = y0.min(px.y);
                y1 = y1.max(px.y);
            }
        }
    }
    let band = 3usize;
    let first = ((y0 - 12.0).max(0.0) as usize / band) * band;
    let last = ((y1 + 12.0).min(h as f64 - 1.0)) as usize;
    let mut y = first;
    while y <= last {
        let tt = t + readout_s * (y as f64 + 0.5 * band as f64 - 0.5) / h as f64;
        let (im, _) = r.render_frame(traj, k, tt).expect("render");
        let raw = im.as_raw();
        let end = (y + band).min(h);
        out[y * w..end * w].copy_from_slice(&raw[y * w..end * w]);
        y += band;
    }
    (out, truth)
}

/// Renders `n` frames at `fps` and degrades them.
pub fn render(
    cfg: &SceneConfig,
    traj: &[(f64, Pose2)],
    fps: f64,
    n: usize,
    seed: u64,
    d: &Degrade,
) -> (Vec<Frame>, Vec<FrameTruth>) {
    let r = SceneRenderer::new(cfg.clone(), seed).expect("scene");
    let times: Vec<f64> = frame_times(traj, fps).into_iter().take(n).collect();
    let (w, h) = (cfg.camera.width, cfg.camera.height);
    times
        .par_iter()
        .enumerate()
        .map(|(k, &t)| {
            let (raw, truth) = render_one(&r, traj, k, t, d.readout_s);
            let motion = image_motion(cfg, traj, t);
            let data = degrade(&raw, w, h, d, motion, seed * 1000 + k as u64);
            let frame = Frame {
                index: k,
                t_s: t,
                image: GrayFrame {
                    width: w,
                    height: h,
                    data,
                },
            };
            (frame, truth)
        })
        .unzip()
}

pub fn track(cfg: &SceneConfig, frames: Vec<Frame>, opts: &TrackOptions) -> TrackResult {
    let src = Box::new(MemorySource::new("synthetic", frames));
    track_source(src, &cfg.camera, &cfg.floor, opts, &mut |_, _| Ok(())).expect("tracking")
}

/// Figures of one condition against the truth.
#[derive(Debug, Clone, Copy)]
pub struct Score {
    pub frames: usize,
    pub fixes: usize,
    pub pos_rms_mm: f64,
    pub pos_max_mm: f64,
    pub heading_rms_deg: f64,
    /// RMS of error/σ over x, y (position) and θ.
    pub nees_rms_xy: f64,
    pub nees_rms_theta: f64,
}

impl Score {
    pub fn tracked(&self) -> f64 {
        self.fixes as f64 / self.frames as f64
    }
}

/// Scores fixes against `truth_at(record)`: the pose each fix should have.
pub fn score_with(res: &TrackResult, truth_at: &dyn Fn(usize, f64) -> Pose2) -> Score {
    let (mut sp, mut sh, mut mx, mut n) = (0.0, 0.0, 0.0f64, 0usize);
    let (mut zxy, mut zt, mut nz) = (0.0, 0.0, 0usize);
    for (rec, f) in res.fixes() {
        let truth = truth_at(rec.index, f.t_s);
        let e = f.pose.position() - truth.position();
        let eh = wrap_angle(f.pose.theta_rad - truth.theta_rad);
        sp += e.norm_squared();
        sh += eh * eh;
        mx = mx.max(e.norm());
        n += 1;
        let s = f.sigma;
        zxy += (e.x / s.x_m).powi(2) + (e.y / s.y_m).powi(2);
        zt += (eh / s.theta_rad).powi(2);
        nz += 1;
    }
    Score {
        frames: res.records.len(),
        fixes: n,
        pos_rms_mm: (sp / n.max(1) as f64).sqrt() * 1e3,
        pos_max_mm: mx * 1e3,
        heading_rms_deg: (sh / n.max(1) as f64).sqrt().to_degrees(),
        nees_rms_xy: (zxy / (2 * nz).max(1) as f64).sqrt(),
        nees_rms_theta: (zt / nz.max(1) as f64).sqrt(),
    }
}

/// AprilTag 3's own detection rate on the frames: the C library with decimation 2 and its
/// defaults, counting frames where it reports the robot's tag.
pub fn apriltag_rate(frames: &[Frame], tag_id: u32) -> f64 {
    let hits: usize = frames
        .par_chunks(8)
        .map(|chunk| {
            let mut det = TagDetector::reference("tag36h11").expect("detector");
            chunk
                .iter()
                .filter(|f| {
                    det.detect_raw(&f.image)
                        .expect("detect")
                        .iter()
                        .any(|d| d.id == tag_id)
                })
                .count()
        })
        .sum();
    hits as f64 / frames.len() as f64
}

/// Prints one line of a condition's figures.
pub fn print(name: &str, s: &Score, at3: f64) {
    eprintln!(
        "{name}: tracked {:.1} % ({}/{}), position RMS {:.3} mm, max {:.2} mm, heading RMS {:.3}°, error/σ RMS {:.2} (x,y) {:.2} (θ); AprilTag 3 (decimate 2) detects {:.1} %",
        100.0 * s.tracked(),
        s.fixes,
        s.frames,
        s.pos_rms_mm,
        s.pos_max_mm,
        s.heading_rms_deg,
        s.nees_rms_xy,
        s.nees_rms_theta,
        100.0 * at3
    );
}
