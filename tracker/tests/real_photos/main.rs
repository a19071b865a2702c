//! odocal's tag corners on real photographs: the AprilTag C library's three test photographs
//! (47 tag36h11 tags, 10–45 px across) with the reference corners that library ships
//! (tests/data/apriltag, whose README gives their origin, licence and pixel convention).
//!
//! odocal's corners sit lower in these photographs than the reference corners: by 0.09, 0.29
//! and 0.10 px in y, and within 0.04 px in x. The reference corners are the library's quad fit
//! without edge refinement, not the truth, so the tests here ask two questions that do not
//! depend on them:
//!
//! - Does odocal carry a fixed offset, as a half-pixel or a one-sided stencil in one axis
//!   would give? Such an offset stays put in image axes when the photograph is turned half
//!   way round, while everything the picture itself causes turns with it; so half the
//!   difference between the corners found in the photograph and in the turned photograph
//!   (mapped back) is the offset. odocal's is below 0.006 px in both axes on all three.
//! - Where are the corners, judged by a method that shares neither the quad fit nor odocal's
//!   edge model? A fit of the whole printed pattern to the pixels (`pattern_fit`) puts them
//!   within 0.015 px of odocal's on average in each axis, and 0.07–0.27 px below the
//!   reference corners.
//!
//! So the y-only difference is the reference's. A little of it is the quad fit's own fixed
//! offset, 0.03–0.07 px up (and 0.02–0.05 px left), measured here the same way; the rest turns
//! with the picture. The quad fit's error depends on what lies beside each side of the black
//! square (light data cells next to the ring pull it, differently on each side), and every tag
//! in these photos is id 0 upright on the face of a cube, so it errs the same way in all of
//! them. (On rendered, blurred id-0 tags of this size the quad fit sits up to 0.18 px high;
//! turn the tag a quarter and most of the error turns with it.)

mod pattern_fit;

use std::path::PathBuf;
use std::str::FromStr;

use apriltag::{DetectorBuilder, Family, Image};
use nalgebra::{Point2, Vector2};
use odocal_tracker::{GrayFrame, Roi, TagDetector};
use opencv::core::{rotate, Mat, ROTATE_180};
use opencv::imgcodecs;
use opencv::prelude::*;
use pattern_fit::{fit, TagCells};

/// The photographs, by file stem.
const PHOTOS: [&str; 3] = [
    "33369213973_9d9bb4cc96_c",
    "34085369442_304b6bafd9_c",
    "34139872896_defdb2f8d9_c",
];

type Quad = [Point2<f64>; 4];

fn data(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/apriltag")
        .join(file)
}

fn photo(stem: &str) -> Mat {
    let path = data(&format!("{stem}.jpg"));
    let mat = imgcodecs::imread(&path, imgcodecs::IMREAD_GRAYSCALE).expect("imread");
    assert!(!mat.empty(), "cannot read {}", path.display());
    mat
}

/// The reference corners of a photograph, in OpenCV's convention (the file's minus 0.5).
fn reference(stem: &str) -> Vec<Quad> {
    let path = data(&format!("{stem}.txt"));
    let text = std::fs::read_to_string(&path).expect("reference corners");
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|line| {
            let v: Vec<f64> = line
                .replace(['(', ')', ','], " ")
                .split_whitespace()
                .skip(1)
                .map(|s| s.parse().expect("a number"))
                .collect();
            assert_eq!(v.len(), 8, "{}: {line}", path.display());
            [0, 1, 2, 3].map(|k| Point2::new(v[2 * k] - 0.5, v[2 * k + 1] - 0.5))
        })
        .collect()
}

/// The AprilTag library's own quad fit with the settings its test used for the reference
/// corners (full resolution, no edge refinement), in OpenCV's convention.
fn quad_fit(frame: &GrayFrame) -> Vec<Quad> {
    let family = Family::from_str("tag36h11").expect("tag36h11");
    let mut detector = DetectorBuilder::new()
        .add_family_bits(family, 2)
        .build()
        .expect("detector");
    detector.set_thread_number(1);
    detector.set_decimation(1.0);
    detector.set_refine_edges(false);
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut image = Image::zeros_with_alignment(w, h, 96).expect("image");
    let stride = image.stride();
    let buf = image.as_slice_mut();
    for (row, pixels) in frame.data.chunks_exact(w).enumerate() {
        buf[row * stride..row * stride + w].copy_from_slice(pixels);
    }
    detector
        .detect(&image)
        .iter()
        .map(|d| d.corners().map(|p| Point2::new(p[0] - 0.5, p[1] - 0.5)))
        .collect()
}

