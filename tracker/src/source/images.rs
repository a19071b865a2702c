//! Folders of PNG/JPEG images, decoded in parallel, timed by a timestamp file or a frame rate.

use super::timestamps::read_timestamps;
use super::*;

/// A folder of PNG/JPEG frames in natural file-name order (`img2` before `img10`).
///
/// A frame file that cannot be decoded whole (cut short by a copy interrupted, empty, damaged)
/// is left out as a dropped frame and named, so that one bad file does not cost the recording;
/// a folder most of whose frames are so is refused.
pub struct FolderSource {
    info: SourceInfo,
    files: Vec<(PathBuf, f64)>,
    next: usize,
    /// The frame files left out so far, with what is wrong with each.
    broken: Vec<(PathBuf, &'static str)>,
}

/// Bytes read from the end of a frame file to find its end marker (a JPEG may carry padding
/// after its end-of-image marker, a PNG nothing after its end chunk).
const TAIL_BYTES: u64 = 1024;

/// PNG's file signature.
const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];

/// PNG's end chunk's type and CRC, which close every whole PNG.
const PNG_IEND: [u8; 8] = [b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82];

/// Why a frame file of `len` bytes beginning with `head` and ending with `tail` is not a whole
/// image, judged by its markers alone: None when it is whole, or of a format without an end
/// marker (left to the decoder). A JPEG cut short decodes without an error in OpenCV, its
/// missing rows grey or leftover memory, and a tag there would be read wrong.
fn cut_short(len: u64, head: &[u8], tail: &[u8]) -> Option<&'static str> {
    if len == 0 {
        return Some("empty (0 bytes)");
    }
    if head.starts_with(&[0xFF, 0xD8]) {
        let end = tail.len() - tail.iter().rev().take_while(|b| **b == 0).count();
        if !tail[..end].ends_with(&[0xFF, 0xD9]) {
            return Some("cut short: no JPEG end-of-image marker");
        }
    } else if head.starts_with(&PNG_SIGNATURE) && !tail.windows(8).any(|w| w == PNG_IEND) {
        return Some("cut short: no PNG end chunk (IEND)");
    }
    None
}

/// [`cut_short`] of the file at `path`, reading only its first and last bytes.
fn file_cut_short(path: &Path) -> std::io::Result<Option<&'static str>> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path)?;
    let len = f.metadata()?.len();
    let mut head = [0u8; 8];
    let n = f.read(&mut head)?;
    let mut tail = Vec::new();
    f.seek(SeekFrom::Start(len.saturating_sub(TAIL_BYTES)))?;
    f.read_to_end(&mut tail)?;
    Ok(cut_short(len, &head[..n], &tail))
}

/// `path`'s file name, as a warning names a frame.
fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// Refuses a folder when more than half of its `total` frames cannot be decoded whole, named
/// by `broken` (file, what is wrong): that is no camera dropping a frame now and then but a
/// copy gone wrong, and what is left is no recording of the run.
fn refuse_mostly_broken(
    dir: &Path,
    broken: &[(PathBuf, &str)],
    total: usize,
) -> Result<(), TrackError> {
    let Some((first, why)) = broken.first() else {
        return Ok(());
    };
    if broken.len() * 2 <= total {
        return Ok(());
    }
    Err(TrackError::bad_input(
        dir,
        format!(
            "{} of the folder's {total} frames cannot be decoded whole (the first, {}, is {why}): the frames were not copied whole; copy the folder again",
            broken.len(),
            file_name(first)
        ),
    ))
}

const IMAGE_EXTS: [&str; 6] = ["png", "jpg", "jpeg", "pgm", "bmp", "tif"];

/// Whether `path` is one of a folder's frames: an image, and not a hidden file (macOS leaves
/// `._frame_000000.png` beside each frame copied to some drives, holding no image).
fn is_frame(path: &Path) -> bool {
    let hidden = path
        .file_name()
        .is_some_and(|n| n.to_string_lossy().starts_with('.'));
    let image = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| IMAGE_EXTS.contains(&e.to_ascii_lowercase().as_str()));
    image && !hidden
}

