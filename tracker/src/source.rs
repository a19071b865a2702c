//! Frame sources: video files through OpenCV's FFmpeg backend (MP4/H.264, MJPG
//! AVI, anything FFmpeg reads) and folders of PNG/JPEG images. Every frame is
//! delivered as an 8-bit grey image with a timestamp in seconds.
//!
//! Frames come in batches so that decoding can run in parallel: JPEG frames of
//! an MJPG video are taken from the container undecoded and decoded on all
//! cores, as are the files of an image folder.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use opencv::core::{Mat, Vector};
use opencv::prelude::*;
use opencv::{imgcodecs, imgproc, videoio};
use rayon::prelude::*;

use crate::TrackError;

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

/// The threads that decode frames in parallel.
///
/// They are not rayon's global pool: a tracker called from inside a parallel loop blocks its
/// worker while it waits for frames, and decoding queued behind it on the same pool would wait
/// for that worker for ever. With a pool of their own, frame sources work from any thread.
fn decode_pool() -> &'static rayon::ThreadPool {
    static POOL: std::sync::OnceLock<rayon::ThreadPool> = std::sync::OnceLock::new();
    POOL.get_or_init(|| {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("odocal-decode-{i}"))
            .build()
            .or_else(|_| rayon::ThreadPoolBuilder::new().num_threads(1).build())
            .unwrap_or_else(|e| panic!("cannot start a frame-decoding thread: {e}"))
    })
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
}

/// A stream of frames, read in batches.
pub trait FrameSource: Send {
    /// Size and kind of the source.
    fn info(&self) -> &SourceInfo;
    /// The next up to `n` frames in order; an empty batch means the end.
    fn next_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError>;
}

/// How frames get their timestamps when the source does not say.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceOptions {
    /// Fixed frame rate, frames per second (overrides a video's own rate).
    pub fps: Option<f64>,
    /// CSV of image timestamps (`file,t` or `t` per image in name order); for
    /// folders, `timestamps.csv` inside the folder is used when present.
    pub timestamps: Option<PathBuf>,
}

/// Opens a video file or an image folder.
pub fn open_source(path: &Path, opts: &SourceOptions) -> Result<Box<dyn FrameSource>, TrackError> {
    let meta =
        std::fs::metadata(path).map_err(|e| TrackError::io(path, format!("cannot read: {e}")))?;
    if meta.is_dir() {
        Ok(Box::new(FolderSource::open(path, opts)?))
    } else {
        Ok(Box::new(VideoSource::open(path, opts)?))
    }
}

/// A video file decoded by OpenCV's FFmpeg backend.
pub struct VideoSource {
    info: SourceInfo,
    cap: SendCapture,
    fps: f64,
    /// Undecoded JPEG packets are read and decoded here (MJPG only).
    raw_jpeg: bool,
    next_index: usize,
    /// A frame read ahead while opening (to reject empty videos).
    pending: Option<Frame>,
}

struct SendCapture(videoio::VideoCapture);
// SAFETY: a VideoCapture is only ever used by one thread at a time (it is owned
// by the source, which is moved to the decoding thread as a whole).
unsafe impl Send for SendCapture {}

fn fourcc_string(code: i32) -> String {
    (0..4)
        .map(|i| {
            let c = ((code >> (8 * i)) & 0xff) as u8;
            if c.is_ascii_graphic() {
                c as char
            } else {
                '?'
            }
        })
        .collect()
}

impl VideoSource {
    /// Opens `path` with the FFmpeg backend.
    pub fn open(path: &Path, opts: &SourceOptions) -> Result<Self, TrackError> {
        let file = std::fs::File::open(path)
            .map_err(|e| TrackError::io(path, format!("cannot read: {e}")))?;
        if file.metadata().map(|m| m.len()).unwrap_or(0) == 0 {
            return Err(TrackError::bad_input(
                path,
                "the file is empty (0 bytes): the recording did not complete",
            ));
        }
        let cap = videoio::VideoCapture::from_file(path, videoio::CAP_FFMPEG)?;
        if !cap.is_opened()? {
            return Err(TrackError::bad_input(
                path,
                "FFmpeg cannot decode this file: give an MP4 (H.264) or MJPG AVI video, or a folder of PNG/JPEG frames",
            ));
        }
        let mut cap = SendCapture(cap);
        let width = cap.0.get(videoio::CAP_PROP_FRAME_WIDTH)?.round() as u32;
        let height = cap.0.get(videoio::CAP_PROP_FRAME_HEIGHT)?.round() as u32;
        let count = cap.0.get(videoio::CAP_PROP_FRAME_COUNT)?;
        let fourcc = fourcc_string(cap.0.get(videoio::CAP_PROP_FOURCC)? as i32);
        let own_fps = cap.0.get(videoio::CAP_PROP_FPS)?;
        let fps = match opts.fps {
            Some(f) if f > 0.0 && f.is_finite() => f,
            Some(f) => {
                return Err(TrackError::Options(format!(
                    "--fps must be positive, got {f}"
                )))
            }
            None if own_fps > 0.0 && own_fps.is_finite() => own_fps,
            None => {
                return Err(TrackError::bad_input(
                    path,
                    "the video does not state its frame rate: give --fps",
                ));
            }
        };
        let raw_jpeg = fourcc.eq_ignore_ascii_case("MJPG")
            && cap.0.set(videoio::CAP_PROP_FORMAT, -1.0).unwrap_or(false);
        let mut src = Self {
            info: SourceInfo {
                path: path.to_path_buf(),
                width,
                height,
                frame_count: (count > 0.0).then_some(count as usize),
                kind: format!("video {fourcc}"),
            },
            cap,
            fps,
            raw_jpeg,
            next_index: 0,
            pending: None,
        };
        let first = src.read_batch(1)?;
        match first.into_iter().next() {
            Some(f) => {
                if (f.image.width, f.image.height) != (width, height) {
                    src.info.width = f.image.width;
                    src.info.height = f.image.height;
                }
                src.pending = Some(f);
            }
            None => return Err(TrackError::bad_input(path, "the video contains no frames")),
        }
        Ok(src)
    }