/// odocal's detections at full resolution, as the tracker makes them.
fn odocal(frame: &GrayFrame) -> Vec<(u32, Quad)> {
    let mut detector = TagDetector::new("tag36h11", 1, 1.0).expect("detector");
    detector
        .detect(frame, None)
        .expect("detection")
        .into_iter()
        .map(|d| (d.id, d.corners_px))
        .collect()
}

fn centre(q: &Quad) -> Vector2<f64> {
    q.iter().fold(Vector2::zeros(), |s, p| s + p.coords) / 4.0
}

/// `found`'s corners minus `truth`'s, corner by nearest corner, for the quads whose centres
/// are within 2 px of one another.
fn differences(found: &[Quad], truth: &[Quad]) -> Vec<Vector2<f64>> {
    let mut out = Vec::new();
    for t in truth {
        let Some(f) = found.iter().find(|f| (centre(f) - centre(t)).norm() < 2.0) else {
            continue;
        };
        for p in t {
            let q = f
                .iter()
                .min_by(|a, b| (*a - p).norm().total_cmp(&(*b - p).norm()));
            out.extend(q.map(|q| q - p));
        }
    }
    out
}

/// Mean of how far `found`'s corners lie outwards of `truth`'s (away from the tag's centre),
/// pixels: a detector that makes tags too large or too small shows here, not in the mean offset.
fn outwards(found: &[Quad], truth: &[Quad]) -> f64 {
    let mut sum = 0.0;
    let mut n = 0;
    for t in truth {
        let Some(f) = found.iter().find(|f| (centre(f) - centre(t)).norm() < 2.0) else {
            continue;
        };
        for p in t {
            if let Some(q) = f
                .iter()
                .min_by(|a, b| (*a - p).norm().total_cmp(&(*b - p).norm()))
            {
                sum += (q - p).dot(&(p.coords - centre(t)).normalize());
                n += 1;
            }
        }
    }
    sum / n.max(1) as f64
}

/// Mean and RMS of differences per axis, pixels.
struct Offset {
    mean: Vector2<f64>,
    rms: Vector2<f64>,
    corners: usize,
}

fn offset(d: &[Vector2<f64>]) -> Offset {
    let n = d.len().max(1) as f64;
    Offset {
        mean: d.iter().sum::<Vector2<f64>>() / n,
        rms: (d.iter().map(|e| e.component_mul(e)).sum::<Vector2<f64>>() / n).map(f64::sqrt),
        corners: d.len(),
    }
}

fn show(what: &str, o: &Offset) -> String {
    format!(
        "{what}: mean ({:+.3}, {:+.3}) px, RMS ({:.3}, {:.3}) px over {} corners",
        o.mean.x, o.mean.y, o.rms.x, o.rms.y, o.corners
    )
}

/// What the reference corners are: the library's quad fit without edge refinement, which the
/// `apriltag` crate reproduces on OpenCV's decoding of the photographs to 0.02 px RMS (its own
/// test allows 0.1 px per coordinate; one corner of the 188 moves by 0.14 px here, where
/// OpenCV's JPEG decoder and the library's differ by a grey level at a threshold).
#[test]
fn reference_corners_are_the_librarys_quad_fit() {
    for stem in PHOTOS {
        let frame = GrayFrame::from_mat(&photo(stem)).expect("grey frame");
        let truth = reference(stem);
        let d = differences(&quad_fit(&frame), &truth);
        let o = offset(&d);
        let worst = d.iter().map(|e| e.amax()).fold(0.0, f64::max);
        println!(
            "{stem}: {}, worst {worst:.3} px",
            show("quad fit − reference", &o)
        );
        assert_eq!(d.len(), 4 * truth.len(), "{stem}: every reference tag");
        assert!(
            o.rms.x < 0.03 && o.rms.y < 0.03 && worst < 0.25,
            "{stem}: {}",
            show("quad fit − reference", &o)
        );
    }
}

