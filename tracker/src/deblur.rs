//! Undoing motion blur along a known direction before detection.
//!
//! A robot that moves during the exposure smears the tag along its image motion: the
//! black-and-white cells of the code (four to five pixels each on a 35-pixel tag) run into
//! each other and the detector no longer finds the quad or cannot read its bits. The smear is
//! a line of known direction (the track's motion) and a length to be tried, so it is undone by
//! Wiener deconvolution with that line (OpenCV's DFT), in the region of interest only; the
//! detector then works on the restored image and the corners are refitted on the original
//! (the edge refit models a blurred edge, whose centre does not move).

use nalgebra::Vector2;
use opencv::core::{self, Mat, Point, Scalar, Vector, CV_32F, CV_8U};
use opencv::imgproc;
use opencv::prelude::*;

use crate::detect::Roi;
use crate::source::GrayFrame;
use crate::TrackError;

/// A line kernel of `len_px` along the unit vector `dir`, drawn anti-aliased, summing to 1.
fn line_kernel(dir: Vector2<f64>, len_px: f64) -> Result<Mat, TrackError> {
    let k = (len_px.ceil() as i32 + 2) | 1;
    let mut kernel = Mat::zeros(k, k, CV_32F)?.to_mat()?;
    let c = (k / 2) as f64;
    let half = dir * (len_px - 1.0).max(0.0) / 2.0;
    let shift = 8;
    let s = f64::from(1 << shift);
    let p0 = Point::new(
        ((c - half.x) * s).round() as i32,
        ((c - half.y) * s).round() as i32,
    );
    let p1 = Point::new(
        ((c + half.x) * s).round() as i32,
        ((c + half.y) * s).round() as i32,
    );
    imgproc::line(
        &mut kernel,
        p0,
        p1,
        Scalar::all(1.0),
        1,
        imgproc::LINE_AA,
        shift,
    )?;
    let sum = core::sum_elems(&kernel)?[0];
    let mut out = Mat::default();
    kernel.convert_to(&mut out, CV_32F, 1.0 / sum.max(1e-9), 0.0)?;
    Ok(out)
}

/// The region `roi` of `frame` with a motion blur of `len_px` along `dir` undone: a grey image
/// of the ROI's size (its pixel (0, 0) is the frame's (roi.x0, roi.y0)). `nsr` is the Wiener
/// filter's noise-to-signal ratio (larger: smoother, less ringing, less sharpening).
pub(crate) fn deblur_roi(
    frame: &GrayFrame,
    roi: Roi,
    dir: Vector2<f64>,
    len_px: f64,
    nsr: f64,
) -> Result<GrayFrame, TrackError> {
    let full = frame.to_mat()?;
    let rect = core::Rect::new(
        roi.x0 as i32,
        roi.y0 as i32,
        roi.width as i32,
        roi.height as i32,
    );
    let crop = Mat::roi(&full, rect)?;
    let kernel = line_kernel(dir, len_px)?;
    // Padding by reflection keeps the DFT's wrap-around away from the tag.
    let pad = kernel.rows();
    let w = core::get_optimal_dft_size(roi.width as i32 + 2 * pad)?;
    let h = core::get_optimal_dft_size(roi.height as i32 + 2 * pad)?;
    let mut padded8 = Mat::default();
    core::copy_make_border(
        &crop,
        &mut padded8,
        pad,
        h - roi.height as i32 - pad,
        pad,
        w - roi.width as i32 - pad,
        core::BORDER_REFLECT,
        Scalar::all(0.0),
    )?;
    let mut img = Mat::default();
    padded8.convert_to(&mut img, CV_32F, 1.0, 0.0)?;
    // The kernel centred on the origin, wrapped around.
    let mut psf = Mat::zeros(h, w, CV_32F)?.to_mat()?;
    let c = kernel.rows() / 2;
    for y in 0..kernel.rows() {
        for x in 0..kernel.cols() {
            let v = *kernel.at_2d::<f32>(y, x)?;
            if v != 0.0 {
                *psf.at_2d_mut::<f32>((y - c).rem_euclid(h), (x - c).rem_euclid(w))? = v;
            }
        }
    }
    let (mut gi, mut hk) = (Mat::default(), Mat::default());
    core::dft(&img, &mut gi, core::DFT_COMPLEX_OUTPUT, 0)?;
    core::dft(&psf, &mut hk, core::DFT_COMPLEX_OUTPUT, 0)?;
    let (mut num, mut power) = (Mat::default(), Mat::default());
    core::mul_spectrums(&gi, &hk, &mut num, 0, true)?;
    core::mul_spectrums(&hk, &hk, &mut power, 0, true)?;
    let mut parts = Vector::<Mat>::new();
    core::split(&power, &mut parts)?;
    let mut denom = Mat::default();
    core::add(
        &parts.get(0)?,
        &Scalar::all(nsr),
        &mut denom,
        &core::no_array(),
        -1,
    )?;
    let mut num_parts = Vector::<Mat>::new();
    core::split(&num, &mut num_parts)?;
    let mut out_parts = Vector::<Mat>::new();
    for i in 0..2 {
        let mut q = Mat::default();
        core::divide2(&num_parts.get(i)?, &denom, &mut q, 1.0, -1)?;
        out_parts.push(q);
    }
    let mut f = Mat::default();
    core::merge(&out_parts, &mut f)?;
    let mut restored = Mat::default();
    core::idft(
        &f,
        &mut restored,
        core::DFT_SCALE | core::DFT_REAL_OUTPUT,
        0,
    )?;
    let inner = Mat::roi(
        &restored,
        core::Rect::new(pad, pad, roi.width as i32, roi.height as i32),
    )?;
    let mut out8 = Mat::default();
    inner.convert_to(&mut out8, CV_8U, 1.0, 0.0)?;
    GrayFrame::from_mat(&out8)
}
