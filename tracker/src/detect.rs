//! AprilTag detection (the `apriltag` crate, i.e. the reference C library) on a
//! whole frame or a region of interest, with corners in OpenCV's pixel
//! convention (pixel centres at integer coordinates).

use std::str::FromStr;

use apriltag::{Detector, DetectorBuilder, Family, Image};
use nalgebra::Point2;

use crate::source::GrayFrame;
use crate::TrackError;

/// The tag families the AprilTag library knows, each with the number of tags it holds (ids 0
/// to that less one; the unit test reads each from the C library's own code table).
const FAMILIES: [(&str, u32); 8] = [
    ("tag36h11", 587),
    ("tag25h9", 35),
    ("tag16h5", 30),
    ("tagStandard41h12", 2115),
    ("tagStandard52h13", 48714),
    ("tagCircle21h7", 38),
    ("tagCircle49h12", 65535),
    ("tagCustom48h12", 42211),
];

fn unknown_family(family: &str) -> TrackError {
    let names: Vec<&str> = FAMILIES.iter().map(|(name, _)| *name).collect();
    TrackError::Options(format!(
        "unknown tag family {family:?}: use {} or {}",
        names[..names.len() - 1].join(", "),
        names[names.len() - 1]
    ))
}

/// Refuses a tag id that `family` does not hold, naming its range and `option` (the
/// command-line option that gave it): no frame could show that tag, and looking for it
/// would search the whole video before saying so.
pub fn check_tag_id(family: &str, id: u32, option: &str) -> Result<(), TrackError> {
    let (_, size) = FAMILIES
        .iter()
        .find(|(name, _)| *name == family)
        .ok_or_else(|| unknown_family(family))?;
    if id >= *size {
        return Err(TrackError::Options(format!(
            "{option} {id}: {family} holds tags 0 to {}; give the id of the robot's tag, or the --family it belongs to",
            size - 1
        )));
    }
    Ok(())
}

/// Frames [`read_other_families`] tries at most: the tag reads in nearly every frame of
/// the right family, so a handful says which it is (each family costs one pass per frame).
pub const FAMILY_PROBE_FRAMES: usize = 5;

/// A tag read by another family than the one tracked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FamilyReading {
    /// The family the tag reads as.
    pub family: &'static str,
    /// Its id in that family.
    pub id: u32,
    /// Frames in which it read with every bit right.
    pub frames: usize,
}

/// What the other families read in a few frames of a video whose tag the tracked family
/// did not find.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FamilyProbe {
    /// Frames tried.
    pub frames_tried: usize,
    /// The tag those frames show, if another family reads one in at least half of them.
    pub reading: Option<FamilyReading>,
}

impl FamilyProbe {
    /// What to tell the user: the family and id to give, or that no other family reads a tag
    /// either. `tag_id` is the id given (named again only when the tag's differs).
    pub fn advice(&self, tag_id: u32) -> String {
        match &self.reading {
            Some(r) => format!(
                "the tag in {} of {} frames tried reads as {} id {} (every bit right): give --family {}{}",
                r.frames,
                self.frames_tried,
                r.family,
                r.id,
                r.family,
                if r.id == tag_id {
                    String::new()
                } else {
                    format!(" --tag-id {}", r.id)
                }
            ),
            None => format!(
                "no other AprilTag family reads a tag in the {} frames tried either (a tag this library does not know, or one too small, blurred or dark to read)",
                self.frames_tried
            ),
        }
    }
}

/// The least Hamming distance between two codes of `family` (the number after "h"): the
/// more, the less a false reading of it is likely.
fn family_distance(family: &str) -> u32 {
    family
        .rsplit('h')
        .next()
        .and_then(|d| d.parse().ok())
        .unwrap_or(0)
}

/// The ids of `family` read with every bit right in the mirror images of `frames`, each with
/// the frames it was read in; empty unless read in at least half of them. A tag reads only
/// the right way round, so a video mirrored by the camera's setting shows no tag at all.
pub(crate) fn read_mirrored(
    frames: &[GrayFrame],
    family: &str,
) -> Result<Vec<(u32, usize)>, TrackError> {
    let frames = &frames[..frames.len().min(FAMILY_PROBE_FRAMES)];
    let mut det = TagDetector::new(family, 0, 2.0)?;
    let mut tally: std::collections::BTreeMap<u32, usize> = Default::default();
    for frame in frames {
        let w = frame.width as usize;
        let data: Vec<u8> = frame
            .data
            .chunks_exact(w.max(1))
            .flat_map(|row| row.iter().rev().copied())
            .collect();
        let mirrored = GrayFrame {
            width: frame.width,
            height: frame.height,
            data,
        };
        let mut ids: Vec<u32> = det
            .detect_raw(&mirrored)?
            .iter()
            .filter(|d| d.hamming == 0)
            .map(|d| d.id)
            .collect();
        ids.sort_unstable();
        ids.dedup();
        for id in ids {
            *tally.entry(id).or_insert(0) += 1;
        }
    }
    Ok(tally
        .into_iter()
        .filter(|&(_, n)| 2 * n >= frames.len() && n > 0)
        .collect())
}