/// The reference corners and odocal's agree up to the reference's own offset: every tag but
/// one (13 px across) is found, x agrees on average within 0.05 px, y within 0.35 px (the
/// part the pattern fit shows to be the reference's), and no corner is a pixel off in RMS.
#[test]
fn corners_agree_with_the_reference_corners() {
    for stem in PHOTOS {
        let frame = GrayFrame::from_mat(&photo(stem)).expect("grey frame");
        let truth = reference(stem);
        let found: Vec<Quad> = odocal(&frame).into_iter().map(|(_, q)| q).collect();
        let d = differences(&found, &truth);
        let o = offset(&d);
        println!("{stem}: {}", show("odocal − reference", &o));
        assert!(
            o.corners + 4 >= 4 * truth.len(),
            "{stem}: {} of {} reference tags found",
            o.corners / 4,
            truth.len()
        );
        assert!(o.mean.x.abs() < 0.05, "{stem}: {}", show("x", &o));
        assert!(o.mean.y.abs() < 0.35, "{stem}: {}", show("y", &o));
        assert!(
            o.rms.x < 0.7 && o.rms.y < 0.7,
            "{stem}: {}",
            show("RMS", &o)
        );
    }
}

/// No fixed offset in either axis: the corners found in the photograph turned half way round,
/// mapped back, differ from those found in the photograph by twice the fixed offset.
#[test]
fn no_fixed_offset_when_the_photograph_is_turned_half_way_round() {
    for stem in PHOTOS {
        let mat = photo(stem);
        let mut turned_mat = Mat::default();
        rotate(&mat, &mut turned_mat, ROTATE_180).expect("rotate");
        let frame = GrayFrame::from_mat(&mat).expect("grey frame");
        let (w, h) = (frame.width as f64, frame.height as f64);
        // Pixel (x, y) of the photograph is pixel (w−1−x, h−1−y) of the turned one.
        let back = |p: Point2<f64>| Point2::new(w - 1.0 - p.x, h - 1.0 - p.y);
        let upright: Vec<Quad> = odocal(&frame).into_iter().map(|(_, q)| q).collect();
        let turned: Vec<Quad> = odocal(&GrayFrame::from_mat(&turned_mat).expect("grey frame"))
            .into_iter()
            .map(|(_, q)| q.map(back))
            .collect();
        let d = differences(&upright, &turned);
        let fixed = offset(&d).mean / 2.0;
        // The same measure of the quad fit behind the reference corners, for comparison.
        let theirs = offset(&differences(
            &quad_fit(&frame),
            &quad_fit(&GrayFrame::from_mat(&turned_mat).expect("grey frame"))
                .into_iter()
                .map(|q| q.map(back))
                .collect::<Vec<_>>(),
        ))
        .mean
            / 2.0;
        println!(
            "{stem}: fixed offset ({:+.4}, {:+.4}) px from {} corners; the quad fit's ({:+.4}, {:+.4}) px",
            fixed.x,
            fixed.y,
            d.len(),
            theirs.x,
            theirs.y
        );
        assert!(d.len() >= 40, "{stem}: only {} corners in both", d.len());
        assert!(
            fixed.x.abs() < 0.02 && fixed.y.abs() < 0.02,
            "{stem}: odocal's corners carry a fixed offset of ({:+.4}, {:+.4}) px",
            fixed.x,
            fixed.y
        );
    }
}

/// A tag found in a region of interest (at odd offsets) has the corners it has in the whole
/// frame: the region's origin is added back without a slip. (The edge refit starts from the
/// library's quad, which the region's other thresholds change a little, and stops within about
/// 0.01 px of the same answer.)
#[test]
fn a_region_of_interest_gives_the_whole_frames_corners() {
    let frame = GrayFrame::from_mat(&photo(PHOTOS[2])).expect("grey frame");
    let whole = odocal(&frame);
    let mut detector = TagDetector::new("tag36h11", 1, 1.0).expect("detector");
    let mut d = Vec::new();
    for (id, q) in &whole {
        let c = centre(q);
        let roi = Roi::around(Point2::from(c), 41.3, frame.width, frame.height).expect("roi");
        let found: Vec<Quad> = detector
            .detect(&frame, Some(roi))
            .expect("detection")
            .into_iter()
            .filter(|t| t.id == *id)
            .map(|t| t.corners_px)
            .collect();
        d.extend(differences(&found, &[*q]));
    }
    let o = offset(&d);
    println!("{}", show("region − whole frame", &o));
    assert!(o.corners + 4 >= 4 * whole.len(), "{} corners", o.corners);
    assert!(
        o.mean.x.abs() < 0.005 && o.mean.y.abs() < 0.005,
        "{}",
        show("mean", &o)
    );
    assert!(d.iter().all(|e| e.norm() < 0.05), "{}", show("largest", &o));
}

