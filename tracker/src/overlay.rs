//! Overlay frames for a person to check: the detected quad, its first corner,
//! the heading and the quality drawn on the frame.

use std::path::Path;

use opencv::core::{Mat, Point, Scalar, Vector};
use opencv::{imgcodecs, imgproc};

use crate::source::Frame;
use crate::track::{FrameRecord, Outcome};
use crate::TrackError;

/// File name of the overlay of frame `index`.
pub fn overlay_name(index: usize) -> String {
    format!("overlay_{index:06}.png")
}

/// Draws the record of `frame` and writes it as `dir/overlay_NNNNNN.png`.
pub fn write_overlay(dir: &Path, frame: &Frame, record: &FrameRecord) -> Result<(), TrackError> {
    let grey = frame.image.to_mat()?;
    let mut img = Mat::default();
    imgproc::cvt_color(&grey, &mut img, imgproc::COLOR_GRAY2BGR, 0)?;
    let green = Scalar::new(0.0, 220.0, 0.0, 0.0);
    let red = Scalar::new(0.0, 0.0, 255.0, 0.0);
    let text = match &record.outcome {
        Outcome::Fix(f) => {
            let pts: Vec<Point> = f
                .corners_px
                .iter()
                .map(|p| Point::new(p.x.round() as i32, p.y.round() as i32))
                .collect();
            let mut poly = Vector::<Vector<Point>>::new();
            poly.push(Vector::from_slice(&pts));
            imgproc::polylines(&mut img, &poly, true, green, 1, imgproc::LINE_AA, 0)?;
            imgproc::circle(&mut img, pts[0], 3, red, 1, imgproc::LINE_AA, 0)?;
            // Heading: from the centre towards the middle of the right edge (corners 1, 2).
            let c = (pts[0] + pts[1] + pts[2] + pts[3]) / 4;
            let r = (pts[1] + pts[2]) / 2;
            imgproc::arrowed_line(
                &mut img,
                c,
                c + (r - c) * 2,
                green,
                1,
                imgproc::LINE_AA,
                0,
                0.2,
            )?;
            format!(
                "#{} t={:.3}s x={:.4} y={:.4} th={:.2}deg q={:.3}{}",
                record.index,
                record.t_s,
                f.pose.x_m,
                f.pose.y_m,
                f.pose.theta_rad.to_degrees(),
                f.quality,
                if f.from_roi { " roi" } else { " full" }
            )
        }
        Outcome::Gap(reason) => format!(
            "#{} t={:.3}s GAP: {}",
            record.index,
            record.t_s,
            reason.as_str()
        ),
    };
    let colour = if matches!(record.outcome, Outcome::Fix(_)) {
        green
    } else {
        red
    };
    imgproc::put_text(
        &mut img,
        &text,
        Point::new(10, 24),
        imgproc::FONT_HERSHEY_SIMPLEX,
        0.6,
        colour,
        1,
        imgproc::LINE_AA,
        false,
    )?;
    let path = dir.join(overlay_name(record.index));
    let ok = imgcodecs::imwrite(&path, &img, &Vector::new())?;
    if !ok {
        return Err(TrackError::io(&path, "cannot write the overlay image"));
    }
    Ok(())
}
