//! The calibration section: residuals per view and the corners' coverage of the image.

use super::*;

/// One calibration view.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibView {
    /// Image name.
    pub image: String,
    /// Reprojection RMS of the view, pixels (None when only the truth knows the view).
    pub rms_px: Option<f64>,
    /// Corner positions in the image, pixels (None = unknown).
    pub corners_px: Option<Vec<(f64, f64)>>,
}

/// What the calibration section shows.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibInput {
    /// Image width and height, pixels.
    pub image_size_px: (u32, u32),
    /// Overall reprojection RMS, pixels.
    pub rms_px: f64,
    /// The views used, in calibration order.
    pub views: Vec<CalibView>,
    /// Views left out by the calibration: (image, reason).
    pub skipped: Vec<(String, String)>,
    /// Where the corner positions come from (e.g. "synthetic truth"), if any.
    pub corners_source: Option<String>,
    /// Extra lines (intrinsics, comparison with the truth).
    pub facts: Vec<String>,
    /// Projection uncertainty of a camera-frame direction over the image, if the
    /// calibration's covariance is known.
    pub projection_sigma: Option<odocal_calib::UncertaintyMap>,
    /// Floor-position uncertainty over the image, if floor views were given.
    pub floor_sigma: Option<odocal_calib::FloorUncertaintyMap>,
}