/// The judge first: on rendered tags as small and blurred as the photographs' (17 px, blur σ
/// 0.6 and 1.0 px, noise σ 2), the pattern fit finds the drawn corners within 0.02 px on
/// average in each axis.
#[test]
fn the_pattern_fit_finds_the_corners_of_rendered_tags() {
    use odocal_core::Pose2;
    use odocal_synth::scene::{nadir, SceneConfig, SceneRenderer};
    let tag = TagCells::tag36h11(0);
    for blur in [0.6, 1.0] {
        let mut cfg = SceneConfig::default();
        cfg.robot.tag_size_m = 0.04;
        cfg.sensor.blur_px = blur;
        cfg.lighting.amplitude = 0.0;
        let renderer = SceneRenderer::new(cfg.clone(), 3).expect("scene");
        let c = nadir(&cfg.floor);
        let mut d = Vec::new();
        for k in 0..8 {
            let pose = Pose2::new(
                c.x - 0.2 + 0.0513 * k as f64,
                c.y + 0.1 - 0.0217 * k as f64,
                0.1 + 0.79 * k as f64,
            );
            let (img, _) = renderer
                .render_frame(&[(0.0, pose), (10.0, pose)], k, 1.0)
                .expect("frame");
            let (width, height) = img.dimensions();
            let frame = GrayFrame {
                width,
                height,
                data: img.into_raw(),
            };
            let drawn = renderer.tag_corners(&pose).map(|p| {
                cfg.camera
                    .floor_to_pixel(&cfg.floor, &p, cfg.robot.marker_height_m)
                    .expect("in view")
            });
            let Some((_, start)) = odocal(&frame).into_iter().next() else {
                continue;
            };
            let f = fit(&frame, &start, &tag).expect("a pattern fit");
            d.extend(differences(&[f.corners], &[drawn]));
        }
        let o = offset(&d);
        println!("blur {blur} px: {}", show("pattern fit − drawn", &o));
        assert!(o.corners >= 24, "{} corners", o.corners);
        assert!(
            o.mean.x.abs() < 0.02 && o.mean.y.abs() < 0.02,
            "{}",
            show("pattern fit − drawn", &o)
        );
        assert!(o.rms.x < 0.1 && o.rms.y < 0.1, "{}", show("RMS", &o));
    }
}

/// The corners against the pattern fit: odocal's agree within 0.03 px on average in each axis
/// (0.3 px RMS) on every photograph; the reference corners sit at least 0.05 px above.
#[test]
fn corners_agree_with_a_fit_of_the_whole_tag_pattern() {
    for stem in PHOTOS {
        let frame = GrayFrame::from_mat(&photo(stem)).expect("grey frame");
        let found = odocal(&frame);
        let mut fitted = Vec::new();
        let mut blur = Vec::new();
        for (id, q) in &found {
            if let Some(f) = fit(&frame, q, &TagCells::tag36h11(*id)) {
                blur.push(format!("{:.2}", f.blur_px));
                assert!(f.rms_grey < 25.0, "{stem}: residual RMS {:.1}", f.rms_grey);
                fitted.push(f.corners);
            }
        }
        let quads: Vec<Quad> = found.iter().map(|(_, q)| *q).collect();
        let ours = offset(&differences(&quads, &fitted));
        let theirs = offset(&differences(&reference(stem), &fitted));
        let larger = outwards(&quads, &fitted);
        println!(
            "{stem}: {} tags fitted, blur σ {} px",
            fitted.len(),
            blur.join(" ")
        );
        println!(
            "  {}; corners {larger:+.3} px outwards",
            show("odocal − pattern fit", &ours)
        );
        println!(
            "  {}; corners {:+.3} px outwards",
            show("reference − pattern fit", &theirs),
            outwards(&reference(stem), &fitted)
        );
        assert!(
            fitted.len() + 1 >= found.len(),
            "{stem}: {} of {} fitted",
            fitted.len(),
            found.len()
        );
        assert!(
            ours.mean.x.abs() < 0.03 && ours.mean.y.abs() < 0.03,
            "{stem}: {}",
            show("odocal − pattern fit", &ours)
        );
        assert!(
            ours.rms.x < 0.3 && ours.rms.y < 0.3,
            "{stem}: {}",
            show("RMS", &ours)
        );
        assert!(
            larger.abs() < 0.15,
            "{stem}: odocal's corners {larger:+.3} px outwards"
        );
        assert!(
            theirs.mean.y < -0.05,
            "{stem}: {}",
            show("reference − pattern fit", &theirs)
        );
    }
}
