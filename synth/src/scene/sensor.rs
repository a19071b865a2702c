//! A realistic camera: what a real USB or IP camera does to the ceiling scene.
//!
//! API: [`CameraEffects`] (a field of [`SceneConfig`], all off by default so a default
//! scene renders the same bytes as before) holds the exposure sampling, the rolling
//! shutter, light flicker, auto-exposure drift, vignetting, a light gradient, a tag printed
//! on paper, a person walking through, dropped frames and the H.264 bitrate.
//! [`CameraEffects::realistic`] is the combination used for "all conditions combined";
//! [`CameraEffects::check`] refuses settings without physical sense. The renderer
//! ([`SceneRenderer::render_frame`]) applies everything but the encoder and the drops, which
//! [`render_video`] applies; its per-frame truth is [`FrameTruth`], written by
//! [`frames_csv`] (frames.csv) and read back by [`FramesTruth`].
//!
//! Time convention (also written into scene.json by `synth track`): a frame's timestamp
//! `t_frame` is the centre of the exposure of pixel row 0. Pixel row `v` (0 at the top) is
//! exposed over `t_row(v) ± exposure_s / 2` with
//! `t_row(v) = t_frame + v · rolling_shutter_s / height_px`, so `rolling_shutter_s` is the
//! readout time of a whole frame. With a global shutter (`rolling_shutter_s = 0`) every row
//! is exposed around `t_frame`, as before.
//!
//! Photometry is linear (before noise and 8-bit quantisation): each pixel's radiance is
//! multiplied by the slow lighting change, the auto-exposure gain of the frame, the flicker
//! of the light integrated over the row's exposure (so a 10 ms exposure cancels 100 Hz
//! flicker, as it does in a real camera), the vignetting and the light gradient.

use super::*;

/// Mains flicker of the room light: intensity `1 + depth · cos(2π f t + φ)`, φ seeded.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Flicker {
    /// Frequency of the intensity change, Hz (twice the mains frequency: 100 or 120).
    pub frequency_hz: f64,
    /// Relative amplitude of the intensity change (0.3 = ±30 %); 0 for steady light.
    pub depth: f64,
}

/// Auto-exposure drift: the camera's gain wanders slowly, a smooth seeded function of time
/// `exp(sigma · s(t))` where s is a sum of four sinusoids with periods between 1 and 4
/// `period_s` and unit standard deviation. The gain is per frame (the camera sets it between
/// frames).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AutoExposure {
    /// Standard deviation of the log gain (0.05 = about ±5 %); 0 for a fixed gain.
    pub sigma: f64,
    /// Typical period of the drift, seconds.
    pub period_s: f64,
}

/// The room's lamp whose reflection a glossy paper tag shows, relative to the camera's
/// centre in the floor frame, metres.
pub const LAMP_FROM_CAMERA_M: [f64; 3] = [0.6, 0.4, 0.1];

/// A tag printed on paper instead of an ideal black-and-white target: its white is the
/// paper's (205 grey levels where the ideal target's is 220), its black `white · (1 −
/// contrast)`, and it reflects the lamp at [`LAMP_FROM_CAMERA_M`] in a soft lobe (0.12 rad).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PaperTag {
    /// Print contrast signal `(white − black) / white` of the print (0.7: the ink reflects
    /// 30 % of what the paper does); 1 would be ideal black ink.
    pub contrast: f64,
    /// Peak of the soft specular highlight of the room's lamp on the paper, as a fraction of
    /// full scale (0.15 adds up to 38 grey levels where the lamp's reflection is seen).
    pub gloss: f64,
}