/// Reads `frames` with every AprilTag family but `tracked`, for a video whose tag the
/// tracked family does not find (or reads only as false, shapeless codes). The tag is the
/// (family, id) read with every bit right in the most frames, at least half of them; on a
/// tie, the family whose codes lie farther apart (a small family's codes are read falsely
/// inside a larger family's tag, the same in every frame of a tag at rest).
pub fn read_other_families(frames: &[GrayFrame], tracked: &str) -> Result<FamilyProbe, TrackError> {
    let frames = &frames[..frames.len().min(FAMILY_PROBE_FRAMES)];
    // (frames read, distance, summed decision margin) per (family, id)
    let mut tally: std::collections::BTreeMap<(&'static str, u32), (usize, u32, f64)> =
        Default::default();
    for (family, _) in FAMILIES.iter().filter(|(f, _)| *f != tracked) {
        // No bit corrected: a misread of another tag must not pass for this family's, and the
        // large families' tables for corrections cost more to build than the search.
        let mut det = TagDetector::new(family, 0, 2.0)?;
        for frame in frames {
            let mut ids: Vec<(u32, f32)> = det
                .detect_raw(frame)?
                .iter()
                .filter(|d| d.hamming == 0)
                .map(|d| (d.id, d.decision_margin))
                .collect();
            ids.sort_by_key(|(id, _)| *id);
            ids.dedup_by_key(|(id, _)| *id);
            for (id, margin) in ids {
                let e = tally
                    .entry((*family, id))
                    .or_insert((0, family_distance(family), 0.0));
                e.0 += 1;
                e.2 += margin as f64;
            }
        }
    }
    let best = tally
        .into_iter()
        .filter(|(_, (n, _, _))| 2 * n >= frames.len() && *n > 0)
        .max_by(|a, b| {
            (a.1 .0, a.1 .1)
                .cmp(&(b.1 .0, b.1 .1))
                .then(a.1 .2.total_cmp(&b.1 .2))
        });
    Ok(FamilyProbe {
        frames_tried: frames.len(),
        reading: best.map(|((family, id), (frames, _, _))| FamilyReading { family, id, frames }),
    })
}

/// [`read_other_families`] on [`FAMILY_PROBE_FRAMES`] frames spread over the video or frame
/// folder at `path`: for a run whose frames were not kept (an arena's cameras are tracked
/// for several tags at once), read again only when no selected tag was seen at all.
pub fn probe_video_families(
    path: &std::path::Path,
    opts: &crate::SourceOptions,
    tracked: &str,
) -> Result<FamilyProbe, TrackError> {
    let mut source = crate::open_source(path, opts)?;
    let stride = source
        .info()
        .frame_count
        .map_or(30, |n| n / FAMILY_PROBE_FRAMES)
        .max(1);
    let mut frames = Vec::new();
    while frames.len() < FAMILY_PROBE_FRAMES {
        let batch = source.next_batch(16)?;
        if batch.is_empty() {
            break;
        }
        frames.extend(
            batch
                .into_iter()
                .filter(|f| f.index % stride == 0)
                .map(|f| f.image),
        );
    }
    read_other_families(&frames, tracked)
}

/// A rectangle of pixels: columns x0..x0+width, rows y0..y0+height.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Roi {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
}

impl Roi {
    /// A square of half-size `half_px` around `centre`, clipped to a `w`×`h`
    /// image; `None` if nothing of it is inside.
    pub fn around(centre: Point2<f64>, half_px: f64, w: u32, h: u32) -> Option<Self> {
        let x0 = (centre.x - half_px).floor().max(0.0);
        let y0 = (centre.y - half_px).floor().max(0.0);
        let x1 = (centre.x + half_px).ceil().min(w as f64);
        let y1 = (centre.y + half_px).ceil().min(h as f64);
        (x1 - x0 >= 16.0 && y1 - y0 >= 16.0).then_some(Self {
            x0: x0 as u32,
            y0: y0 as u32,
            width: (x1 - x0) as u32,
            height: (y1 - y0) as u32,
        })
    }
}

