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
    /// Frames read ahead while opening (to reject empty videos and probe the timestamps).
    pending: Vec<Frame>,
    /// Frames are timed by counting at `fps` (--fps given, or the container has no
    /// timestamps) instead of by the container's presentation timestamps.
    counted: bool,
    /// --fps times the frames: the container's own times are still read, as the timeline
    /// that shows frames dropped, which counting would shift every later frame over.
    by_fps: bool,
    /// The container has no presentation timestamps (found at the second frame).
    no_timestamps: bool,
    /// The rate the container's timestamps are put on the grid of: its own when it states one.
    grid_fps: f64,
    /// Presentation time of the first frame, seconds (frame times start at 0).
    first_pts_s: Option<f64>,
    /// Time of the last frame and the last step forward, seconds.
    last_t_s: f64,
    last_step_s: f64,
    /// The presentation times of the stream's packets, on the frames' timeline (seconds from
    /// the first frame), sorted: read by ffprobe for the frames OpenCV gives no time (None
    /// until one comes, empty when ffprobe cannot tell).
    packet_times_s: Option<Vec<f64>>,
    /// What ffprobe reads of the stream and its container (None without ffprobe).
    probe: Option<StreamProbe>,
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

/// Why an MP4 whose frames are there but whose index is not cannot be read, and what to do.
const MP4_WITHOUT_INDEX: &str = "an MP4 without its index (no `moov` box, FFmpeg's \"moov atom not found\"): the recording did not finish (the recorder crashed or lost power, or the file was copied before it was closed), and an MP4 writes its index last. Recover the frames with untrunc and a whole recording of the same camera and settings (`untrunc whole.mp4 this.mp4`), and record with fragmented MP4 (FFmpeg: -movflags +frag_keyframe+empty_moov) so that a crash leaves a readable file";

/// Whether `path` is an MP4 whose top-level boxes hold no `moov` (its index): MP4 writers put
/// it at the end, so a recording cut short has its frames' data (`mdat`) and no index.
fn mp4_without_index(path: &Path) -> bool {
    use std::io::{Read, Seek, SeekFrom};
    let Ok(mut f) = std::fs::File::open(path) else {
        return false;
    };
    let Ok(len) = f.metadata().map(|m| m.len()) else {
        return false;
    };
    let (mut at, mut ftyp, mut mdat) = (0u64, false, false);
    while at + 8 <= len {
        let mut head = [0u8; 16];
        if f.seek(SeekFrom::Start(at)).is_err() || f.read_exact(&mut head[..8]).is_err() {
            return false;
        }
        let kind: [u8; 4] = [head[4], head[5], head[6], head[7]];
        let size = match u32::from_be_bytes([head[0], head[1], head[2], head[3]]) {
            // A 64-bit size follows the type.
            1 => {
                if f.read_exact(&mut head[8..16]).is_err() {
                    return false;
                }
                let mut b = [0u8; 8];
                b.copy_from_slice(&head[8..16]);
                u64::from_be_bytes(b)
            }
            // The box runs to the end of the file.
            0 => len - at,
            n => u64::from(n),
        };
        match &kind {
            b"moov" => return false,
            b"ftyp" => ftyp = true,
            b"mdat" => mdat = true,
            _ => {}
        }
        if size < 8 {
            break;
        }
        at += size;
    }
    ftyp && mdat
}