/// Everything a real camera adds to the ideal scene. [`Default`] is all off.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CameraEffects {
    /// Largest image motion of the tag between two of the exposure's time samples, pixels:
    /// the exposure is integrated with `max(motion_samples, ⌈blur / step⌉ + 1)` samples so
    /// the blur is smooth. `None` keeps [`SceneConfig::motion_samples`] fixed.
    pub blur_step_px: Option<f64>,
    /// Readout time of a whole frame (row 0 to row `height`), seconds; 0 = global shutter.
    pub rolling_shutter_s: f64,
    /// Light flicker.
    pub flicker: Flicker,
    /// Auto-exposure drift.
    pub auto_exposure: AutoExposure,
    /// Relative fall-off of the light at the image corners (0.3: corners at 70 %), following
    /// `1 − vignetting · (r / r_corner)²` from the principal point.
    pub vignetting: f64,
    /// Uneven light: the gain changes linearly across the image along a seeded direction,
    /// from `1 − gradient` on one side to `1 + gradient` on the other.
    pub gradient: f64,
    /// The tag printed on paper; `None` for the ideal target.
    pub paper: Option<PaperTag>,
    /// A person walks between the camera and the robot, hiding the tag for about this long,
    /// seconds; 0 for nobody.
    pub occlusion_s: f64,
    /// Probability that a frame is dropped (missing from the file; the others keep their
    /// true timestamps). The first and last frames are never dropped.
    pub drop_rate: f64,
    /// H.264 bitrate for an MP4 video, kbit/s, encoded by FFmpeg's libx264 as a camera would
    /// (`None`: OpenCV's writer at its default quality).
    pub h264_bitrate_kbps: Option<f64>,
    /// The camera's tone curve: a pixel's 8-bit value is `255 · (v / 255)^(1 / tone_gamma)`
    /// for the linear value `v` (gain, lighting and noise applied), as a camera encodes its
    /// output for display; 1 keeps the output linear, 2.2 is about sRGB's.
    pub tone_gamma: f64,
}

impl Default for CameraEffects {
    fn default() -> Self {
        Self {
            blur_step_px: None,
            rolling_shutter_s: 0.0,
            flicker: Flicker {
                frequency_hz: 100.0,
                depth: 0.0,
            },
            auto_exposure: AutoExposure {
                sigma: 0.0,
                period_s: 3.0,
            },
            vignetting: 0.0,
            gradient: 0.0,
            paper: None,
            occlusion_s: 0.0,
            drop_rate: 0.0,
            h264_bitrate_kbps: None,
            tone_gamma: 1.0,
        }
    }
}

/// The rows' time convention in words, as truth files state it.
pub const ROW_TIME_CONVENTION: &str = "t_row(v) = t_frame + v * rolling_shutter_s / height_px for pixel row v (0 at the top); each row is exposed over t_row(v) +- exposure_s / 2; t_frame is the video's timestamp of the frame";

/// Exposure of the realistic preset, seconds: an indoor camera's automatic exposure (the
/// tag smears 11 mm, about 5 px, at 0.7 m/s 2.2 m below a 1280×720 camera).
pub const REALISTIC_EXPOSURE_S: f64 = 0.016;

/// Exposure sampling step of a realistic camera: two samples per pixel of motion.
pub const REALISTIC_BLUR_STEP_PX: f64 = 0.5;

impl CameraEffects {
    /// A plausible cheap ceiling camera in an ordinary room, every effect on ("all conditions
    /// combined"): 30 ms rolling-shutter readout, 100 Hz flicker of depth 0.4, ±5 %
    /// auto-exposure drift, vignetting 0.3, gradient 0.3, a paper tag (contrast 0.7, gloss
    /// 0.15), a person hiding the tag for 1 s, 1 % of frames dropped, H.264 at 4 Mbit/s.
    /// The exposure itself is [`SceneConfig::exposure_s`]: [`REALISTIC_EXPOSURE_S`] goes
    /// with this preset.
    pub fn realistic() -> Self {
        Self {
            blur_step_px: Some(REALISTIC_BLUR_STEP_PX),
            rolling_shutter_s: 0.030,
            flicker: Flicker {
                frequency_hz: 100.0,
                depth: 0.4,
            },
            auto_exposure: AutoExposure {
                sigma: 0.05,
                period_s: 3.0,
            },
            vignetting: 0.3,
            gradient: 0.3,
            paper: Some(PaperTag {
                contrast: 0.7,
                gloss: 0.15,
            }),
            occlusion_s: 1.0,
            drop_rate: 0.01,
            h264_bitrate_kbps: Some(4000.0),
            tone_gamma: 1.0,
        }
    }

    /// Whether the frame gain varies over the image (vignetting, gradient) or between rows
    /// (flicker under a rolling shutter).
    fn has_gain_map(&self) -> bool {
        self.vignetting > 0.0 || self.gradient > 0.0
    }