/// Each file's frame number counted from the first's, in steps of the usual step between
/// the numbers in the names (the last run of digits in each name): none unless every name
/// carries a number, the numbers rise, and each step is a whole number of the usual one.
fn frame_numbers(files: &[PathBuf]) -> Option<Vec<usize>> {
    let numbers: Vec<u64> = files
        .iter()
        .map(|f| {
            let stem = f.file_stem()?.to_str()?;
            let end = stem.rfind(|c: char| c.is_ascii_digit())? + 1;
            let start = stem[..end]
                .rfind(|c: char| !c.is_ascii_digit())
                .map_or(0, |i| i + 1);
            stem[start..end].parse().ok()
        })
        .collect::<Option<_>>()?;
    let mut steps: Vec<u64> = numbers
        .windows(2)
        .map(|w| w[1].checked_sub(w[0]).filter(|d| *d > 0))
        .collect::<Option<_>>()?;
    steps.sort_unstable();
    let usual = *steps.get(steps.len() / 2)?;
    let first = *numbers.first()?;
    numbers
        .iter()
        .map(|n| {
            let d = n - first;
            (d % usual == 0)
                .then(|| usize::try_from(d / usual).ok())
                .flatten()
        })
        .collect()
}

impl FolderSource {
    /// Lists the images of `dir` and assigns their timestamps.
    pub fn open(dir: &Path, opts: &SourceOptions) -> Result<Self, TrackError> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| TrackError::io(dir, format!("cannot list: {e}")))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| is_frame(p))
            .collect();
        // Unpadded numbers (img2, img10) are common: plain order would scramble time.
        odocal_core::sort_naturally(&mut files);
        if files.is_empty() {
            return Err(TrackError::bad_input(
                dir,
                "the folder holds no PNG/JPEG images",
            ));
        }
        let csv = opts.timestamps_file(dir)?;
        // Numbered files that skip numbers are frames the camera dropped: counted one after
        // another, every later frame would be timed early by them (6 deleted frames put the
        // trajectory 38 mm RMS off in silence).
        let numbers = frame_numbers(&files).filter(|n| n.last().copied() != Some(n.len() - 1));
        let timing = match (&csv, opts.fps, &numbers) {
            (Some(csv), _, _) => format!("timestamps file {}", csv.display()),
            (None, fps, Some(_)) => {
                format!("file numbers at {} fps (--fps)", fps.unwrap_or(f64::NAN))
            }
            (None, fps, None) => {
                format!("frame count at {} fps (--fps)", fps.unwrap_or(f64::NAN))
            }
        };
        let times: Vec<f64> = match (csv, opts.fps) {
            (Some(csv), _) => read_timestamps(&csv, &files)?,
            (None, Some(fps)) if (super::MIN_FPS..=super::MAX_FPS).contains(&fps) => match numbers {
                Some(n) => n.iter().map(|&k| k as f64 / fps).collect(),
                None => (0..files.len()).map(|k| k as f64 / fps).collect(),
            },
            (None, Some(fps)) => return Err(TrackError::Options(format!("--fps {fps}: a camera's frame rate is {} to {} frames/s", super::MIN_FPS, super::MAX_FPS))),
            (None, None) => {
                return Err(TrackError::bad_input(
                    dir,
                    "image folder without timestamps: give --fps or --timestamps FILE.csv (columns file,t)",
                ))
            }
        };
        let mut cut = Vec::new();
        for f in &files {
            let why =
                file_cut_short(f).map_err(|e| TrackError::io(f, format!("cannot read: {e}")))?;
            if let Some(why) = why {
                cut.push((f.clone(), why));
            }
        }
        refuse_mostly_broken(dir, &cut, files.len())?;
        // The frame size is the first whole frame's.
        let mut first = None;
        for f in &files {
            if cut.iter().any(|(c, _)| c == f) {
                continue;
            }
            let m = imgcodecs::imread(f, odocal_calib::IMREAD_SENSOR_GRAY)?;
            if !m.empty() {
                first = Some((f.clone(), m));
                break;
            }
        }
        let Some((first_file, first)) = first else {
            return Err(TrackError::bad_input(
                dir,
                "none of the folder's images can be decoded",
            ));
        };
        let n = files.len();
        Ok(Self {
            info: SourceInfo {
                path: dir.to_path_buf(),
                width: first.cols() as u32,
                height: first.rows() as u32,
                frame_count: Some(n),
                kind: "images".into(),
                timing,
                extrapolated_times: 0,
                overridden_fps: None,
                corrupt_frames: Vec::new(),
                corrupt_files: Vec::new(),
                container_fps: None,
                container_times_s: None,
                // A folder's frames come from one camera: the first speaks for them all.
                interlace_comb: None,
                first_frame_clock_s: None,
                display_rotation: odocal_calib::display_rotation(&first_file)
                    .map(|turn| format!("its first image carries {turn} for display")),
            },
            files: files.into_iter().zip(times).collect(),
            next: 0,
            broken: Vec::new(),
        })
    }
}

