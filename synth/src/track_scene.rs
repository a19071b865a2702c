//! A tracking scene on disk, as `odocal synth track` writes it: a ceiling video of the robot
//! driving the demonstration path (video.avi, video.mp4 or frames/), the true camera.json,
//! the true trajectory (truth.csv), the camera's truth per frame (frames.csv: dropped,
//! occluded, blur, the rolling shutter's row times; see [`frames_csv`]), the scene's
//! settings (scene.json, with the camera's effects and its row-time convention when any is
//! on) and, when asked, the truth as a motion-capture system would record it (mocap.csv: the
//! robot's pose at its own rate, sampled between the camera's frames).

use std::path::{Path, PathBuf};

use odocal_calib::{CameraFile, FloorPlane};
use odocal_core::TagToRobot;
use serde::Serialize;

use crate::scene::{
    demo_trajectory, frames_csv, nadir, render_frames, truth_csv, CameraEffects, FrameTruth,
    SceneConfig, SceneError, VideoFormat, ROW_TIME_CONVENTION,
};

/// The `format` tag of scene.json.
pub const TRACK_SCENE_FORMAT: &str = "odocal.synth-track/1";

/// The scene to render.
#[derive(Debug, Clone)]
pub struct TrackScene {
    /// Random seed (floor texture, path phases, sensor noise).
    pub seed: u64,
    /// Number of frames.
    pub frames: usize,
    /// Container.
    pub format: VideoFormat,
    /// Frame rate, frames/s.
    pub fps: f64,
    /// Slowest robot speed, m/s.
    pub speed_min_mps: f64,
    /// Fastest robot speed, m/s.
    pub speed_max_mps: f64,
    /// Sensor noise σ, grey levels.
    pub noise_sigma: f32,
    /// Exposure time (motion blur), seconds.
    pub exposure_s: f64,
    /// Id of the robot's tag36h11 marker.
    pub tag_id: u32,
    /// Where the tag sits on the robot; the truth is the robot's (its axle midpoint).
    pub tag_to_robot: TagToRobot,
    /// The tag plate's tilt on the robot, degrees (its +x edge raised; 0: level).
    pub tag_tilt_deg: f64,
    /// What a real camera adds (all off by default).
    pub effects: CameraEffects,
    /// Rate of the motion-capture truth written to mocap.csv, Hz (none: not written).
    pub mocap_hz: Option<f64>,
}

/// The camera's effects as scene.json states them.
#[derive(Serialize)]
struct EffectsInfo {
    /// How the time of a pixel row follows from the frame's timestamp.
    row_time: &'static str,
    rolling_shutter_s: f64,
    exposure_s: f64,
    height_px: u32,
    flicker_hz: f64,
    flicker_depth: f64,
    auto_exposure_sigma: f64,
    vignetting: f64,
    gradient: f64,
    paper_contrast: Option<f64>,
    paper_gloss: Option<f64>,
    occlusion_s: f64,
    drop_rate: f64,
    tone_gamma: f64,
    h264_bitrate_kbps: Option<f64>,
    blur_step_px: Option<f64>,
    /// Frames missing from the video.
    dropped_frames: Vec<usize>,
    /// Frames in which a person hides part of the tag.
    occluded_frames: Vec<usize>,
}

#[derive(Serialize)]
struct SceneInfo {
    format: &'static str,
    seed: u64,
    fps: f64,
    frames: usize,
    video: String,
    tag_family: &'static str,
    tag_id: u32,
    tag_size_m: f64,
    marker_height_m: f64,
    /// Where the tag's centre sits on the robot, metres ahead of and left of the axle midpoint.
    tag_offset_m: [f64; 2],
    /// The tag's x axis from the robot's front, degrees counter-clockwise.
    tag_yaw_deg: f64,
    /// The tag plate's tilt on the robot, degrees (its +x edge raised).
    tag_tilt_deg: f64,
    exposure_s: f64,
    noise_sigma: f32,
    speed_min_mps: f64,
    speed_max_mps: f64,
    /// Frames in which the whole tag is not inside the image.
    tag_not_fully_visible: Vec<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    camera_effects: Option<EffectsInfo>,
}

/// What [`write_track_scene`] wrote.
pub struct TrackSceneSummary {
    /// Frames rendered.
    pub frames: usize,
    /// Of those, frames left out of the video as a camera drops them (`--drop-rate`).
    pub dropped: usize,
    /// The video (or frame folder), relative to the output directory.
    pub video: PathBuf,
    /// Image size, pixels.
    pub size_px: (u32, u32),
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), SceneError> {
    std::fs::write(path, bytes).map_err(|source| SceneError::Io {
        path: path.display().to_string(),
        source,
    })
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), SceneError> {
    let mut s = serde_json::to_string_pretty(value)
        .map_err(|e| SceneError::Input(format!("cannot serialise {}: {e}", path.display())))?;
    s.push('\n');
    write(path, s.as_bytes())
}

