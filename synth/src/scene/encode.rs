//! Encoding as a camera records: FFmpeg's command-line program (installed by `make deps`)
//! takes the rendered frames as raw grey images on its standard input and writes H.264 at a
//! target bitrate (libx264, 4:2:0, what a USB or IP camera stores) or MJPG, leaving out the
//! dropped frames with `select` while every remaining frame keeps its true presentation
//! timestamp (`-fps_mode passthrough`), so a drop is a gap in the container's timeline.
//!
//! OpenCV's `VideoWriter` can do neither: it has no bitrate setting for H.264 and writes
//! frames at a constant rate. It stays the writer of the default videos (their bytes are
//! unchanged).
//!
//! Determinism: the output is byte-for-byte reproducible with the same FFmpeg and libx264
//! (bitexact flags, one encoder thread); another version of either may encode differently.

use std::io::Write;
use std::process::{Child, ChildStdin, Command, Stdio};

use super::*;

/// libx264's thread count. One: with frame threads its rate control (bitrate and VBV) is
/// not reproducible from run to run (measured with FFmpeg 5.1 and libx264 164), and the
/// renderer, not the encoder, is the slow part.
const X264_THREADS: &str = "1";

/// A running FFmpeg encoder fed with 8-bit grey frames.
pub(crate) struct FfmpegWriter {
    child: Child,
    stdin: Option<ChildStdin>,
    path: String,
    frame_bytes: usize,
}

impl FfmpegWriter {
    /// Starts FFmpeg writing `out` as `format` (AVI: MJPG; MP4: H.264 at `bitrate_kbps`, or
    /// at constant quality 18 without one) at `fps`, leaving out the frames whose index is
    /// in `dropped`.
    pub(crate) fn start(
        out: &Path,
        format: VideoFormat,
        fps: f64,
        size_px: (u32, u32),
        bitrate_kbps: Option<f64>,
        dropped: &[usize],
    ) -> Result<Self, SceneError> {
        let path = out.display().to_string();
        let fail = |reason: String| SceneError::Encode {
            path: path.clone(),
            reason,
        };
        let mut cmd = Command::new("ffmpeg");
        cmd.args(["-hide_banner", "-loglevel", "error", "-nostdin", "-y"])
            .args(["-f", "rawvideo", "-pix_fmt", "gray"])
            .args(["-s", &format!("{}x{}", size_px.0, size_px.1)])
            .args(["-framerate", &format!("{fps}")])
            .args(["-i", "-"]);
        if !dropped.is_empty() {
            let terms: Vec<String> = dropped.iter().map(|k| format!("eq(n\\,{k})")).collect();
            cmd.args(["-vf", &format!("select='not({})'", terms.join("+"))]);
        }
        cmd.args(["-fps_mode", "passthrough"])
            .args(["-fflags", "+bitexact", "-flags:v", "+bitexact"])
            .args(["-map_metadata", "-1"]);
        match format {
            VideoFormat::Avi => {
                cmd.args(["-c:v", "mjpeg", "-q:v", "3", "-pix_fmt", "yuvj420p"]);
            }
            VideoFormat::Mp4 => {
                cmd.args([
                    "-c:v", "libx264", "-preset", "veryfast", "-pix_fmt", "yuv420p",
                ])
                .args(["-threads", X264_THREADS])
                .args(["-g", &format!("{}", (2.0 * fps).round().max(1.0))]);
                match bitrate_kbps {
                    Some(b) => {
                        let b = b.round() as u64;
                        cmd.args(["-b:v", &format!("{b}k"), "-maxrate", &format!("{b}k")])
                            .args(["-bufsize", &format!("{}k", 2 * b)]);
                    }
                    None => {
                        cmd.args(["-crf", "18"]);
                    }
                }
            }
            VideoFormat::Png => {
                return Err(fail("PNG frames are not encoded by FFmpeg".into()));
            }
        }
        cmd.arg(out)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        let mut child = cmd.spawn().map_err(|e| {
            SceneError::Input(format!(
                "cannot run ffmpeg ({e}): H.264 at a set bitrate and dropped frames need FFmpeg's command-line program; install it (`make deps` or `apt-get install ffmpeg`)"
            ))
        })?;
        let stdin = child.stdin.take();
        Ok(Self {
            child,
            stdin,
            path,
            frame_bytes: size_px.0 as usize * size_px.1 as usize,
        })
    }

    /// Sends one frame (dropped ones too: FFmpeg's `select` removes them).
    pub(crate) fn write(&mut self, frame: &[u8]) -> Result<(), SceneError> {
        if frame.len() != self.frame_bytes {
            return Err(SceneError::Encode {
                path: self.path.clone(),
                reason: format!(
                    "frame of {} bytes, expected {}",
                    frame.len(),
                    self.frame_bytes
                ),
            });
        }
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(SceneError::Encode {
                path: self.path.clone(),
                reason: "ffmpeg's input is closed".into(),
            });
        };
        if stdin.write_all(frame).is_err() {
            // FFmpeg stopped: its own message says why.
            self.stdin = None;
            return Err(self.failure());
        }
        Ok(())
    }

    /// Closes FFmpeg's input and waits for it to finish the file.
    pub(crate) fn finish(mut self) -> Result<(), SceneError> {
        self.stdin = None;
        let status = self.child.wait().map_err(|e| SceneError::Encode {
            path: self.path.clone(),
            reason: format!("waiting for ffmpeg: {e}"),
        })?;
        if status.success() {
            Ok(())
        } else {
            Err(self.failure())
        }
    }

    fn failure(&mut self) -> SceneError {
        let _ = self.child.wait();
        let mut err = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            let _ = std::io::Read::read_to_string(&mut e, &mut err);
        }
        let first = err
            .lines()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("no message");
        SceneError::Encode {
            path: self.path.clone(),
            reason: format!("ffmpeg failed: {first}"),
        }
    }
}

impl Drop for FfmpegWriter {
    fn drop(&mut self) {
        // A writer abandoned on an error must not leave FFmpeg waiting for input.
        self.stdin = None;
        let _ = self.child.wait();
    }
}
