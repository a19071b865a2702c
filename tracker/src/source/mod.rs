//! Frame sources: video files through OpenCV's FFmpeg backend (MP4/H.264, MJPG
//! AVI, anything FFmpeg reads) and folders of PNG/JPEG images. Every frame is
//! delivered as an 8-bit grey image with a timestamp in seconds.
//!
//! Frames come in batches so that decoding can run in parallel: JPEG frames of
//! an MJPG video are taken from the container undecoded and decoded on all
//! cores, as are the files of an image folder.

mod images;
mod pool;
mod timestamps;
mod video;

pub use images::FolderSource;
pub use video::VideoSource;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use opencv::core::{Mat, Vector};
use opencv::prelude::*;
use opencv::{imgcodecs, imgproc, videoio};
use rayon::prelude::*;

use crate::TrackError;
use pool::decode_pool;

/// An 8-bit grey image, row-major without padding.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GrayFrame {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Pixels, `width * height` bytes.
    pub data: Vec<u8>,
}

impl GrayFrame {
    /// Copies a grey (or BGR/BGRA, converted) OpenCV image.
    pub fn from_mat(mat: &Mat) -> Result<Self, TrackError> {
        let grey;
        let m = match mat.channels() {
            1 => mat,
            3 => {
                let mut g = Mat::default();
                imgproc::cvt_color(mat, &mut g, imgproc::COLOR_BGR2GRAY, 0)?;
                grey = g;
                &grey
            }
            4 => {
                let mut g = Mat::default();
                imgproc::cvt_color(mat, &mut g, imgproc::COLOR_BGRA2GRAY, 0)?;
                grey = g;
                &grey
            }
            c => {
                return Err(TrackError::Options(format!(
                    "unsupported image with {c} channels"
                )))
            }
        };
        let (w, h) = (m.cols() as usize, m.rows() as usize);
        let mut data = Vec::with_capacity(w * h);
        if m.is_continuous() {
            data.extend_from_slice(&m.data_bytes()?[..w * h]);
        } else {
            for r in 0..h as i32 {
                let row = m.row(r)?;
                data.extend_from_slice(&row.data_bytes()?[..w]);
            }
        }
        Ok(Self {
            width: w as u32,
            height: h as u32,
            data,
        })
    }

    /// The image as an OpenCV matrix (a copy).
    pub fn to_mat(&self) -> Result<Mat, TrackError> {
        let m = Mat::new_rows_cols_with_data(self.height as i32, self.width as i32, &self.data)?;
        Ok(m.try_clone()?)
    }
}

/// One frame with its timestamp.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Frame index in the source, from 0.
    pub index: usize,
    /// Timestamp, seconds.
    pub t_s: f64,
    /// The image.
    pub image: GrayFrame,
}

/// What a source is.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceInfo {
    /// The video file or image folder.
    pub path: PathBuf,
    /// Frame width, pixels.
    pub width: u32,
    /// Frame height, pixels.
    pub height: u32,
    /// Frame count if known in advance (videos: the container's estimate).
    pub frame_count: Option<usize>,
    /// Short description ("video MJPG", "images").
    pub kind: String,
    /// Where the frame times come from ("container timestamps", "frame count at 30 fps").
    pub timing: String,
    /// Frames read so far whose container timestamp was missing, timed one frame step after
    /// the previous frame.
    pub extrapolated_times: usize,
    /// The video's own frame rate when `--fps` overrode it with another, frames/s.
    pub overridden_fps: Option<f64>,
}

/// A stream of frames, read in batches.
pub trait FrameSource: Send {
    /// Size and kind of the source.
    fn info(&self) -> &SourceInfo;
    /// The next up to `n` frames in order; an empty batch means the end.
    fn next_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError>;
}

/// The fastest frame rate `--fps` may give, frames/s (high-speed cameras reach a few
/// thousand).
pub const MAX_FPS: f64 = 10_000.0;

/// The slowest frame rate `--fps` may give, frames/s: a frame every ten seconds already
/// loses a robot driving at walking pace.
pub const MIN_FPS: f64 = 0.1;

/// How frames get their timestamps when the source does not say.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceOptions {
    /// Fixed frame rate, frames per second (overrides a video's own rate).
    pub fps: Option<f64>,
    /// CSV of image timestamps (`file,t` or `t` per image in natural name order, img2 before
    /// img10); for folders, `timestamps.csv` inside the folder is used when present.
    pub timestamps: Option<PathBuf>,
}