impl VideoSource {
    /// Opens `path` with the FFmpeg backend. Frames are timed by the container's presentation
    /// timestamps (so dropped frames leave a gap in time instead of shifting every later
    /// frame), or by counting at `--fps` when given or when the container has none.
    pub fn open(path: &Path, opts: &SourceOptions) -> Result<Self, TrackError> {
        let file = std::fs::File::open(path)
            .map_err(|e| TrackError::io(path, format!("cannot read: {e}")))?;
        if file.metadata().map(|m| m.len()).unwrap_or(0) == 0 {
            return Err(TrackError::bad_input(
                path,
                "the file is empty (0 bytes): the recording did not complete",
            ));
        }
        let mut src = Self::open_capture(path, opts, true)?;
        // Without ffprobe, interlacing goes unchecked and OpenCV's frame count stands.
        let probe = probe_stream(path);
        if let Some(probe) = &probe {
            refuse_interlaced(path, probe)?;
        }
        // A raw stream's times are FFmpeg's guess at 25 fps: the frames are counted at --fps,
        // and without it refused, as an image folder without timestamps is.
        let untimed = probe.as_ref().and_then(StreamProbe::untimed);
        if let Some(format) = &untimed {
            if opts.fps.is_none() {
                return Err(TrackError::bad_input(
                    path,
                    format!(
                        "a raw {format} stream holds no timestamps nor a frame rate (FFmpeg would guess 25 fps, and every time and speed would follow the guess): give --fps, the camera's frame rate"
                    ),
                ));
            }
            src.no_timestamps = true;
            src.info.overridden_fps = None;
            src.info.container_fps = None;
        }
        src.probe = probe.clone();
        src.pending = src.read_batch(2)?;
        if src.raw_jpeg && src.pending.len() == 2 && src.no_timestamps && untimed.is_none() {
            // OpenCV gives no timestamps for undecoded packets of this container (AVI):
            // decode in FFmpeg instead, which does (beside --fps too: they show the drops).
            src = Self::open_capture(path, opts, false)?;
            src.probe = probe;
            src.pending = src.read_batch(1)?;
        }
        let Some(first) = src.pending.first() else {
            return Err(TrackError::bad_input(path, "the video contains no frames"));
        };
        (src.info.width, src.info.height) = (first.image.width, first.image.height);
        src.info.frame_count = src.frame_count_from_first();
        // OpenCV times frames from the stream's start time.
        let start = src.probe.as_ref().and_then(|p| p.stream_start_s);
        src.info.first_frame_clock_s =
            Some(start.unwrap_or(0.0) + src.first_pts_s.unwrap_or(0.0)).filter(|t| t.abs() > 1e-3);
        Ok(src)
    }

    /// The frames the container holds from the first frame read on: OpenCV's count, unless the
    /// container's stated end of the stream holds fewer frame steps after the first frame.
    /// OpenCV counts from the stream's samples or from the container's duration, and both can
    /// hold more than the frames decoded: an MP4 cut by stream copy keeps the samples before
    /// its cut point, which its edit list leaves out (122 samples for 92 frames), and a
    /// Matroska file whose timestamps start late states the segment's end time as its duration
    /// (10 s for 5 s of frames that start at 5 s). Either made a complete video look cut short.
    /// A file truly cut keeps both its sample count and its stated end, so it still looks so.
    /// Other containers keep OpenCV's count: an AVI cut short keeps its header's frame count,
    /// while FFmpeg estimates its duration from the bytes left (2.5 s of a 5 s file cut in
    /// half), which would hide the cut.
    fn frame_count_from_first(&self) -> Option<usize> {
        let counted = self.info.frame_count?;
        let probe = self.probe.as_ref().filter(|p| p.states_its_end());
        let (Some(end_s), Some(first_s), Some(fps)) = (
            probe.and_then(StreamProbe::stream_end_s),
            self.first_pts_s,
            self.info.container_fps,
        ) else {
            return Some(counted);
        };
        let stated = ((end_s - first_s) * fps).round();
        Some(if stated >= 1.0 && stated < counted as f64 {
            stated as usize
        } else {
            counted
        })
    }

