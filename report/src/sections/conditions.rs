//! How good the camera's poses are: the tracking-conditions section (how the tracker fares on
//! video as real cameras record it — motion blur, rolling shutter, dim light, noise,
//! compression — each condition measured against synthetic truth, with AprilTag 3's own
//! detection rate on the same frames, and how honest each fix's σ is there: the RMS of
//! error/σ, 1 when σ is right), and the target-uncertainty section (each run's target σ in
//! dataset.json, carried from the per-pose σ of the trajectories).

use super::*;

/// One measured condition.
#[derive(Debug, Clone, PartialEq)]
pub struct ConditionRow {
    /// What the frames went through (e.g. "9 px motion blur").
    pub condition: String,
    /// Frames in the condition.
    pub frames: usize,
    /// Frames with a fix.
    pub fixes: usize,
    /// Position RMS error of the fixes, metres.
    pub position_rms_m: f64,
    /// Largest position error, metres.
    pub position_max_m: f64,
    /// Heading RMS error, radians.
    pub heading_rms_rad: f64,
    /// RMS of error/σ over x and y.
    pub normalised_xy: f64,
    /// RMS of error/σ of the heading.
    pub normalised_theta: f64,
    /// Fraction of frames where AprilTag 3 alone (decimation 2, defaults) finds the tag.
    pub apriltag3_rate: Option<f64>,
    /// What `odocal track` warned of in this condition.
    pub warnings: Vec<String>,
}

/// error/σ with two decimals; "–" when the fixes had no σ.
fn normalised(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2}")
    } else {
        "–".into()
    }
}

/// A table of the conditions, one row each.
pub fn conditions_section(rows: &[ConditionRow]) -> Result<Section, ReportError> {
    if rows.is_empty() {
        return Err(ReportError::Mismatch(
            "the tracking-conditions section needs at least one measured condition".into(),
        ));
    }
    let mut s = Section::new("conditions", "Tracking under real-camera conditions");
    s.blocks.push(Block::Text(
        "Each condition is rendered from a known camera and drive and tracked; the errors are against the truth. \
         error/σ is each fix's error divided by its own σ: an RMS near 1 means the error bars are right."
            .into(),
    ));
    s.blocks.push(Block::Table(Table {
        caption: "Tracked frames, accuracy and error bars per condition".into(),
        header: [
            "condition",
            "tracked %",
            "position RMS (mm)",
            "position max (mm)",
            "heading RMS (°)",
            "error/σ RMS x,y",
            "error/σ RMS θ",
            "AprilTag 3 detects %",
        ]
        .map(String::from)
        .to_vec(),
        rows: rows
            .iter()
            .map(|r| {
                vec![
                    r.condition.clone(),
                    format!(
                        "{:.1} ({}/{})",
                        100.0 * r.fixes as f64 / r.frames.max(1) as f64,
                        r.fixes,
                        r.frames
                    ),
                    format!("{:.2}", r.position_rms_m * 1e3),
                    format!("{:.2}", r.position_max_m * 1e3),
                    format!("{:.3}", r.heading_rms_rad.to_degrees()),
                    normalised(r.normalised_xy),
                    normalised(r.normalised_theta),
                    r.apriltag3_rate
                        .map_or("–".into(), |a| format!("{:.1}", 100.0 * a)),
                ]
            })
            .collect(),
    }));
    for r in rows {
        for w in &r.warnings {
            s.blocks
                .push(Block::Text(format!("{}: warning: {w}", r.condition)));
        }
    }
    Ok(s)
}

/// The σ of each run's target (dataset.json's `target_sigma_m`, `target_sigma_theta_rad`),
/// or `None` when no sample has one (trajectories without σ).
pub fn target_sigma_section(samples: &[Sample]) -> Option<Section> {
    let with: Vec<&Sample> = samples
        .iter()
        .filter(|s| s.target_sigma_m.is_some())
        .collect();
    if with.is_empty() {
        return None;
    }
    let mut s = Section::new("target-sigma", "Target uncertainty");
    let mut pos: Vec<f64> = with
        .iter()
        .filter_map(|x| x.target_sigma_m)
        .map(|[a, b]| a.hypot(b) * 1e3)
        .collect();
    pos.sort_by(f64::total_cmp);
    s.blocks.push(Block::Text(format!(
        "{} of {} runs carry the camera's σ on their target (the σ of each fix averaged over the rest frames at both ends): median position σ {:.3} mm, largest {:.3} mm.",
        with.len(),
        samples.len(),
        pos[pos.len() / 2],
        pos[pos.len() - 1]
    )));
    s.blocks.push(Block::Table(Table {
        caption: "Target σ per run (start frame of the run)".into(),
        header: ["run", "σ x (mm)", "σ y (mm)", "σ θ (°)"]
            .map(String::from)
            .to_vec(),
        rows: with
            .iter()
            .map(|x| {
                let [a, b] = x.target_sigma_m.unwrap_or([f64::NAN; 2]);
                vec![
                    x.run_id.clone(),
                    format!("{:.3}", a * 1e3),
                    format!("{:.3}", b * 1e3),
                    x.target_sigma_theta_rad
                        .map_or("–".into(), |t| format!("{:.4}", t.to_degrees())),
                ]
            })
            .collect(),
    }));
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_sigma_only_when_samples_have_it() {
        let mut a = Sample {
            run_id: "run001".into(),
            ..Sample::default()
        };
        assert!(target_sigma_section(std::slice::from_ref(&a)).is_none());
        a.target_sigma_m = Some([0.0003, 0.0004]);
        a.target_sigma_theta_rad = Some(0.001);
        let s = target_sigma_section(&[a]).unwrap();
        let Some(Block::Table(t)) = s.blocks.last() else {
            panic!("no table")
        };
        assert_eq!(t.rows[0], vec!["run001", "0.300", "0.400", "0.0573"]);
        let Some(Block::Text(text)) = s.blocks.first() else {
            panic!("no text")
        };
        assert!(text.contains("median position σ 0.500 mm"), "{text}");
    }

    #[test]
    fn one_row_per_condition_and_none_is_refused() {
        let row = ConditionRow {
            condition: "9 px motion blur".into(),
            frames: 90,
            fixes: 90,
            position_rms_m: 0.000493,
            position_max_m: 0.0025,
            heading_rms_rad: 0.364f64.to_radians(),
            normalised_xy: 1.11,
            normalised_theta: 1.10,
            apriltag3_rate: Some(0.056),
            warnings: vec![],
        };
        let s = conditions_section(std::slice::from_ref(&row)).unwrap();
        let Some(Block::Table(t)) = s.blocks.last() else {
            panic!("no table")
        };
        assert_eq!(t.rows.len(), 1);
        assert_eq!(t.rows[0][1], "100.0 (90/90)");
        assert_eq!(t.rows[0][7], "5.6");
        assert!(conditions_section(&[]).is_err());
        // A condition's warnings follow the table, named by the condition.
        let warned = ConditionRow {
            warnings: vec!["the tags are sheared".into()],
            ..row
        };
        let s = conditions_section(&[warned]).unwrap();
        let Some(Block::Text(w)) = s.blocks.last() else {
            panic!("no warning")
        };
        assert_eq!(w, "9 px motion blur: warning: the tags are sheared");
    }
}