/// One detected tag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TagDetection {
    /// Tag id within the family.
    pub id: u32,
    /// Bits corrected while decoding.
    pub hamming: u32,
    /// The detector's decision margin (higher is more certain).
    pub decision_margin: f32,
    /// Corners of the black square in full-frame pixels (OpenCV convention), in
    /// the detector's order: counter-clockwise in the tag's own frame (x right,
    /// y up the printed tag) starting at the bottom-left corner.
    pub corners_px: [Point2<f64>; 4],
}

impl TagDetection {
    /// Centre of the four corners, pixels.
    pub fn centre_px(&self) -> Point2<f64> {
        quad_centre(&self.corners_px)
    }

    /// Mean side length of the quad, pixels.
    pub fn side_px(&self) -> f64 {
        (0..4)
            .map(|i| (self.corners_px[(i + 1) % 4] - self.corners_px[i]).norm())
            .sum::<f64>()
            / 4.0
    }
}

/// The mean of a tag's four corners, pixels.
pub fn quad_centre(corners_px: &[Point2<f64>; 4]) -> Point2<f64> {
    let s = corners_px
        .iter()
        .fold(nalgebra::Vector2::zeros(), |a, p| a + p.coords);
    Point2::from(s / 4.0)
}

/// An AprilTag detector for one family. Not shared between threads: make one
/// per thread.
pub struct TagDetector {
    det: Detector,
    decimate: f32,
    /// Scratch image reused between calls of the same size.
    scratch: Option<Image>,
}

// SAFETY: the C detector has no thread affinity; it is only used through
// `&mut self`, so never from two threads at once.
unsafe impl Send for TagDetector {}

impl TagDetector {
    /// A detector for `family` (e.g. "tag36h11") correcting up to `max_bits`
    /// bit errors, with quad decimation `decimate` (1 = full resolution).
    pub fn new(family: &str, max_bits: usize, decimate: f32) -> Result<Self, TrackError> {
        let fam = Family::from_str(family).map_err(|_| unknown_family(family))?;
        let mut det = DetectorBuilder::new()
            .add_family_bits(fam, max_bits)
            .build()
            .map_err(|e| TrackError::Options(format!("cannot create the tag detector: {e}")))?;
        det.set_thread_number(1);
        det.set_decimation(decimate);
        det.set_sigma(0.0);
        det.set_refine_edges(true);
        det.set_shapening(0.25);
        Ok(Self {
            det,
            decimate,
            scratch: None,
        })
    }

    /// AprilTag 3's own detector as its authors configure it by default (quad decimation 2,
    /// no quad blur, edge refinement, decode sharpening 0.25, no odocal refit): the reference
    /// that odocal's detection rate is compared with. Use [`TagDetector::detect_raw`].
    pub fn reference(family: &str) -> Result<Self, TrackError> {
        Self::new(family, 2, 2.0)
    }

    /// Gaussian blur (σ, pixels) applied before the quad search (the C library's `quad_sigma`;
    /// 0 for none). It steadies the segmentation of noisy or blurred frames; the corners are
    /// refined on the unblurred image.
    pub fn set_quad_sigma(&mut self, sigma: f32) {
        self.det.set_sigma(sigma);
    }

    /// Quad decimation in use.
    pub fn decimate(&self) -> f32 {
        self.decimate
    }

    /// Changes the quad decimation.
    pub fn set_decimate(&mut self, decimate: f32) {
        if decimate != self.decimate {
            self.det.set_decimation(decimate);
            self.decimate = decimate;
        }
    }

    /// Detects tags in `frame`, restricted to `roi` if given. Corners are in
    /// full-frame pixel coordinates, refined from the tag's edges.
    pub fn detect(
        &mut self,
        frame: &GrayFrame,
        roi: Option<Roi>,
    ) -> Result<Vec<TagDetection>, TrackError> {
        let mut out = self.detect_in(frame, roi)?;
        // The C library's quad fit is biased by up to a tenth of a pixel; refit the sides.
        for d in &mut out {
            if let Some(c) = crate::edges::refine_corners(frame, &d.corners_px) {
                d.corners_px = c;
            }
        }
        Ok(out)
    }