impl SourceOptions {
    /// The timestamps file that times the frames of `path`: `--timestamps`, else a folder's own
    /// `timestamps.csv`; `None` when frames are timed by a video's container or by counting
    /// at `--fps`. Refuses options that give the frames two timings, so none is silently
    /// dropped: `--fps` beside a timestamps file (counting shifts every frame after one
    /// missing from the folder), and `--timestamps` for a video, which carries its own.
    pub fn timestamps_file(&self, path: &Path) -> Result<Option<PathBuf>, TrackError> {
        if !path.is_dir() {
            return match &self.timestamps {
                Some(ts) => Err(TrackError::Options(format!(
                    "--timestamps {}: only an image folder takes a timestamps file; the video {} carries its frames' times (--fps overrides its frame rate)",
                    ts.display(),
                    path.display()
                ))),
                None => Ok(None),
            };
        }
        let own = path.join(FOLDER_TIMESTAMPS);
        match (&self.timestamps, self.fps) {
            (Some(ts), Some(fps)) => Err(TrackError::Options(format!(
                "--timestamps {} and --fps {fps} both give the frames' times: give one",
                ts.display()
            ))),
            (Some(ts), None) => Ok(Some(ts.clone())),
            (None, Some(fps)) if own.is_file() => Err(TrackError::bad_input(
                &own,
                format!(
                    "times the frames of this folder, and --fps {fps} would time them by counting instead (a frame missing from the folder would shift every later one): leave out --fps, or remove or rename {FOLDER_TIMESTAMPS} to time the frames by counting"
                ),
            )),
            (None, Some(_)) => Ok(None),
            (None, None) => Ok(own.is_file().then_some(own)),
        }
    }
}

/// The timestamps file a frame folder carries: it times the folder's frames unless
/// `--timestamps` names another.
const FOLDER_TIMESTAMPS: &str = "timestamps.csv";

/// Opens a video file or an image folder.
pub fn open_source(path: &Path, opts: &SourceOptions) -> Result<Box<dyn FrameSource>, TrackError> {
    let meta =
        std::fs::metadata(path).map_err(|e| TrackError::io(path, format!("cannot read: {e}")))?;
    if meta.is_dir() {
        Ok(Box::new(FolderSource::open(path, opts)?))
    } else {
        opts.timestamps_file(path)?;
        Ok(Box::new(VideoSource::open(path, opts)?))
    }
}

/// Frames already in memory (tests, benchmarks, callers that decode themselves).
pub struct MemorySource {
    info: SourceInfo,
    frames: std::collections::VecDeque<Frame>,
}

impl MemorySource {
    /// A source over `frames`; `name` stands for the path in messages. The
    /// size is that of the first frame (0×0 when empty).
    pub fn new(name: &str, frames: Vec<Frame>) -> Self {
        let (width, height) = frames
            .first()
            .map(|f| (f.image.width, f.image.height))
            .unwrap_or((0, 0));
        Self {
            info: SourceInfo {
                path: PathBuf::from(name),
                width,
                height,
                frame_count: Some(frames.len()),
                kind: "memory".into(),
                timing: "given with the frames".into(),
                extrapolated_times: 0,
                overridden_fps: None,
            },
            frames: frames.into(),
        }
    }
}

impl FrameSource for MemorySource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn next_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError> {
        let k = n.min(self.frames.len());
        Ok(self.frames.drain(..k).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_source_batches_in_order() {
        let frames: Vec<Frame> = (0..5)
            .map(|i| Frame {
                index: i,
                t_s: i as f64,
                image: GrayFrame {
                    width: 2,
                    height: 1,
                    data: vec![0, 1],
                },
            })
            .collect();
        let mut s = MemorySource::new("m", frames);
        assert_eq!((s.info().width, s.info().height), (2, 1));
        assert_eq!(s.next_batch(3).unwrap().len(), 3);
        let b = s.next_batch(3).unwrap();
        assert_eq!(b.iter().map(|f| f.index).collect::<Vec<_>>(), vec![3, 4]);
        assert!(s.next_batch(3).unwrap().is_empty());
    }
}
