//! Writing rendered frames: MJPG AVI or H.264 MP4 through FFmpeg, or a PNG folder with a
//! timestamp CSV.

use super::*;

/// Output container of [`render_video`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VideoFormat {
    /// Motion-JPEG in an AVI file (FFmpeg's MJPEG encoder).
    Avi,
    /// H.264 in an MP4 file (through FFmpeg).
    Mp4,
    /// A folder of PNG frames `frame_NNNNNN.png` plus `timestamps.csv` (`file,t`).
    Png,
}

impl std::str::FromStr for VideoFormat {
    type Err = SceneError;
    fn from_str(s: &str) -> Result<Self, SceneError> {
        match s.to_ascii_lowercase().as_str() {
            "avi" | "mjpg" => Ok(Self::Avi),
            "mp4" | "h264" => Ok(Self::Mp4),
            "png" => Ok(Self::Png),
            _ => Err(SceneError::Input(format!(
                "unknown video format {s:?}: use avi, mp4 or png"
            ))),
        }
    }
}

/// Renders a video of a robot following `trajectory` (timed floor poses, seconds
/// and [`Pose2`]) seen by the scene's camera at `fps`, and writes it to `out`:
/// an `.avi` (MJPG) or `.mp4` (H.264) file, or for [`VideoFormat::Png`] a folder
/// of `frame_NNNNNN.png` plus `timestamps.csv`. Frame k is at
/// t = t_first + k / fps. Same seed → same frames. Returns the per-frame truth (every
/// frame, dropped ones too). With the config's [`CameraEffects`], frames are dropped (left
/// out of the file, the others keeping their timestamps) and MP4 is encoded at the set
/// H.264 bitrate, both by FFmpeg's command-line program.
pub fn render_video(
    out: &Path,
    format: VideoFormat,
    config: &SceneConfig,
    trajectory: &[(f64, Pose2)],
    fps: f64,
    seed: u64,
) -> Result<Vec<FrameTruth>, SceneError> {
    render_video_with_progress(out, format, config, trajectory, fps, seed, &|_| {})
}

/// [`render_video`] that calls `on_frame(k)` after each frame is written (for a progress bar).
pub fn render_video_with_progress(
    out: &Path,
    format: VideoFormat,
    config: &SceneConfig,
    trajectory: &[(f64, Pose2)],
    fps: f64,
    seed: u64,
    on_frame: &(dyn Fn(usize) + Sync),
) -> Result<Vec<FrameTruth>, SceneError> {
    render_frames(out, format, config, trajectory, fps, None, seed, on_frame)
}

