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

use opencv::core::Mat;
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
    /// The frame rate the video's container states, frames/s (None for image folders).
    pub container_fps: Option<f64>,
    /// The turn the source's metadata asks for on display (a video's rotate tag, the first
    /// image's EXIF orientation), which is not applied: frames are read as the sensor
    /// recorded them, the layout the calibration describes.
    pub display_rotation: Option<String>,
    /// The first frame's time on the container's own clock, seconds, when it is not 0: frame
    /// times count from the first frame, so a truth on the container's clock is this much
    /// later than the fixes.
    pub first_frame_clock_s: Option<f64>,
    /// How much a moving tag's rows alternate between two places (adjacent rows' differences
    /// over those of rows two apart, around the tag in frames where it moves): above
    /// [`crate::interlace::COMBED`] the frames are interlaced fields woven together.
    pub interlace_comb: Option<f64>,
    /// The container's own times of the frames (seconds from the first, by frame index) when
    /// `--fps` timed them by counting instead: they still show the frames dropped.
    pub container_times_s: Option<Vec<f64>>,
    /// Frames of the file that could not be decoded whole (their JPEG data is cut or
    /// damaged), by index: left out, so the timeline has a gap there.
    pub corrupt_frames: Vec<usize>,
    /// An image folder's frame files among [`Self::corrupt_frames`], in its order, each with
    /// what is wrong with it ("frame_000042.jpg (cut short: no JPEG end-of-image marker)").
    pub corrupt_files: Vec<String>,
}

/// Why an interlaced video (`what` says how it was found) is refused, and the FFmpeg command
/// that deinterlaces it to one frame per field.
pub(crate) fn interlaced_advice(path: &Path, what: &str) -> String {
    let stem = path
        .file_stem()
        .map_or("video".into(), |s| s.to_string_lossy());
    let progressive = path.with_file_name(format!("{stem}_progressive.mp4"));
    format!(
        "{what}: each frame holds two fields taken half a frame apart, so a moving tag is torn between two places and its fixes are off by more than their σ says; deinterlace it to one frame per field, `ffmpeg -i {} -vf yadif=1 {}`, and track that",
        path.display(),
        progressive.display()
    )
}

/// Whether `bytes` hold a whole JPEG image: its start-of-image marker first and its
/// end-of-image marker last (after any zero padding). A JPEG cut or overwritten on its way
/// decodes without an error in OpenCV, the rows after the damage left as whatever the
/// memory held, often the previous frame's: the tag found there is an earlier frame's pose
/// under this frame's time.
pub fn jpeg_is_whole(bytes: &[u8]) -> bool {
    let end = bytes.len() - bytes.iter().rev().take_while(|b| **b == 0).count();
    bytes.starts_with(&[0xFF, 0xD8]) && bytes[..end].ends_with(&[0xFF, 0xD9])
}

/// Decodes a JPEG `bytes` to grey levels, or None when it cannot be decoded whole: cut
/// short ([`jpeg_is_whole`]), or damaged inside so that the decoder stops early. OpenCV does
/// not report the latter; it leaves the rows after the damage as the buffer held them. So
/// the image is decoded into a buffer of `width`×`height` filled with a marker value, and a
/// last row still all of that value was not written (the rare image whose last row really is
/// that flat grey is decoded again over another value).
pub fn decode_jpeg_whole(
    bytes: &[u8],
    width: u32,
    height: u32,
) -> Result<Option<opencv::core::Mat>, opencv::Error> {
    use opencv::core::{Mat, MatTraitConst, Scalar, Vector, CV_8UC1};
    use opencv::imgcodecs;
    if !jpeg_is_whole(bytes) {
        return Ok(None);
    }
    let buf = Vector::<u8>::from_slice(bytes);
    let last_row_is = |m: &Mat, v: u8| -> Result<bool, opencv::Error> {
        let rows = m.rows();
        if rows == 0 {
            return Ok(false);
        }
        Ok(m.row(rows - 1)?.data_bytes()?.iter().all(|p| *p == v))
    };
    for marker in [91u8, 164] {
        let mut dst = Mat::new_rows_cols_with_default(
            height as i32,
            width as i32,
            CV_8UC1,
            Scalar::all(f64::from(marker)),
        )?;
        let mat = imgcodecs::imdecode_to(&buf, odocal_calib::IMREAD_SENSOR_GRAY, &mut dst)?;
        if mat.empty() {
            return Ok(None);
        }
        if !last_row_is(&mat, marker)? {
            return Ok(Some(mat));
        }
    }
    Ok(None)
}

/// A stream of frames, read in batches.
pub trait FrameSource: Send {
    /// Size and kind of the source.
    fn info(&self) -> &SourceInfo;
    /// The next up to `n` frames in order; an empty batch means the end.
    fn next_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError>;
}

/// A decoded batch on its way from the decoder thread to the tracker.
pub(crate) type Batch = Result<Vec<Frame>, TrackError>;

/// Decodes `source` batch by batch into `tx` until it ends, fails or the tracker hangs up,
/// and returns its description as decoding left it (dropped frames and timestamps are only
/// known once read).
pub(crate) fn decode_into(
    source: &mut dyn FrameSource,
    tx: std::sync::mpsc::SyncSender<Batch>,
) -> SourceInfo {
    loop {
        let batch = source.next_batch(16);
        let stop = !matches!(&batch, Ok(b) if !b.is_empty());
        if tx.send(batch).is_err() || stop {
            break;
        }
    }
    source.info().clone()
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
pub const FOLDER_TIMESTAMPS: &str = "timestamps.csv";

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
                corrupt_frames: Vec::new(),
                corrupt_files: Vec::new(),
                container_fps: None,
                container_times_s: None,
                interlace_comb: None,
                first_frame_clock_s: None,
                display_rotation: None,
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