/// Calibration: per-view residuals and the coverage of the image by corners.
pub fn calibration_section(c: &CalibInput) -> Result<Section, ReportError> {
    let mut s = Section::new("calibration", "Camera calibration");
    s.blocks.push(Block::Text(format!(
        "Zhang calibration from {} views ({} skipped): overall reprojection RMS {:.3} px; image {} × {} px.",
        c.views.len(),
        c.skipped.len(),
        c.rms_px,
        c.image_size_px.0,
        c.image_size_px.1
    )));
    for f in &c.facts {
        s.blocks.push(Block::Text(f.clone()));
    }
    let bars: Vec<(f64, f64)> = c
        .views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.rms_px.map(|r| ((i + 1) as f64, r)))
        .collect();
    if bars.is_empty() {
        s.blocks.push(Block::Note(
            "camera.json has no per-view residuals: no per-view plot.".into(),
        ));
    } else {
        let mut ch = Chart::new(
            "Reprojection RMS per calibration view",
            "view number (1 = first view)",
            "reprojection RMS (px)",
        )
        .with(Series::new("per-view RMS", bars, Mark::Bars, 0));
        let n = c.views.len() as f64;
        ch = ch.with(Series::new(
            &format!("overall RMS {:.3} px", c.rms_px),
            vec![(0.5, c.rms_px), (n + 0.5, c.rms_px)],
            Mark::Line,
            1,
        ));
        s.blocks.push(figure(
            "calib-residuals",
            "Reprojection RMS of each view after calibration (pixels). A view far above the others has badly detected corners or moved during exposure.",
            &ch,
        )?);
    }
    let (w, h) = (f64::from(c.image_size_px.0), f64::from(c.image_size_px.1));
    let with_corners: Vec<(usize, &Vec<(f64, f64)>)> = c
        .views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.corners_px.as_ref().map(|p| (i, p)))
        .collect();
    if with_corners.is_empty() || w <= 0.0 || h <= 0.0 {
        s.blocks.push(Block::Note(
            "Corner coverage is not shown: this camera.json has no corner positions (files from before odocal stored them); run odocal calibrate again to get them."
                .into(),
        ));
    } else {
        let (gx, gy) = (8usize, 6usize);
        let mut cells = vec![false; gx * gy];
        let mut ch = Chart::new(
            "Checkerboard corner coverage of the image",
            "image column u (px)",
            "image row v (px, down)",
        );
        ch.y_down = true;
        ch.equal_aspect = true;
        ch.x_range = Some((0.0, w));
        ch.y_range = Some((0.0, h));
        ch.size_px = (760, 500);
        for (i, pts) in &with_corners {
            for &(u, v) in pts.iter() {
                if (0.0..w).contains(&u) && (0.0..h).contains(&v) {
                    let cx = ((u / w) * gx as f64) as usize;
                    let cy = ((v / h) * gy as f64) as usize;
                    cells[cy.min(gy - 1) * gx + cx.min(gx - 1)] = true;
                }
            }
            ch.series
                .push(Series::new("", pts.to_vec(), Mark::Dots, *i));
        }
        ch.series.push(Series::new(
            "image border",
            vec![(0.0, 0.0), (w, 0.0), (w, h), (0.0, h), (0.0, 0.0)],
            Mark::Line,
            7,
        ));
        let covered = cells.iter().filter(|c| **c).count();
        s.blocks.push(figure(
            "calib-coverage",
            &format!(
                "Inner corners of all views in the image (one colour per view; {}). {} of {} cells of an {gx} × {gy} grid over the image hold corners ({:.0} %): corners near the border fix the distortion.",
                c.corners_source.as_deref().unwrap_or("detected corners"),
                covered,
                gx * gy,
                100.0 * covered as f64 / (gx * gy) as f64
            ),
            &ch,
        )?);
    }
    if let Some(m) = &c.projection_sigma {
        let cells = Cells {
            origin: (0.0, 0.0),
            cell: (f64::from(m.cell_px), f64::from(m.cell_px)),
            cols: m.cols as usize,
            values: m.sigma_px.iter().map(|v| Some(*v)).collect(),
            missing_label: String::new(),
            unit: "px".into(),
        };
        let median = m.median_px().unwrap_or(f64::NAN);
        s.blocks.push(figure(
            "calib-projection-uncertainty",
            &format!(
                "How uncertain the projection of a camera-frame direction is, over the image: one standard deviation along the worst image direction (pixels), from the intrinsics' covariance with the board poses marginalised out. Median {median:.3} px, largest {:.3} px. Large values where no corners were seen (compare the coverage plot) mean more views are needed there.",
                m.max_px()
            ),
            &image_heat_map("Projection uncertainty (1σ, px)", cells, (w, h), &[]),
        )?);
    }
    if let Some(m) = &c.floor_sigma {
        let cells = Cells {
            origin: (0.0, 0.0),
            cell: (f64::from(m.cell_px), f64::from(m.cell_px)),
            cols: m.cols as usize,
            values: m.sigma_mm.clone(),
            missing_label: "does not see the floor".into(),
            unit: "mm".into(),
        };
        let boards: Vec<Vec<(f64, f64)>> = m
            .floor_boards_px
            .iter()
            .map(|b| b.iter().map(|p| (p[0], p[1])).collect())
            .collect();
        let (median, max) = m.median_and_max_mm().unwrap_or((f64::NAN, f64::NAN));
        s.blocks.push(figure(
            "calib-floor-uncertainty",
            &format!(
                "How uncertain the floor position of what each part of the image sees is: one standard deviation along the worst floor direction (millimetres), from the intrinsics' covariance (which moves both the ray and the floor plane located with the same intrinsics) and the floor boards' corner noise. Grey: the ray is more than {:.0}° from straight down, so it does not see the floor. Orange dots: the floor boards' corners, where the floor plane was measured. Median {median:.3} mm, largest {max:.3} mm where the floor is seen.",
                odocal_calib::floor_uncertainty::FLOOR_SEEN_MAX_OFF_NADIR_DEG
            ),
            &image_heat_map("Floor position uncertainty (1σ, mm)", cells, (w, h), &boards),
        )?);
    }
    let mut t = Table {
        caption: "Calibration views".into(),
        header: vec![
            "view".into(),
            "image".into(),
            "reprojection RMS (px)".into(),
        ],
        rows: Vec::new(),
    };
    for (i, v) in c.views.iter().enumerate() {
        t.rows.push(vec![
            (i + 1).to_string(),
            v.image.clone(),
            v.rms_px.map_or("–".into(), |r| format!("{r:.3}")),
        ]);
    }
    for (img, why) in &c.skipped {
        t.rows
            .push(vec!["skipped".into(), img.clone(), why.clone()]);
    }
    s.blocks.push(Block::Table(t));
    Ok(s)
}

/// A heat map over the image (pixel coordinates, rows down) with the image border and `dots`.
fn image_heat_map(
    title: &str,
    cells: Cells,
    (w, h): (f64, f64),
    dots: &[Vec<(f64, f64)>],
) -> Chart {
    let mut ch = Chart::new(title, "image column u (px)", "image row v (px, down)");
    ch.y_down = true;
    ch.equal_aspect = true;
    ch.x_range = Some((0.0, w));
    ch.y_range = Some((0.0, h));
    ch.size_px = (760, 500);
    ch.cells = Some(cells);
    for (i, d) in dots.iter().enumerate() {
        let label = if i == 0 { "floor board corners" } else { "" };
        ch.series.push(Series::new(label, d.clone(), Mark::Dots, 1));
    }
    ch.series.push(Series::new(
        "",
        vec![(0.0, 0.0), (w, 0.0), (w, h), (0.0, h), (0.0, 0.0)],
        Mark::Line,
        7,
    ));
    ch
}

// ---------------------------------------------------------------- runs