/// [`render_video_with_progress`] of the first `frames` frames only (all of the trajectory's
/// when None): a trajectory that runs on past the last frame wanted, by less than a frame
/// period at 30 fps but by more at 100 fps and above, put frames in the file that its truth
/// did not have.
#[allow(clippy::too_many_arguments)]
pub fn render_frames(
    out: &Path,
    format: VideoFormat,
    config: &SceneConfig,
    trajectory: &[(f64, Pose2)],
    fps: f64,
    frames: Option<usize>,
    seed: u64,
    on_frame: &(dyn Fn(usize) + Sync),
) -> Result<Vec<FrameTruth>, SceneError> {
    if !(fps > 0.0 && fps.is_finite()) {
        return Err(SceneError::Input(format!(
            "frame rate must be positive, got {fps}"
        )));
    }
    if trajectory.len() < 2 {
        return Err(SceneError::Input(
            "trajectory needs at least two timed poses".into(),
        ));
    }
    if trajectory.windows(2).any(|w| w[1].0 <= w[0].0) {
        return Err(SceneError::Input(
            "trajectory times must increase strictly".into(),
        ));
    }
    config.effects.check(fps)?;
    let renderer = SceneRenderer::new(config.clone(), seed)?;
    let mut times = frame_times(trajectory, fps);
    if let Some(n) = frames {
        times.truncate(n);
    }
    let dropped = dropped_frames(times.len(), config.effects.drop_rate, seed);
    let (w, h) = (config.camera.width as i32, config.camera.height as i32);
    let mut truths = Vec::with_capacity(times.len());
    // Renders frames `c·8 ..` of a batch in parallel; a dropped frame is not rendered.
    let batch = |c: usize, ts: &[f64]| {
        ts.par_iter()
            .enumerate()
            .map(|(j, &t)| {
                let k = c * 8 + j;
                if dropped[k] {
                    let mut truth = renderer.frame_truth(trajectory, k, t)?;
                    truth.dropped = true;
                    Ok((None, truth))
                } else {
                    let (img, truth) = renderer.render_frame(trajectory, k, t)?;
                    Ok((Some(img), truth))
                }
            })
            .collect::<Result<Vec<_>, SceneError>>()
    };
    let through_ffmpeg = dropped.iter().any(|&d| d)
        || (format == VideoFormat::Mp4 && config.effects.h264_bitrate_kbps.is_some());
    match format {
        VideoFormat::Png => {
            std::fs::create_dir_all(out).map_err(|e| io_err(out, e))?;
            let mut csv = String::from("file,t\n");
            // Render in small batches; encode the PNGs of a batch in parallel.
            for (c, ts) in times.chunks(8).enumerate() {
                let frames = batch(c, ts)?;
                frames
                    .par_iter()
                    .filter_map(|(img, truth)| img.as_ref().map(|img| (img, truth)))
                    .map(|(img, truth)| {
                        let path = out.join(png_name(truth.index));
                        img.save(&path).map_err(|e| SceneError::Encode {
                            path: path.display().to_string(),
                            reason: e.to_string(),
                        })
                    })
                    .collect::<Result<Vec<()>, SceneError>>()?;
                for (img, truth) in frames {
                    if img.is_some() {
                        csv.push_str(&format!("{},{}\n", png_name(truth.index), truth.t_s));
                    }
                    on_frame(truth.index);
                    truths.push(truth);
                }
            }
            let ts_path = out.join("timestamps.csv");
            std::fs::write(&ts_path, csv).map_err(|e| io_err(&ts_path, e))?;
        }
        VideoFormat::Avi | VideoFormat::Mp4 if through_ffmpeg => {
            let drops: Vec<usize> = (0..dropped.len()).filter(|&k| dropped[k]).collect();
            let mut writer = encode::FfmpegWriter::start(
                out,
                format,
                fps,
                (config.camera.width, config.camera.height),
                config.effects.h264_bitrate_kbps,
                &drops,
            )?;
            // FFmpeg's `select` removes the dropped frames; it is sent the previous image.
            let mut last: Option<GrayImage> = None;
            for (c, ts) in times.chunks(8).enumerate() {
                for (img, truth) in batch(c, ts)? {
                    if let Some(img) = img {
                        last = Some(img);
                    }
                    let bytes = last.as_ref().map(|i| i.as_raw().as_slice());
                    match bytes {
                        Some(b) => writer.write(b)?,
                        None => {
                            return Err(SceneError::Input(
                                "the first frame cannot be dropped".into(),
                            ))
                        }
                    }
                    on_frame(truth.index);
                    truths.push(truth);
                }
            }
            writer.finish()?;
        }
        VideoFormat::Avi | VideoFormat::Mp4 => {
            // Both through FFmpeg: OpenCV 4.6's own MJPEG encoder fails on 1-channel
            // frames and writes some frames that libjpeg reports as corrupt.
            let fourcc = match format {
                VideoFormat::Avi => videoio::VideoWriter::fourcc('M', 'J', 'P', 'G')?,
                _ => videoio::VideoWriter::fourcc('a', 'v', 'c', '1')?,
            };
            let mut writer = videoio::VideoWriter::new_with_backend(
                out,
                videoio::CAP_FFMPEG,
                fourcc,
                fps,
                Size::new(w, h),
                false,
            )?;
            if !writer.is_opened()? {
                return Err(SceneError::Encode {
                    path: out.display().to_string(),
                    reason: "OpenCV could not open a video writer for this file and codec".into(),
                });
            }
            for (c, ts) in times.chunks(8).enumerate() {
                for (img, truth) in batch(c, ts)? {
                    if let Some(img) = img {
                        let mat = Mat::new_rows_cols_with_data(h, w, img.as_raw())?;
                        writer.write(&mat)?;
                    }
                    on_frame(truth.index);
                    truths.push(truth);
                }
            }
            writer.release()?;
        }
    }
    Ok(truths)
}

/// File name of PNG frame `index`.
pub fn png_name(index: usize) -> String {
    format!("frame_{index:06}.png")
}

fn io_err(path: &Path, e: std::io::Error) -> SceneError {
    SceneError::Io {
        path: path.display().to_string(),
        source: e,
    }
}

/// Where a rendered PNG sequence keeps its timestamps.
pub fn png_timestamps(dir: &Path) -> PathBuf {
    dir.join("timestamps.csv")
}
