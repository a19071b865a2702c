//! Laser poses against the truth.

use super::*;

/// What the laser section shows.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserInput {
    /// Poses from `odocal lrf localize`.
    pub poses: Vec<odocal_lrf::PoseLogRow>,
    /// True sensor poses.
    pub truth: LaserTruth,
    /// Landmark positions of the map (x, y), metres.
    pub landmarks_m: Vec<(f64, f64)>,
}

/// A heading RMS against the truth beyond this (5°) beside positions within a few
/// centimetres: a correct pose is within 1°, so the truth's headings are suspect.
const TRUTH_HEADING_SUSPECT_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// Laser positioning: estimated sensor poses against the truth.
pub fn laser_section(l: &LaserInput) -> Result<Section, ReportError> {
    let mut s = Section::new("laser", "Laser positioning against the truth");
    let count = |st: &str| l.poses.iter().filter(|p| p.status.as_str() == st).count();
    let mut pos_err = Vec::new();
    let mut head_err = Vec::new();
    let mut err_series = Vec::new();
    // Times from the first scan: epoch times (1.7e9 s) would give every tick one label.
    let t0 = l.poses.first().map_or(0.0, |p| p.t_s);
    for p in &l.poses {
        if let (Some(e), Some(tp)) = (p.pose, l.truth.at(p.t_s)) {
            if p.status == odocal_lrf::Status::Ok {
                let d = (e.x_m - tp.pose.x_m).hypot(e.y_m - tp.pose.y_m);
                pos_err.push(d);
                head_err.push(wrap_angle(e.theta_rad - tp.pose.theta_rad));
                err_series.push((p.t_s - t0, 1000.0 * d));
            }
        }
    }
    let n_ok = count("ok");
    // With no ok scan against the truth there is no error to give: "RMS NaN mm (max 0.0 mm)"
    // read as a figure.
    let against = if !pos_err.is_empty() {
        format!(
            "Against the truth ({} ok scans with a true pose): position RMS {:.1} mm (max {:.1} mm), heading RMS {:.3} deg.",
            pos_err.len(),
            1000.0 * rms(&pos_err),
            1000.0 * pos_err.iter().fold(0.0f64, |m, e| m.max(*e)),
            rms(&head_err).to_degrees()
        )
    } else if l.truth.poses().is_empty() {
        "No truth given: no error figures.".to_string()
    } else if n_ok == 0 {
        "No scan is ok (ambiguous poses are not judged): no error against the truth.".to_string()
    } else {
        "No ok scan has a true pose at its time: no error against the truth.".to_string()
    };
    s.blocks.push(Block::Text(format!(
        "{} scans: {n_ok} ok, {} ambiguous, {} lost. {against}",
        l.poses.len(),
        count("ambiguous"),
        count("lost"),
    )));
    // Positions that agree with headings that do not: the truth's theta is in another unit
    // or convention, and the heading figure above judges the truth, not the poses.
    if !pos_err.is_empty()
        && rms(&pos_err) <= odocal_lrf::CORRECT_POS_M
        && rms(&head_err) > TRUTH_HEADING_SUSPECT_RAD
    {
        s.blocks.push(Block::Note(format!(
            "WARNING: the positions agree with the truth ({:.1} mm RMS) but the headings are {:.1}° RMS apart: is the truth's theta in radians (not degrees), counter-clockwise, and the scanner's own heading? The heading figure above is then no judgement of the poses.",
            1000.0 * rms(&pos_err),
            rms(&head_err).to_degrees()
        )));
    }
    let mut ch = Chart::new(
        "Laser sensor positions: estimate vs truth",
        "x, map frame (m)",
        "y, map frame (m)",
    );
    ch.equal_aspect = true;
    ch.size_px = (760, 560);
    // What was thinned, for the caption: a page of a million dots is a hundred megabytes
    // that no browser shows, and no eye tells from five thousand.
    let mut thinned = Vec::new();
    for (st, color) in [("ok", 0usize), ("ambiguous", 4usize)] {
        let pts: Vec<(f64, f64)> = l
            .poses
            .iter()
            .filter(|p| p.status.as_str() == st)
            .filter_map(|p| p.pose.map(|q| (q.x_m, q.y_m)))
            .collect();
        if !pts.is_empty() {
            let (pts, every) = every_nth(pts, MAX_DRAWN);
            if let Some(s) = every {
                thinned.push(format!("{s} {st} estimates"));
            }
            ch.series.push(Series::new(
                &format!("estimate ({st})"),
                pts,
                Mark::Dots,
                color,
            ));
        }
    }
    // The true path last, on top of the estimates.
    if !l.truth.poses().is_empty() {
        let path = l
            .truth
            .poses()
            .iter()
            .map(|p| (p.pose.x_m, p.pose.y_m))
            .collect();
        let (path, every) = every_nth(path, MAX_DRAWN);
        if let Some(s) = every {
            thinned.push(format!("the true path through {s} true poses"));
        }
        ch.series
            .push(Series::new("true path", path, Mark::Line, 6));
    }
    if !l.landmarks_m.is_empty() {
        ch.series.push(Series::new(
            "landmarks",
            l.landmarks_m.clone(),
            Mark::Markers,
            1,
        ));
    }
    if ch.n_points() > 0 {
        let drawn = if thinned.is_empty() {
            String::new()
        } else {
            format!(" Drawn: {}.", thinned.join("; "))
        };
        s.blocks.push(figure(
            "laser-poses",
            &format!("Sensor positions in the map frame (metres): the true path, the estimates by status, and the reflective landmarks.{drawn}"),
            &ch,
        )?);
    }
    if !err_series.is_empty() {
        let n = err_series.len();
        let (err_series, per) = largest_of_each(err_series, MAX_DRAWN);
        let drawn = match per {
            Some(k) => format!(
                " Drawn: the largest error of every {k} consecutive ok scans ({n} in all), so no spike is hidden; the figures above are over all of them."
            ),
            None => String::new(),
        };
        let ch = Chart::new(
            "Laser position error over time",
            "time since the first scan (s)",
            "position error (mm)",
        )
        .with(Series::new(
            "|estimate − truth| (ok scans)",
            err_series,
            Mark::Dots,
            0,
        ));
        s.blocks.push(figure(
            "laser-error",
            &format!(
                "Distance between estimated and true sensor position per ok scan (mm), against the time since the first scan (at t = {t0:.3} s).{drawn}"
            ),
            &ch,
        )?);
    } else {
        s.blocks.push(Block::Note(
            "No error plot: no ok scan with a true pose.".into(),
        ));
    }
    Ok(s)
}