    fn read_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError> {
        let path = self.info.path.clone();
        if self.raw_jpeg {
            let mut packets = Vec::with_capacity(n);
            let mut m = Mat::default();
            while packets.len() < n && self.cap.0.read(&mut m)? {
                let bytes = if m.is_continuous() {
                    m.data_bytes()?.to_vec()
                } else {
                    Vec::new()
                };
                packets.push((self.next_index, bytes));
                self.next_index += 1;
            }
            let fps = self.fps;
            decode_pool().install(|| {
                packets
                    .into_par_iter()
                    .map(|(index, bytes)| {
                        let buf = Vector::<u8>::from_slice(&bytes);
                        let mat = imgcodecs::imdecode(&buf, imgcodecs::IMREAD_GRAYSCALE)?;
                        if mat.empty() {
                            return Err(TrackError::bad_input(
                                &path,
                                format!("frame {index} is corrupt (JPEG cannot be decoded)"),
                            ));
                        }
                        Ok(Frame {
                            index,
                            t_s: index as f64 / fps,
                            image: GrayFrame::from_mat(&mat)?,
                        })
                    })
                    .collect()
            })
        } else {
            let mut out = Vec::with_capacity(n);
            let mut m = Mat::default();
            while out.len() < n && self.cap.0.read(&mut m)? {
                if m.empty() {
                    break;
                }
                out.push(Frame {
                    index: self.next_index,
                    t_s: self.next_index as f64 / self.fps,
                    image: GrayFrame::from_mat(&m)?,
                });
                self.next_index += 1;
            }
            Ok(out)
        }
    }
}

impl FrameSource for VideoSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn next_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError> {
        let mut out = Vec::with_capacity(n);
        if let Some(f) = self.pending.take() {
            out.push(f);
        }
        if out.len() < n {
            out.extend(self.read_batch(n - out.len())?);
        }
        Ok(out)
    }
}

/// A folder of PNG/JPEG frames in file-name order.
pub struct FolderSource {
    info: SourceInfo,
    files: Vec<(PathBuf, f64)>,
    next: usize,
}

const IMAGE_EXTS: [&str; 6] = ["png", "jpg", "jpeg", "pgm", "bmp", "tif"];

impl FolderSource {
    /// Lists the images of `dir` and assigns their timestamps.
    pub fn open(dir: &Path, opts: &SourceOptions) -> Result<Self, TrackError> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| TrackError::io(dir, format!("cannot list: {e}")))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| IMAGE_EXTS.contains(&e.to_ascii_lowercase().as_str()))
            })
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(TrackError::bad_input(
                dir,
                "the folder holds no PNG/JPEG images",
            ));
        }
        let default_csv = dir.join("timestamps.csv");
        let csv = opts
            .timestamps
            .clone()
            .or_else(|| (opts.fps.is_none() && default_csv.is_file()).then_some(default_csv));
        let times: Vec<f64> = match (csv, opts.fps) {
            (Some(csv), _) => read_timestamps(&csv, &files)?,
            (None, Some(fps)) if fps > 0.0 && fps.is_finite() => (0..files.len()).map(|k| k as f64 / fps).collect(),
            (None, Some(fps)) => return Err(TrackError::Options(format!("--fps must be positive, got {fps}"))),
            (None, None) => {
                return Err(TrackError::bad_input(
                    dir,
                    "image folder without timestamps: give --fps or --timestamps FILE.csv (columns file,t)",
                ))
            }
        };
        let first = imgcodecs::imread(&files[0], imgcodecs::IMREAD_GRAYSCALE)?;
        if first.empty() {
            return Err(TrackError::bad_input(&files[0], "cannot decode this image"));
        }
        let n = files.len();
        Ok(Self {
            info: SourceInfo {
                path: dir.to_path_buf(),
                width: first.cols() as u32,
                height: first.rows() as u32,
                frame_count: Some(n),
                kind: "images".into(),
            },
            files: files.into_iter().zip(times).collect(),
            next: 0,
        })
    }
}