    /// Checks every setting for physical sense at the frame period `1 / fps`; the message
    /// names the command-line option.
    pub fn check(&self, fps: f64) -> Result<(), SceneError> {
        let bad = |m: String| Err(SceneError::Input(m));
        let period_s = 1.0 / fps;
        if let Some(s) = self.blur_step_px {
            if !(s.is_finite() && s >= 0.05) {
                return bad(format!(
                    "blur sampling step {s} px: must be at least 0.05 px"
                ));
            }
        }
        let rs = self.rolling_shutter_s;
        // Each row is read once per frame period, so the readout of all rows must fit in it.
        if !(rs.is_finite() && rs >= 0.0 && rs <= period_s + 1e-12) {
            return bad(format!(
                "--rolling-shutter-ms {}: must be between 0 and the {:.3} ms frame period",
                rs * 1e3,
                period_s * 1e3
            ));
        }
        let f = self.flicker;
        if !(f.depth.is_finite() && (0.0..1.0).contains(&f.depth)) {
            return bad(format!(
                "--flicker-depth {}: must be in [0, 1) (relative amplitude of the light's change)",
                f.depth
            ));
        }
        if f.depth > 0.0
            && !(f.frequency_hz.is_finite() && (1.0..=10_000.0).contains(&f.frequency_hz))
        {
            return bad(format!(
                "--flicker-hz {}: must be between 1 and 10000 Hz (100 or 120 for mains light)",
                f.frequency_hz
            ));
        }
        let ae = self.auto_exposure;
        if !(ae.sigma.is_finite() && (0.0..=0.5).contains(&ae.sigma)) {
            return bad(format!(
                "--auto-exposure {}: must be in [0, 0.5] (standard deviation of the log gain)",
                ae.sigma
            ));
        }
        if ae.sigma > 0.0 && !(ae.period_s.is_finite() && ae.period_s > 2.0 * period_s) {
            return bad(format!(
                "auto-exposure period {} s: must be longer than two frames",
                ae.period_s
            ));
        }
        if !(self.vignetting.is_finite() && (0.0..1.0).contains(&self.vignetting)) {
            return bad(format!(
                "--vignetting {}: must be in [0, 1) (relative fall-off at the corners)",
                self.vignetting
            ));
        }
        if !(self.gradient.is_finite() && (0.0..1.0).contains(&self.gradient)) {
            return bad(format!(
                "--gradient {}: must be in [0, 1) (relative change of the light across the image)",
                self.gradient
            ));
        }
        if let Some(p) = self.paper {
            if !(p.contrast.is_finite() && p.contrast > 0.1 && p.contrast <= 1.0) {
                return bad(format!(
                    "--paper-contrast {}: must be in (0.1, 1] (print contrast (white − black) / white)",
                    p.contrast
                ));
            }
            if !(p.gloss.is_finite() && (0.0..=0.5).contains(&p.gloss)) {
                return bad(format!(
                    "--paper-gloss {}: must be in [0, 0.5] (peak highlight, fraction of full scale)",
                    p.gloss
                ));
            }
        }
        if !(self.occlusion_s.is_finite() && (0.0..=10.0).contains(&self.occlusion_s)) {
            return bad(format!(
                "--occlusion-s {}: must be between 0 and 10 s",
                self.occlusion_s
            ));
        }
        if self.occlusion_s > 0.0 && self.occlusion_s < 2.0 * period_s {
            return bad(format!(
                "--occlusion-s {}: shorter than two frames; use at least {:.3} s",
                self.occlusion_s,
                2.0 * period_s
            ));
        }
        if !(self.tone_gamma.is_finite() && (1.0..=3.0).contains(&self.tone_gamma)) {
            return bad(format!(
                "--tone-gamma {}: a camera's tone curve has a gamma of 1 (linear) to 3 (2.2 is about sRGB's)",
                self.tone_gamma
            ));
        }
        if !(self.drop_rate.is_finite() && (0.0..=0.5).contains(&self.drop_rate)) {
            return bad(format!(
                "--drop-rate {}: must be between 0 and 0.5 (fraction of frames lost)",
                self.drop_rate
            ));
        }
        if let Some(b) = self.h264_bitrate_kbps {
            if !(b.is_finite() && (100.0..=200_000.0).contains(&b)) {
                return bad(format!(
                    "--bitrate-kbps {b}: must be between 100 and 200000 kbit/s (4000 is a typical USB or IP camera at 1280x720)"
                ));
            }
        }
        Ok(())
    }

    /// Time offset of pixel row `v` from the frame's timestamp, seconds.
    pub fn row_offset_s(&self, v: f64, height_px: u32) -> f64 {
        v * self.rolling_shutter_s / height_px.max(1) as f64
    }
}

