//! Folders of PNG/JPEG images, decoded in parallel, timed by a timestamp file or a frame rate.

use super::timestamps::read_timestamps;
use super::*;

/// A folder of PNG/JPEG frames in natural file-name order (`img2` before `img10`).
pub struct FolderSource {
    info: SourceInfo,
    files: Vec<(PathBuf, f64)>,
    next: usize,
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
        let timing = match (&csv, opts.fps) {
            (Some(csv), _) => format!("timestamps file {}", csv.display()),
            (None, fps) => format!("frame count at {} fps (--fps)", fps.unwrap_or(f64::NAN)),
        };
        let times: Vec<f64> = match (csv, opts.fps) {
            (Some(csv), _) => read_timestamps(&csv, &files)?,
            (None, Some(fps)) if (super::MIN_FPS..=super::MAX_FPS).contains(&fps) => (0..files.len()).map(|k| k as f64 / fps).collect(),
            (None, Some(fps)) => return Err(TrackError::Options(format!("--fps {fps}: a camera's frame rate is {} to {} frames/s", super::MIN_FPS, super::MAX_FPS))),
            (None, None) => {
                return Err(TrackError::bad_input(
                    dir,
                    "image folder without timestamps: give --fps or --timestamps FILE.csv (columns file,t)",
                ))
            }
        };
        let first = imgcodecs::imread(&files[0], odocal_calib::IMREAD_SENSOR_GRAY)?;
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
                timing,
                extrapolated_times: 0,
                overridden_fps: None,
                corrupt_frames: Vec::new(),
                container_fps: None,
                container_times_s: None,
                // A folder's frames come from one camera: the first speaks for them all.
                display_rotation: odocal_calib::display_rotation(&files[0])
                    .map(|turn| format!("its first image carries {turn} for display")),
            },
            files: files.into_iter().zip(times).collect(),
            next: 0,
        })
    }
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
                    let bytes = std::fs::read(path)
                        .map_err(|e| TrackError::bad_input(path, format!("cannot read it: {e}")))?;
                    let is_jpeg = bytes.starts_with(&[0xFF, 0xD8]);
                    if is_jpeg && !super::jpeg_is_whole(&bytes) {
                        return Err(TrackError::bad_input(
                            path,
                            "is not a whole JPEG image (cut short or damaged; OpenCV would decode its missing rows as leftover memory): copy it again, or delete it from the folder (with its row in timestamps.csv) to leave a gap",
                        ));
                    }
                    let mat = imgcodecs::imdecode(
                        &opencv::core::Vector::<u8>::from_slice(&bytes),
                        odocal_calib::IMREAD_SENSOR_GRAY,
                    )?;
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