/// Reads image timestamps: CSV with header `file,t` (any order of rows) or `t`
/// (one row per image in name order).
fn read_timestamps(csv_path: &Path, files: &[PathBuf]) -> Result<Vec<f64>, TrackError> {
    let text = std::fs::read_to_string(csv_path)
        .map_err(|e| TrackError::io(csv_path, format!("cannot read: {e}")))?;
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| TrackError::bad_input(csv_path, e.to_string()))?
        .iter()
        .map(|s| s.to_string())
        .collect();
    let by_name = match header
        .iter()
        .map(|s| s.as_str())
        .collect::<Vec<_>>()
        .as_slice()
    {
        ["file", "t"] => true,
        ["t"] => false,
        _ => {
            return Err(TrackError::bad_input(
                csv_path,
                format!(
                    "line 1: header is \"{}\", expected \"file,t\" or \"t\"",
                    header.join(",")
                ),
            ))
        }
    };
    let mut map = HashMap::new();
    let mut list = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let line = i + 2;
        let rec = rec.map_err(|e| TrackError::bad_input(csv_path, format!("line {line}: {e}")))?;
        let tcol = if by_name { 1 } else { 0 };
        let field = rec.get(tcol).unwrap_or("");
        let t: f64 = field
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite())
            .ok_or_else(|| {
                TrackError::bad_input(
                    csv_path,
                    format!(
                        "line {line}, column {}: {field:?} is not a time in seconds",
                        tcol + 1
                    ),
                )
            })?;
        if by_name {
            map.insert(rec.get(0).unwrap_or("").to_string(), t);
        } else {
            list.push(t);
        }
    }
    let times: Vec<f64> = if by_name {
        files
            .iter()
            .map(|f| {
                let name = f
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                map.get(&name).copied().ok_or_else(|| {
                    TrackError::bad_input(
                        csv_path,
                        format!("has no timestamp for image {name}: add a row \"{name},<t>\""),
                    )
                })
            })
            .collect::<Result<_, _>>()?
    } else {
        if list.len() != files.len() {
            return Err(TrackError::bad_input(
                csv_path,
                format!("has {} timestamps for {} images", list.len(), files.len()),
            ));
        }
        list
    };
    if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
        return Err(TrackError::bad_input(
            csv_path,
            format!(
                "timestamps must increase in image-name order: {} ({}) is not after {} ({})",
                files[k + 1].display(),
                times[k + 1],
                files[k].display(),
                times[k]
            ),
        ));
    }
    Ok(times)
}

impl FrameSource for FolderSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn next_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError> {
        let end = (self.next + n).min(self.files.len());
        let (w, h) = (self.info.width, self.info.height);
        let batch: Result<Vec<Frame>, TrackError> = decode_pool().install(|| {
            (self.next..end)
                .into_par_iter()
                .map(|index| {
                    let (path, t_s) = &self.files[index];
                    let mat = imgcodecs::imread(path, imgcodecs::IMREAD_GRAYSCALE)?;
                    if mat.empty() {
                        return Err(TrackError::bad_input(path, "cannot decode this image"));
                    }
                    let image = GrayFrame::from_mat(&mat)?;
                    if (image.width, image.height) != (w, h) {
                        return Err(TrackError::bad_input(
                            path,
                            format!(
                            "is {}×{}, the first image is {w}×{h}: all frames must have one size",
                            image.width, image.height
                        ),
                        ));
                    }
                    Ok(Frame {
                        index,
                        t_s: *t_s,
                        image,
                    })
                })
                .collect()
        });
        self.next = end;
        batch
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

    fn files(n: usize) -> Vec<PathBuf> {
        (0..n)
            .map(|i| PathBuf::from(format!("/x/frame_{i:02}.png")))
            .collect()
    }

    fn ts(text: &str, n: usize) -> Result<Vec<f64>, TrackError> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ts.csv");
        std::fs::write(&p, text).unwrap();
        read_timestamps(&p, &files(n))
    }

    #[test]
    fn timestamps_by_name_or_by_order() {
        let t = ts("file,t\nframe_01.png,0.5\nframe_00.png,0.25\n", 2).unwrap();
        assert_eq!(t, vec![0.25, 0.5]);
        assert_eq!(ts("t\n1\n2\n3\n", 3).unwrap(), vec![1.0, 2.0, 3.0]);
    }

    #[test]
    fn bad_timestamp_files_say_where() {
        let e = ts("time\n1\n", 1).unwrap_err().to_string();
        assert!(
            e.contains("line 1") && e.contains("expected \"file,t\""),
            "{e}"
        );
        let e = ts("file,t\nframe_00.png,abc\n", 1).unwrap_err().to_string();
        assert!(e.contains("line 2, column 2") && e.contains("abc"), "{e}");
        let e = ts("file,t\nframe_00.png,1\n", 2).unwrap_err().to_string();
        assert!(e.contains("no timestamp for image frame_01.png"), "{e}");
        let e = ts("t\n1\n1\n", 2).unwrap_err().to_string();
        assert!(e.contains("must increase"), "{e}");
        let e = ts("t\n1\n", 2).unwrap_err().to_string();
        assert!(e.contains("1 timestamps for 2 images"), "{e}");
    }

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