    /// Detects tags in `roi` after undoing a motion blur of `len_px` along the unit image
    /// vector `dir` with a Wiener filter of noise-to-signal ratio `nsr` (see `deblur.rs`); the
    /// corners are refitted on the original frame.
    pub fn detect_deblurred(
        &mut self,
        frame: &GrayFrame,
        roi: Roi,
        dir: nalgebra::Vector2<f64>,
        len_px: f64,
        nsr: f64,
    ) -> Result<Vec<TagDetection>, TrackError> {
        let sharp = crate::deblur::deblur_roi(frame, roi, dir, len_px, nsr)?;
        let mut out = self.detect_in(&sharp, None)?;
        let shift = nalgebra::Vector2::new(roi.x0 as f64, roi.y0 as f64);
        for d in &mut out {
            d.corners_px = d.corners_px.map(|p| p + shift);
            if let Some(c) = crate::edges::refine_corners(frame, &d.corners_px) {
                d.corners_px = c;
            }
        }
        Ok(out)
    }

    /// Detects tags in the whole frame exactly as the C library reports them (no refit).
    pub fn detect_raw(&mut self, frame: &GrayFrame) -> Result<Vec<TagDetection>, TrackError> {
        self.detect_in(frame, None)
    }

    fn detect_in(
        &mut self,
        frame: &GrayFrame,
        roi: Option<Roi>,
    ) -> Result<Vec<TagDetection>, TrackError> {
        let r = roi.unwrap_or(Roi {
            x0: 0,
            y0: 0,
            width: frame.width,
            height: frame.height,
        });
        let (w, h) = (r.width as usize, r.height as usize);
        let reuse = matches!(&self.scratch, Some(im) if im.width() == w && im.height() == h);
        if !reuse {
            self.scratch = Some(Image::zeros_with_alignment(w, h, 96).map_err(|e| {
                TrackError::Options(format!("cannot allocate a detector image: {e}"))
            })?);
        }
        let Some(img) = self.scratch.as_mut() else {
            return Ok(vec![]);
        };
        let stride = img.stride();
        let buf = img.as_slice_mut();
        let fw = frame.width as usize;
        for row in 0..h {
            let src = (r.y0 as usize + row) * fw + r.x0 as usize;
            buf[row * stride..row * stride + w].copy_from_slice(&frame.data[src..src + w]);
        }
        let img = &*img;
        let dets = self.det.detect(img);
        // The C library puts pixel centres at +0.5; OpenCV at integers.
        let (ox, oy) = (r.x0 as f64 - 0.5, r.y0 as f64 - 0.5);
        let out: Vec<TagDetection> = dets
            .iter()
            .map(|d| {
                let c = d.corners();
                TagDetection {
                    id: d.id() as u32,
                    hamming: d.hamming() as u32,
                    decision_margin: d.decision_margin(),
                    corners_px: c.map(|p| Point2::new(p[0] + ox, p[1] + oy)),
                }
            })
            .collect();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roi_is_clipped_to_the_image() {
        let r = Roi::around(Point2::new(5.0, 700.0), 40.0, 1280, 720).unwrap();
        assert_eq!((r.x0, r.y0, r.width, r.height), (0, 660, 45, 60));
        assert!(Roi::around(Point2::new(-100.0, 10.0), 40.0, 1280, 720).is_none());
    }

    #[test]
    fn blank_frames_have_no_tags_and_unknown_families_are_refused() {
        let mut d = TagDetector::new("tag36h11", 1, 1.0).unwrap();
        let frame = GrayFrame {
            width: 64,
            height: 48,
            data: vec![128; 64 * 48],
        };
        assert!(d.detect(&frame, None).unwrap().is_empty());
        let e = TagDetector::new("tag99h1", 1, 1.0)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("tag99h1"), "{e}");
        assert!(
            e.contains("use tag36h11, tag25h9,") && e.contains(" or tagCustom48h12"),
            "{e}"
        );
    }