    fn open_capture(path: &Path, opts: &SourceOptions, try_raw: bool) -> Result<Self, TrackError> {
        let cap = videoio::VideoCapture::from_file(path, videoio::CAP_FFMPEG)?;
        if !cap.is_opened()? {
            let what = match odocal_core::file_kind(path) {
                Some(kind) if !odocal_core::is_video(kind) => {
                    format!("this is {kind}, not a video")
                }
                _ if mp4_without_index(path) => {
                    return Err(TrackError::bad_input(path, MP4_WITHOUT_INDEX));
                }
                _ => "FFmpeg cannot decode this file".to_string(),
            };
            return Err(TrackError::bad_input(
                path,
                format!(
                    "{what}: give an MP4 (H.264) or MJPG AVI video, or a folder of PNG/JPEG frames"
                ),
            ));
        }
        let mut cap = SendCapture(cap);
        // FFmpeg's backend turns the frames by the stream's rotate tag unless told not to:
        // the calibration describes the pixels as the sensor recorded them.
        cap.0.set(videoio::CAP_PROP_ORIENTATION_AUTO, 0.0)?;
        let rotate_deg = cap.0.get(videoio::CAP_PROP_ORIENTATION_META)?.round() as i64;
        let width = cap.0.get(videoio::CAP_PROP_FRAME_WIDTH)?.round() as u32;
        let height = cap.0.get(videoio::CAP_PROP_FRAME_HEIGHT)?.round() as u32;
        let count = cap.0.get(videoio::CAP_PROP_FRAME_COUNT)?;
        let fourcc = fourcc_string(cap.0.get(videoio::CAP_PROP_FOURCC)? as i32);
        let own_fps = cap.0.get(videoio::CAP_PROP_FPS)?;
        let fps = match opts.fps {
            Some(f) if (super::MIN_FPS..=super::MAX_FPS).contains(&f) => f,
            Some(f) => {
                return Err(TrackError::Options(format!(
                    "--fps {f}: a camera's frame rate is {} to {} frames/s",
                    super::MIN_FPS,
                    super::MAX_FPS
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
        let raw_jpeg = try_raw
            && fourcc.eq_ignore_ascii_case("MJPG")
            && cap.0.set(videoio::CAP_PROP_FORMAT, -1.0).unwrap_or(false);
        let counted = opts.fps.is_some();
        Ok(Self {
            info: SourceInfo {
                path: path.to_path_buf(),
                width,
                height,
                frame_count: (count > 0.0).then_some(count as usize),
                kind: format!("video {fourcc}"),
                extrapolated_times: 0,
                corrupt_frames: Vec::new(),
                corrupt_files: Vec::new(),
                container_fps: (own_fps > 0.0 && own_fps.is_finite()).then_some(own_fps),
                container_times_s: None,
                interlace_comb: None,
                first_frame_clock_s: None,
                display_rotation: (rotate_deg.rem_euclid(360) != 0)
                    .then(|| format!("its rotate tag asks for a turn of {rotate_deg}° on display")),
                overridden_fps: opts
                    .fps
                    .filter(|f| {
                        own_fps > 0.0 && own_fps.is_finite() && (f / own_fps - 1.0).abs() > 0.01
                    })
                    .map(|_| own_fps),
                timing: if counted {
                    format!("frame count at {fps} fps (--fps)")
                } else {
                    "container timestamps".into()
                },
            },
            cap,
            fps,
            raw_jpeg,
            next_index: 0,
            pending: Vec::new(),
            counted,
            by_fps: counted,
            no_timestamps: false,
            grid_fps: if own_fps > 0.0 && own_fps.is_finite() {
                own_fps
            } else {
                fps
            },
            first_pts_s: None,
            last_t_s: 0.0,
            last_step_s: 1.0 / fps,
            packet_times_s: None,
            probe: None,
        })
    }

    /// The time of the frame just read, seconds from the first frame: by counting at `fps`
    /// when the frames are counted, else its container time ([`Self::container_time`]). Under
    /// --fps the container time is kept beside it ([`SourceInfo::container_times_s`]).
    fn frame_time(&mut self) -> Result<f64, TrackError> {
        let counted_t = self.next_index as f64 / self.fps;
        let own = self.container_time()?;
        if self.by_fps {
            if let Some(t) = own {
                self.info
                    .container_times_s
                    .get_or_insert_with(Vec::new)
                    .push(t);
            }
            return Ok(counted_t);
        }
        match own {
            Some(t) => Ok(t),
            None => {
                if !self.counted {
                    self.counted = true;
                    self.info.timing =
                        format!("frame count at {} fps (no container timestamps)", self.fps);
                }
                Ok(counted_t)
            }
        }
    }

    /// The frame just read by the container: its presentation timestamp, put exactly on the
    /// nominal frame grid k / fps when it lies within the container's rounding (half a
    /// millisecond) of it, so that a clean video's times are the same whatever the container;
    /// None when the container has no timestamps.
    fn container_time(&mut self) -> Result<Option<f64>, TrackError> {
        if self.no_timestamps {
            return Ok(None);
        }
        // OpenCV reports a missing timestamp as 0.
        let pts_ms = self.cap.0.get(videoio::CAP_PROP_POS_MSEC)?;
        if self.next_index == 1 && pts_ms == 0.0 {
            self.no_timestamps = true;
            // The first frame's time was taken as 0 by both timings.
            self.info.container_times_s = None;
            return Ok(None);
        }
        if self.next_index > 0 && (pts_ms == 0.0 || !pts_ms.is_finite()) {
            return Ok(Some(self.drained_frame_time()));
        }
        let first = *self.first_pts_s.get_or_insert(pts_ms / 1000.0);
        let t = self.on_grid(pts_ms / 1000.0 - first);
        if t > self.last_t_s {
            self.last_step_s = t - self.last_t_s;
        }
        self.last_t_s = t;
        Ok(Some(t))
    }

    /// `t_s` put exactly on the nominal frame grid k / fps when it lies within the
    /// container's rounding (half a millisecond) of it.
    fn on_grid(&self, t_s: f64) -> f64 {
        let on_grid = (t_s * self.grid_fps).round() / self.grid_fps;
        if (t_s - on_grid).abs() <= (0.6e-3f64).min(0.25 / self.grid_fps) {
            on_grid
        } else {
            t_s
        }
    }

    /// The time of a frame OpenCV gives no timestamp: the frames a decoder reordering B-frames
    /// still holds at the end of the stream, which OpenCV times by the packet that made the
    /// decoder give them out, and none does. They come out in presentation order, so each is
    /// the next packet's presentation time after the last frame's, as ffprobe reads them; one
    /// step after the last frame when ffprobe is not there (counted: a frame dropped among the
    /// last would shift them).
    fn drained_frame_time(&mut self) -> f64 {
        if self.packet_times_s.is_none() {
            let times = packet_times_s(&self.info.path).unwrap_or_default();
            // OpenCV times a frame from the stream's start time, and frame times count from
            // the first frame's; without the start time, from the first packet shown.
            let origin = match (
                self.probe.as_ref().and_then(|p| p.stream_start_s),
                self.first_pts_s,
            ) {
                (Some(start), Some(first)) => start + first,
                _ => times.first().copied().unwrap_or(0.0),
            };
            self.packet_times_s = Some(times.into_iter().map(|t| t - origin).collect());
        }
        let last = self.last_t_s;
        let next = self
            .packet_times_s
            .iter()
            .flatten()
            .map(|t| self.on_grid(*t))
            .find(|t| *t > last + 1e-4);
        let t = next.unwrap_or_else(|| {
            self.info.extrapolated_times += 1;
            last + self.last_step_s
        });
        self.last_step_s = t - last;
        self.last_t_s = t;
        t
    }

    fn read_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError> {
        if self.raw_jpeg {
            let (width, height) = (self.info.width, self.info.height);
            // A batch of damaged frames only is no end of the video: read on.
            loop {
                let mut packets = Vec::with_capacity(n);
                let mut m = Mat::default();
                while packets.len() < n && self.cap.0.read(&mut m)? {
                    let bytes = if m.is_continuous() {
                        m.data_bytes()?.to_vec()
                    } else {
                        Vec::new()
                    };
                    let t_s = self.frame_time()?;
                    packets.push((self.next_index, t_s, bytes));
                    self.next_index += 1;
                }
                if packets.is_empty() {
                    return Ok(Vec::new());
                }
                // A damaged frame is left out, a gap in the timeline, and counted: a camera's
                // stream loses a frame now and then, which is no reason to lose the recording.
                let decoded: Vec<(usize, Option<Frame>)> = decode_pool().install(|| {
                    packets
                        .into_par_iter()
                        .map(|(index, t_s, bytes)| {
                            let Some(mat) = super::decode_jpeg_whole(&bytes, width, height)? else {
                                return Ok((index, None));
                            };
                            let image = GrayFrame::from_mat(&mat)?;
                            Ok((index, Some(Frame { index, t_s, image })))
                        })
                        .collect::<Result<_, TrackError>>()
                })?;
                let mut frames = Vec::with_capacity(decoded.len());
                for (index, frame) in decoded {
                    match frame {
                        Some(f) => frames.push(f),
                        None => self.info.corrupt_frames.push(index),
                    }
                }
                if !frames.is_empty() {
                    return Ok(frames);
                }
            }
        } else {
            let mut out = Vec::with_capacity(n);
            let mut m = Mat::default();
            while out.len() < n && self.cap.0.read(&mut m)? {
                if m.empty() {
                    break;
                }
                let t_s = self.frame_time()?;
                out.push(Frame {
                    index: self.next_index,
                    t_s,
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
        let mut out = std::mem::take(&mut self.pending);
        if out.len() > n {
            self.pending = out.split_off(n);
        } else if out.len() < n {
            out.extend(self.read_batch(n - out.len())?);
        }
        Ok(out)
    }
}

/// The presentation times of the first video stream's packets in `path` that the decoder
/// shows, sorted, seconds on the container's clock, read by FFmpeg's ffprobe (OpenCV does not
/// give a packet's time); None when ffprobe is not installed or cannot read them. Packets an
/// MP4's edit list leaves out (flagged D, the frames before the cut point of a copy cut from a
/// longer video) are not shown, and counting them put the last frames a cut's length early.
fn packet_times_s(path: &Path) -> Option<Vec<f64>> {
    let out = std::process::Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
        .args(["packet=pts_time,flags", "-of", "csv=p=0"])
        .arg(path)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let mut times = shown_packet_times_s(&String::from_utf8_lossy(&out.stdout));
    times.sort_by(f64::total_cmp);
    Some(times)
}

/// The times of ffprobe's `pts_time,flags` packet rows that are not flagged discarded (D).
fn shown_packet_times_s(csv: &str) -> Vec<f64> {
    csv.lines()
        .filter_map(|l| {
            let (pts, flags) = l.trim().split_once(',').unwrap_or((l.trim(), ""));
            if flags.contains('D') {
                return None;
            }
            pts.parse().ok()
        })
        .collect()
}

/// What FFmpeg's ffprobe reads of a video's first video stream and of its container.
#[derive(Debug, Clone, Default, PartialEq)]
struct StreamProbe {
    /// FFmpeg's name of the container format ("matroska,webm", "mov,mp4,m4a,3gp,3g2,mj2").
    format_name: String,
    /// The stream's field order ("progressive", "tt", …).
    field_order: Option<String>,
    /// The stream's start time, seconds on the container's clock: OpenCV times frames from it.
    stream_start_s: Option<f64>,
    /// The stream's duration, seconds (after an MP4's edit list).
    stream_duration_s: Option<f64>,
    /// The container's start time, seconds.
    format_start_s: Option<f64>,
    /// The container's duration, seconds.
    format_duration_s: Option<f64>,
    /// The stream's average frame rate as ffprobe reads it ("30/1"; "0/0" when unknown).
    avg_frame_rate: Option<String>,
}

impl StreamProbe {
    /// Reads ffprobe's JSON of `stream=…:format=…`.
    fn parse(json: &str) -> Option<Self> {
        let v: serde_json::Value = serde_json::from_str(json).ok()?;
        let stream = v.get("streams")?.get(0)?;
        let format = v.get("format");
        let num = |o: Option<&serde_json::Value>, key: &str| -> Option<f64> {
            o?.get(key)?
                .as_str()?
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
        };
        let text = |o: Option<&serde_json::Value>, key: &str| -> Option<String> {
            Some(o?.get(key)?.as_str()?.to_string())
        };
        Some(Self {
            format_name: text(format, "format_name").unwrap_or_default(),
            field_order: text(Some(stream), "field_order"),
            stream_start_s: num(Some(stream), "start_time"),
            stream_duration_s: num(Some(stream), "duration"),
            format_start_s: num(format, "start_time"),
            format_duration_s: num(format, "duration"),
            avg_frame_rate: text(Some(stream), "avg_frame_rate"),
        })
    }

    /// The raw stream format, when the file is a codec's bare stream whose frames carry no
    /// times and which states no rate (an MJPEG stream, an H.264 stream without timing in its
    /// headers): FFmpeg times such frames at a guessed 25 fps.
    fn untimed(&self) -> Option<String> {
        const RAW: [&str; 8] = [
            "mjpeg",
            "mpjpeg",
            "jpeg_pipe",
            "image2pipe",
            "h264",
            "hevc",
            "m4v",
            "rawvideo",
        ];
        let raw = self.format_name.split(',').find(|f| RAW.contains(f))?;
        let rate_unknown = self
            .avg_frame_rate
            .as_deref()
            .is_none_or(|r| r.starts_with("0/") || r.ends_with("/0"));
        rate_unknown.then(|| raw.to_string())
    }

    /// Whether the container states where its stream ends (MP4/MOV and Matroska), rather
    /// than FFmpeg estimating it from the file's size.
    fn states_its_end(&self) -> bool {
        self.format_name
            .split(',')
            .any(|f| f == "matroska" || f == "mov" || f == "mp4")
    }

    /// Where the container says the stream ends, seconds from the stream's start time (the
    /// origin of OpenCV's frame times). The stream's own duration when stated (MP4, AVI,
    /// MPEG-TS), else the container's. Matroska counts its timestamps from the segment's start
    /// and states the segment's duration, which is so the end time, however late the first
    /// frame; FFmpeg's other demuxers give the duration from the container's start time.
    fn stream_end_s(&self) -> Option<f64> {
        if let Some(d) = self.stream_duration_s {
            return Some(d);
        }
        let duration = self.format_duration_s?;
        let stream_start = self.stream_start_s.unwrap_or(0.0);
        if self.format_name.split(',').any(|f| f == "matroska") {
            Some(duration - stream_start)
        } else {
            Some(self.format_start_s.unwrap_or(stream_start) + duration - stream_start)
        }
    }
}

/// ffprobe's reading of `path`'s first video stream and its container; None when ffprobe is
/// not installed or cannot read the file.
fn probe_stream(path: &Path) -> Option<StreamProbe> {
    let out = std::process::Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
        .args(["stream=field_order,start_time,duration,avg_frame_rate:format=format_name,start_time,duration"])
        .args(["-of", "json"])
        .arg(path)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    StreamProbe::parse(&String::from_utf8_lossy(&out.stdout))
}

/// Refuses a video whose stream says it is interlaced (field order tt, bb, tb or bt): each
/// frame holds two fields taken half a frame apart, a moving tag's rows alternate between
/// two places, and its fixes came out 2.5 mm RMS off with σ 4.7 times too small, unsaid.
/// One frame per field, deinterlaced by FFmpeg, tracks as a progressive video does (0.09 mm).
fn refuse_interlaced(path: &Path, probe: &StreamProbe) -> Result<(), TrackError> {
    let Some(order) = probe.field_order.as_deref() else {
        return Ok(());
    };
    if !matches!(order, "tt" | "bb" | "tb" | "bt") {
        return Ok(());
    }
    Err(TrackError::bad_input(
        path,
        super::interlaced_advice(
            path,
            &format!("the video is interlaced (field order {order})"),
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn probe(json: &str) -> StreamProbe {
        StreamProbe::parse(json).unwrap()
    }

    #[test]
    fn the_stream_ends_where_its_container_says_from_the_stream_start() {
        // Matroska, timestamps from 5 s: the segment's duration is its end time.
        let mkv = probe(
            r#"{"streams":[{"field_order":"progressive","start_time":"5.000000"}],
                "format":{"format_name":"matroska,webm","start_time":"5.000000","duration":"10.000000"}}"#,
        );
        assert_eq!(mkv.field_order.as_deref(), Some("progressive"));
        assert_eq!(mkv.stream_end_s(), Some(5.0));
        // MP4 from 5 s: the stream's own duration, whatever the container's.
        let mp4 = probe(
            r#"{"streams":[{"start_time":"5.000000","duration":"5.000000"}],
                "format":{"format_name":"mov,mp4,m4a,3gp,3g2,mj2","start_time":"5.000000","duration":"10.000000"}}"#,
        );
        assert_eq!(mp4.stream_end_s(), Some(5.0));
        // MPEG-TS without a stream duration: FFmpeg's duration runs from the container start.
        let ts = probe(
            r#"{"streams":[{"start_time":"6.400000"}],
                "format":{"format_name":"mpegts","start_time":"6.000000","duration":"5.400000"}}"#,
        );
        assert!((ts.stream_end_s().unwrap() - 5.0).abs() < 1e-9);
        let none = probe(r#"{"streams":[{}],"format":{"format_name":"avi"}}"#);
        assert_eq!(none.stream_end_s(), None);
        assert!(StreamProbe::parse(r#"{"streams":[]}"#).is_none());
        assert!(StreamProbe::parse("not json").is_none());
    }

    #[test]
    fn packets_an_edit_list_leaves_out_have_no_time() {
        let csv = "-1.000000,KD\n-0.966667,_D\n0.000000,__\n0.066667,__\n0.033333,K_,\nN/A,__\n";
        assert_eq!(shown_packet_times_s(csv), vec![0.0, 0.066667, 0.033333]);
    }
}