impl FrameSource for FolderSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn next_batch(&mut self, n: usize) -> Result<Vec<Frame>, TrackError> {
        // A batch of broken frames only is no end of the folder: read on.
        while self.next < self.files.len() {
            let end = (self.next + n).min(self.files.len());
            let decoded: Vec<Decoded> = decode_pool().install(|| {
                (self.next..end)
                    .into_par_iter()
                    .map(|index| self.decode(index))
                    .collect::<Result<_, TrackError>>()
            })?;
            self.next = end;
            let mut frames = Vec::with_capacity(decoded.len());
            for d in decoded {
                match d {
                    Decoded::Frame(f) => frames.push(f),
                    Decoded::Broken(index, why) => {
                        let path = &self.files[index].0;
                        self.info.corrupt_frames.push(index);
                        self.info
                            .corrupt_files
                            .push(format!("{} ({why})", file_name(path)));
                        self.broken.push((path.clone(), why));
                    }
                }
            }
            refuse_mostly_broken(&self.info.path, &self.broken, self.files.len())?;
            if !frames.is_empty() {
                return Ok(frames);
            }
        }
        Ok(Vec::new())
    }
}

/// A frame file decoded, or left out as broken with what is wrong with it.
enum Decoded {
    Frame(Frame),
    Broken(usize, &'static str),
}

impl FolderSource {
    /// Decodes frame `index`: a frame, or [`Decoded::Broken`] when it cannot be decoded whole.
    fn decode(&self, index: usize) -> Result<Decoded, TrackError> {
        let (w, h) = (self.info.width, self.info.height);
        let (path, t_s) = &self.files[index];
        let bytes = std::fs::read(path)
            .map_err(|e| TrackError::bad_input(path, format!("cannot read it: {e}")))?;
        let tail = &bytes[bytes.len().saturating_sub(TAIL_BYTES as usize)..];
        if let Some(why) = cut_short(bytes.len() as u64, &bytes, tail) {
            return Ok(Decoded::Broken(index, why));
        }
        let mat = if bytes.starts_with(&[0xFF, 0xD8]) {
            // Damage inside a JPEG stops the decoder early without an error.
            match super::decode_jpeg_whole(&bytes, w, h)? {
                Some(m) => m,
                None => {
                    return Ok(Decoded::Broken(
                        index,
                        "damaged: its JPEG data decodes only in part",
                    ))
                }
            }
        } else {
            imgcodecs::imdecode(
                &opencv::core::Vector::<u8>::from_slice(&bytes),
                odocal_calib::IMREAD_SENSOR_GRAY,
            )?
        };
        if mat.empty() {
            return Ok(Decoded::Broken(index, "cannot be decoded"));
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
        Ok(Decoded::Frame(Frame {
            index,
            t_s: *t_s,
            image,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use opencv::core::{Mat, Scalar, Vector, CV_8UC1};

    fn encoded(ext: &str) -> Vec<u8> {
        let img = Mat::new_rows_cols_with_default(16, 24, CV_8UC1, Scalar::all(90.0)).unwrap();
        let mut buf = Vector::<u8>::new();
        assert!(imgcodecs::imencode(ext, &img, &mut buf, &Vector::new()).unwrap());
        buf.to_vec()
    }

    fn judged(bytes: &[u8]) -> Option<&'static str> {
        let tail = &bytes[bytes.len().saturating_sub(TAIL_BYTES as usize)..];
        cut_short(bytes.len() as u64, bytes, tail)
    }

    #[test]
    fn a_frame_file_without_its_end_marker_is_cut_short() {
        for ext in [".jpg", ".png"] {
            let whole = encoded(ext);
            assert_eq!(judged(&whole), None, "{ext}");
            let cut = &whole[..whole.len() - 3];
            assert!(judged(cut).unwrap().starts_with("cut short"), "{ext}");
        }
        // Zero padding after a JPEG's end-of-image marker is no cut.
        let mut padded = encoded(".jpg");
        padded.extend_from_slice(&[0; 40]);
        assert_eq!(judged(&padded), None);
        assert_eq!(judged(&[]), Some("empty (0 bytes)"));
        // A format without an end marker is left to the decoder.
        let bmp = encoded(".bmp");
        assert_eq!(judged(&bmp[..bmp.len() / 2]), None);
    }

    #[test]
    fn a_file_is_judged_by_its_first_and_last_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a.png");
        let mut whole = encoded(".png");
        // Large enough that its head and tail are read apart.
        whole.splice(33..33, std::iter::repeat_n(0u8, 3000));
        std::fs::write(&f, &whole).unwrap();
        assert_eq!(file_cut_short(&f).unwrap(), None);
        std::fs::write(&f, &whole[..2000]).unwrap();
        assert!(file_cut_short(&f).unwrap().is_some());
    }
}