    /// A `family` tag of `id` drawn `cell_px` pixels a cell, on a grey frame with a white
    /// margin, from the C library's own pattern.
    fn drawn_tag(family: &str, id: u32, cell_px: usize) -> GrayFrame {
        use apriltag_sys as sys;
        // SAFETY: the family is created and freed here by the library's own calls, and its
        // image read within its width, height and stride before it is freed.
        let (cells, n) = unsafe {
            let (make, free): (
                unsafe extern "C" fn() -> *mut sys::apriltag_family_t,
                unsafe extern "C" fn(*mut sys::apriltag_family_t),
            ) = match family {
                "tag36h11" => (sys::tag36h11_create, sys::tag36h11_destroy),
                "tag25h9" => (sys::tag25h9_create, sys::tag25h9_destroy),
                _ => panic!("{family} is not drawn here"),
            };
            let f = make();
            let im = sys::apriltag_to_image(f, id);
            free(f);
            let (w, stride) = ((*im).width as usize, (*im).stride as usize);
            let buf = std::slice::from_raw_parts((*im).buf, stride * w);
            let cells: Vec<u8> = (0..w * w).map(|k| buf[(k / w) * stride + k % w]).collect();
            sys::image_u8_destroy(im);
            (cells, w)
        };
        let (margin, side) = (3 * cell_px, n * cell_px);
        let size = side + 2 * margin;
        let mut data = vec![200u8; size * size];
        for y in 0..side {
            for x in 0..side {
                let white = cells[(y / cell_px) * n + x / cell_px] > 127;
                data[(y + margin) * size + x + margin] = if white { 230 } else { 25 };
            }
        }
        GrayFrame {
            width: size as u32,
            height: size as u32,
            data,
        }
    }

    /// A tag of another family than the one given is named by family and id, also where a
    /// smaller family reads false codes inside it; a frame without a tag names none.
    #[test]
    fn another_familys_tag_is_named() {
        let frames = vec![drawn_tag("tag25h9", 3, 6); 3];
        let probe = read_other_families(&frames, "tag36h11").unwrap();
        let r = probe.reading.as_ref().unwrap();
        assert_eq!((r.family, r.id, r.frames), ("tag25h9", 3, 3), "{probe:?}");
        assert_eq!(probe.frames_tried, 3);
        let said = probe.advice(0);
        assert!(
            said.contains(
                "reads as tag25h9 id 3 (every bit right): give --family tag25h9 --tag-id 3"
            ),
            "{said}"
        );
        let frames = vec![drawn_tag("tag36h11", 0, 5); 2];
        let probe = read_other_families(&frames, "tag16h5").unwrap();
        let r = probe.reading.as_ref().unwrap();
        assert_eq!((r.family, r.id), ("tag36h11", 0), "{probe:?}");
        assert!(probe.advice(0).ends_with("give --family tag36h11"));
        let blank = GrayFrame {
            width: 96,
            height: 96,
            data: vec![128; 96 * 96],
        };
        let probe = read_other_families(&[blank], "tag36h11").unwrap();
        assert_eq!(probe.reading, None);
        assert!(probe
            .advice(0)
            .starts_with("no other AprilTag family reads a tag in the 1 frames tried"));
    }

    #[test]
    fn family_sizes_are_the_c_library_s() {
        use apriltag_sys as sys;
        type Make = unsafe extern "C" fn() -> *mut sys::apriltag_family_t;
        type Free = unsafe extern "C" fn(*mut sys::apriltag_family_t);
        let c: [(&str, Make, Free); 8] = [
            ("tag36h11", sys::tag36h11_create, sys::tag36h11_destroy),
            ("tag25h9", sys::tag25h9_create, sys::tag25h9_destroy),
            ("tag16h5", sys::tag16h5_create, sys::tag16h5_destroy),
            (
                "tagStandard41h12",
                sys::tagStandard41h12_create,
                sys::tagStandard41h12_destroy,
            ),
            (
                "tagStandard52h13",
                sys::tagStandard52h13_create,
                sys::tagStandard52h13_destroy,
            ),
            (
                "tagCircle21h7",
                sys::tagCircle21h7_create,
                sys::tagCircle21h7_destroy,
            ),
            (
                "tagCircle49h12",
                sys::tagCircle49h12_create,
                sys::tagCircle49h12_destroy,
            ),
            (
                "tagCustom48h12",
                sys::tagCustom48h12_create,
                sys::tagCustom48h12_destroy,
            ),
        ];
        for ((name, size), (c_name, make, free)) in FAMILIES.iter().zip(c) {
            assert_eq!(*name, c_name);
            // SAFETY: the family is created, read and freed here by the library's own calls.
            let ncodes = unsafe {
                let f = make();
                let n = (*f).ncodes;
                free(f);
                n
            };
            assert_eq!(*size, ncodes, "{name}");
            assert!(Family::from_str(name).is_ok(), "{name}");
        }
        assert!(check_tag_id("tag36h11", 586, "--tag-id").is_ok());
        let e = check_tag_id("tag36h11", 587, "--tag-id")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("--tag-id 587: tag36h11 holds tags 0 to 586"),
            "{e}"
        );
        let e = check_tag_id("tag16h5", 30, "--tags")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("--tags 30: tag16h5 holds tags 0 to 29"),
            "{e}"
        );
    }
}