impl TrackScene {
    /// Checks the settings for sense; the message names the option.
    pub fn check(&self) -> Result<(), SceneError> {
        let bad = |m: String| Err(SceneError::Input(m));
        if self.frames == 0 {
            return bad("--frames must be at least 1".into());
        }
        let m = &self.tag_to_robot.0;
        // The tag plate stays on the robot's 12 cm body (or close to it) and in view.
        if !(m.x_m.hypot(m.y_m) <= 0.3 && m.theta_rad.is_finite()) {
            return bad(format!(
                "--tag-offset {},{} --tag-yaw {}: the simulated tag sits within 0.3 m of the axle midpoint (metres ahead, left) at a finite angle",
                m.x_m,
                m.y_m,
                m.theta_rad.to_degrees()
            ));
        }
        if self.tag_tilt_deg.is_nan() || self.tag_tilt_deg.abs() > 10.0 {
            return bad(format!(
                "--tag-tilt {}: the simulated tag plate is tilted on the robot by at most 10°",
                self.tag_tilt_deg
            ));
        }
        if !(self.fps > 0.0 && self.fps.is_finite()) {
            return bad(format!(
                "--fps {}: must be a positive number of frames per second",
                self.fps
            ));
        }
        if !(0.0 < self.speed_min_mps
            && self.speed_min_mps <= self.speed_max_mps
            && self.speed_max_mps < 5.0)
        {
            return bad(format!(
                "--speed-min {} --speed-max {}: need 0 < min ≤ max < 5 m/s",
                self.speed_min_mps, self.speed_max_mps
            ));
        }
        if !(self.noise_sigma >= 0.0 && self.noise_sigma <= 50.0) {
            return bad(format!("--noise {}: 0 to 50 grey levels", self.noise_sigma));
        }
        if !(self.exposure_s >= 0.0 && self.exposure_s < 1.0 / self.fps) {
            return bad(format!(
                "--exposure-ms {}: must be between 0 and the frame period, {:.3} ms at {} fps",
                self.exposure_s * 1000.0,
                1000.0 / self.fps,
                self.fps
            ));
        }
        if self.effects.h264_bitrate_kbps.is_some() && self.format != VideoFormat::Mp4 {
            return bad("--bitrate-kbps sets the H.264 bitrate: use it with --video mp4".into());
        }
        let duration_s = (self.frames.max(1) - 1) as f64 / self.fps;
        if self.effects.occlusion_s > 0.0 && duration_s < 2.5 * self.effects.occlusion_s {
            return bad(format!(
                "--occlusion-s {}: the {duration_s:.2} s video is too short for the person to walk through; use at least {} frames",
                self.effects.occlusion_s,
                (2.5 * self.effects.occlusion_s * self.fps).ceil() as usize + 1
            ));
        }
        if let Some(hz) = self.mocap_hz {
            if !(1.0..=10_000.0).contains(&hz) {
                return bad(format!(
                    "--mocap-hz {hz}: a motion-capture rate is 1 to 10000 Hz (100 to 360 is typical)"
                ));
            }
        }
        self.effects.check(self.fps)
    }
}

/// The robot's path as a motion-capture system at `hz` records it: its samples start a
/// quarter of their period after the camera's first frame, so that they fall between frames
/// as an unsynchronised system's do.
fn mocap_csv(
    path: &[(f64, odocal_core::Pose2)],
    hz: f64,
    duration_s: f64,
) -> Result<String, SceneError> {
    let rows = path
        .iter()
        .map(|(t_s, pose)| odocal_core::TrajectoryRow {
            t_s: *t_s,
            pose: *pose,
            quality: 1.0,
            sigma: None,
        })
        .collect();
    let fine = odocal_core::Trajectory::new(rows)
        .map_err(|e| SceneError::Input(format!("the simulated path: {e}")))?;
    let rows = (0..)
        .map(|j| (j as f64 + 0.25) / hz)
        .take_while(|t| *t <= duration_s)
        .filter_map(|t_s| {
            fine.pose_at(t_s, f64::INFINITY)
                .map(|pose| odocal_core::TrajectoryRow {
                    t_s,
                    pose,
                    quality: 1.0,
                    sigma: None,
                })
        })
        .collect();
    Ok(odocal_core::Trajectory { rows }.to_csv())
}

