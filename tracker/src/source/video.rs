//! Video files through OpenCV's FFmpeg backend: MJPG frames taken from the container
//! undecoded and decoded in parallel, other codecs decoded by FFmpeg.

use super::*;

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