/// `sin(πx) / (πx)`.
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-9 {
        1.0
    } else {
        let a = std::f64::consts::PI * x;
        a.sin() / a
    }
}

/// The seeded, time-dependent parts of the camera's photometry for one video.
#[derive(Debug, Clone)]
pub(crate) struct Photometry {
    effects: CameraEffects,
    exposure_s: f64,
    flicker_phase: f64,
    /// (angular frequency, phase, amplitude) of the auto-exposure drift's sinusoids.
    drift: Vec<(f64, f64, f64)>,
    /// Vignetting × gradient per pixel, row-major; empty when both are off.
    pub(crate) gain_map: Vec<f32>,
}

impl Photometry {
    pub(crate) fn new(config: &SceneConfig, seed: u64) -> Self {
        let e = config.effects;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x00ca_3e4a_f1c4);
        let flicker_phase = rng.gen_range(0.0..std::f64::consts::TAU);
        // Four sinusoids of equal amplitude have unit standard deviation at amplitude √(2/4).
        let drift = (0..4)
            .map(|i| {
                let period = e.auto_exposure.period_s.max(1e-6) * (1.0 + i as f64);
                (
                    std::f64::consts::TAU / period,
                    rng.gen_range(0.0..std::f64::consts::TAU),
                    (0.5f64).sqrt(),
                )
            })
            .collect();
        let direction: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
        let gain_map = if e.has_gain_map() {
            gain_map(&config.camera, e.vignetting, e.gradient, direction)
        } else {
            Vec::new()
        };
        Self {
            effects: e,
            exposure_s: config.exposure_s,
            flicker_phase,
            drift,
            gain_map,
        }
    }

    /// Light intensity averaged over an exposure centred at `t_s` (the flicker integrated
    /// over the exposure window).
    pub(crate) fn flicker(&self, t_s: f64) -> f64 {
        let f = self.effects.flicker;
        if f.depth == 0.0 {
            return 1.0;
        }
        let w = std::f64::consts::TAU * f.frequency_hz;
        1.0 + f.depth
            * sinc(f.frequency_hz * self.exposure_s)
            * (w * t_s + self.flicker_phase).cos()
    }

    /// Auto-exposure gain of the frame at `t_frame_s`.
    pub(crate) fn auto_exposure(&self, t_frame_s: f64) -> f64 {
        let sigma = self.effects.auto_exposure.sigma;
        if sigma == 0.0 {
            return 1.0;
        }
        let s: f64 = self
            .drift
            .iter()
            .map(|&(w, ph, a)| a * (w * t_frame_s + ph).sin())
            .sum();
        (sigma * s).exp()
    }
}

/// Vignetting × light gradient for every pixel of `camera`.
fn gain_map(camera: &CameraModel, vignetting: f64, gradient: f64, direction: f64) -> Vec<f32> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let (cx, cy) = (camera.intrinsics.cx, camera.intrinsics.cy);
    let corner2 = [
        (0.0, 0.0),
        (w as f64, 0.0),
        (0.0, h as f64),
        (w as f64, h as f64),
    ]
    .iter()
    .map(|&(x, y)| (x - cx).powi(2) + (y - cy).powi(2))
    .fold(0.0f64, f64::max)
    .max(1.0);
    let (ux, uy) = (direction.cos(), direction.sin());
    // Half the image's extent along the gradient's direction.
    let half = 0.5 * (w as f64 * ux.abs() + h as f64 * uy.abs());
    let (mx, my) = (w as f64 / 2.0, h as f64 / 2.0);
    let mut map = vec![0f32; w * h];
    map.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let yf = y as f64;
        for (x, g) in row.iter_mut().enumerate() {
            let xf = x as f64;
            let r2 = (xf - cx).powi(2) + (yf - cy).powi(2);
            let v = 1.0 - vignetting * r2 / corner2;
            let s = ((xf - mx) * ux + (yf - my) * uy) / half;
            *g = (v * (1.0 + gradient * s.clamp(-1.0, 1.0))) as f32;
        }
    });
    map
}

/// The frames of a video of `n` frames that the camera drops: each with probability
/// `drop_rate`, seeded, never the first or the last.
pub fn dropped_frames(n: usize, drop_rate: f64, seed: u64) -> Vec<bool> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x00d4_09f4_a3e5);
    (0..n)
        .map(|k| {
            let u: f64 = rng.gen();
            drop_rate > 0.0 && k > 0 && k + 1 < n && u < drop_rate
        })
        .collect()
}