/// Renders the scene into the existing directory `out`; `on_frame` is called after each
/// frame (for a progress bar).
pub fn write_track_scene(
    out: &Path,
    s: &TrackScene,
    on_frame: &(dyn Fn(usize) + Sync),
) -> Result<TrackSceneSummary, SceneError> {
    s.check()?;
    let mut cfg = SceneConfig::default();
    cfg.robot.tag_id = s.tag_id;
    cfg.robot.tag_tilt_rad = s.tag_tilt_deg.to_radians();
    cfg.exposure_s = s.exposure_s;
    cfg.sensor.noise_sigma = s.noise_sigma;
    cfg.effects = s.effects;
    let duration = (s.frames - 1) as f64 / s.fps;
    let traj = demo_trajectory(
        nadir(&cfg.floor),
        duration + 0.01,
        s.speed_min_mps,
        s.speed_max_mps,
        s.seed,
    );
    // The path is the robot's; the camera sees its tag.
    let mount = s.tag_to_robot;
    let tag_path: Vec<_> = traj.iter().map(|(t, p)| (*t, mount.tag_pose(p))).collect();
    let name = match s.format {
        VideoFormat::Avi => "video.avi",
        VideoFormat::Mp4 => "video.mp4",
        VideoFormat::Png => "frames",
    };
    let truths = render_frames(
        &out.join(name),
        s.format,
        &cfg,
        &tag_path,
        s.fps,
        Some(s.frames),
        s.seed,
        on_frame,
    )?;
    let truths: Vec<_> = truths
        .into_iter()
        .take(s.frames)
        .map(|t| FrameTruth {
            pose: mount.robot_pose(&t.pose),
            pose_tag_row: mount.robot_pose(&t.pose_tag_row),
            ..t
        })
        .collect();
    let floor = FloorPlane {
        floor_to_camera: cfg.floor,
        plane_rms_m: 0.0,
        camera_height_m: cfg.floor.0.inverse().translation.vector.z,
        views: vec![],
    };
    write_json(
        &out.join("camera.json"),
        &CameraFile::from_model(cfg.camera, Some(floor)),
    )?;
    write(&out.join("truth.csv"), truth_csv(&truths, false).as_bytes())?;
    write(&out.join("frames.csv"), frames_csv(&truths).as_bytes())?;
    if let Some(hz) = s.mocap_hz {
        write(
            &out.join("mocap.csv"),
            mocap_csv(&traj, hz, duration)?.as_bytes(),
        )?;
    }
    let e = &s.effects;
    let camera_effects = (*e != CameraEffects::default()).then(|| EffectsInfo {
        row_time: ROW_TIME_CONVENTION,
        rolling_shutter_s: e.rolling_shutter_s,
        exposure_s: cfg.exposure_s,
        height_px: cfg.camera.height,
        flicker_hz: e.flicker.frequency_hz,
        flicker_depth: e.flicker.depth,
        auto_exposure_sigma: e.auto_exposure.sigma,
        vignetting: e.vignetting,
        gradient: e.gradient,
        paper_contrast: e.paper.map(|p| p.contrast),
        paper_gloss: e.paper.map(|p| p.gloss),
        occlusion_s: e.occlusion_s,
        drop_rate: e.drop_rate,
        tone_gamma: e.tone_gamma,
        h264_bitrate_kbps: e.h264_bitrate_kbps,
        blur_step_px: e.blur_step_px,
        dropped_frames: truths
            .iter()
            .filter(|t| t.dropped)
            .map(|t| t.index)
            .collect(),
        occluded_frames: truths
            .iter()
            .filter(|t| t.occluded())
            .map(|t| t.index)
            .collect(),
    });
    let hidden: Vec<usize> = truths
        .iter()
        .filter(|t| !t.tag_visible)
        .map(|t| t.index)
        .collect();
    write_json(
        &out.join("scene.json"),
        &SceneInfo {
            format: TRACK_SCENE_FORMAT,
            seed: s.seed,
            fps: s.fps,
            frames: truths.len(),
            video: name.into(),
            tag_family: "tag36h11",
            tag_id: s.tag_id,
            tag_size_m: cfg.robot.tag_size_m,
            marker_height_m: cfg.robot.marker_height_m,
            tag_offset_m: [mount.0.x_m, mount.0.y_m],
            tag_yaw_deg: mount.0.theta_rad.to_degrees(),
            tag_tilt_deg: s.tag_tilt_deg,
            exposure_s: cfg.exposure_s,
            noise_sigma: s.noise_sigma,
            speed_min_mps: s.speed_min_mps,
            speed_max_mps: s.speed_max_mps,
            tag_not_fully_visible: hidden,
            camera_effects,
        },
    )?;
    Ok(TrackSceneSummary {
        frames: truths.len(),
        dropped: truths.iter().filter(|t| t.dropped).count(),
        video: PathBuf::from(name),
        size_px: (cfg.camera.width, cfg.camera.height),
    })
}
