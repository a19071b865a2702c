//! The arena: every camera's footprint on the floor, where views overlap, and each robot's
//! fused poses coloured by the camera that weighed most in them, with the consistency of the
//! cameras, their clock offsets and the handoffs.

use std::path::Path;

use nalgebra::Point2;
use odocal_arena::{ArenaFile, ArenaTrackFile};

use super::*;

/// What the arena section shows.
#[derive(Debug, Clone, PartialEq)]
pub struct ArenaInput {
    /// The arena file from `odocal arena`.
    pub arena: ArenaFile,
    /// The tracking summary from `odocal track --arena --arena-report`, if any.
    pub track: Option<ArenaTrackFile>,
}

impl ArenaInput {
    /// Reads the arena file and, when given, the tracking summary.
    pub fn read(arena: &Path, track: Option<&Path>) -> Result<Self, ReportError> {
        let bad = |e: odocal_arena::ArenaError| ReportError::Mismatch(e.to_string());
        let input = Self {
            arena: ArenaFile::load(arena).map_err(bad)?,
            track: track.map(ArenaTrackFile::load).transpose().map_err(bad)?,
        };
        // A tracking of another arena shows its clock offsets and robots over this one's
        // cameras: refused by the arena file it recorded.
        if let (Some(tp), Some(sha)) = (
            track,
            input.track.as_ref().and_then(|t| t.arena_sha256.as_ref()),
        ) {
            let bytes = std::fs::read(arena).map_err(|e| {
                ReportError::Mismatch(format!("{}: cannot be read ({e})", arena.display()))
            })?;
            if odocal_core::sha256_hex(&bytes) != *sha {
                return Err(ReportError::Mismatch(format!(
                    "{}: tracked with another arena file than {} (its arena_sha256 {}…): give the --arena the tracking used, or the --arena-track of a tracking with this arena",
                    tp.display(),
                    arena.display(),
                    &sha[..sha.len().min(12)]
                )));
            }
        }
        // A tracking of another arena would list clock offsets of cameras this one lacks
        // beside its footprints.
        if let (Some(t), Some(tp)) = (&input.track, track) {
            let n = input.arena.cameras.len();
            let cameras = t
                .offsets
                .iter()
                .map(|o| o.camera)
                .chain(t.frame_rates.iter().map(|f| f.camera));
            if let Some(k) = cameras.filter(|&k| k >= n).max() {
                return Err(ReportError::Mismatch(format!(
                    "{}: tracked camera {k}, but {} has {n} cameras (0 to {}): give the --arena-track of a tracking with this arena",
                    tp.display(),
                    arena.display(),
                    n.saturating_sub(1)
                )));
            }
        }
        Ok(input)
    }
}

/// The floor outline of camera k's image: its border, pixel by pixel in steps, on the floor.
fn footprint(a: &ArenaFile, k: usize) -> Vec<(f64, f64)> {
    let c = &a.cameras[k];
    let cam = &c.calibration.camera;
    let (w, h) = (cam.width as f64 - 1.0, cam.height as f64 - 1.0);
    let n = 40;
    let mut border = Vec::new();
    for i in 0..n {
        border.push(Point2::new(w * i as f64 / n as f64, 0.0));
    }
    for i in 0..n {
        border.push(Point2::new(w, h * i as f64 / n as f64));
    }
    for i in 0..n {
        border.push(Point2::new(w * (1.0 - i as f64 / n as f64), h));
    }
    for i in 0..=n {
        border.push(Point2::new(0.0, h * (1.0 - i as f64 / n as f64)));
    }
    border
        .iter()
        .filter_map(|p| cam.pixel_to_floor(&c.arena_to_camera, p, 0.0))
        .map(|p| (p.x, p.y))
        .collect()
}

/// Whether camera k sees the floor point p.
fn sees(a: &ArenaFile, k: usize, p: Point2<f64>) -> bool {
    let c = &a.cameras[k];
    let cam = &c.calibration.camera;
    cam.floor_to_pixel(&c.arena_to_camera, &p, 0.0)
        .filter(|px| {
            px.x >= 0.0
                && px.y >= 0.0
                && px.x <= cam.width as f64 - 1.0
                && px.y <= cam.height as f64 - 1.0
        })
        // A polynomial lens folds far points back into the image: trust round trips only.
        .and_then(|px| cam.pixel_to_floor(&c.arena_to_camera, &px, 0.0))
        .is_some_and(|q| (q - p).norm() < 0.01)
}

/// The arena section.
pub fn arena_section(inp: &ArenaInput) -> Result<Section, ReportError> {
    let a = &inp.arena;
    let mut s = Section::new("arena", "Arena: several cameras, one floor frame");
    let c = &a.consistency;
    s.blocks.push(Block::Text(format!(
        "{} cameras tied into the first camera's floor frame by {} shared floor-board views. Where two cameras see the same floor point their floor coordinates differ by {:.2} mm RMS, {:.2} mm at most ({} corners).",
        a.cameras.len(),
        a.shared_views.len(),
        c.rms_mm,
        c.max_mm,
        c.points
    )));
    if let Some(f) = &a.frame_placement {
        let o = f.origin_sigma_m();
        s.blocks.push(Block::Text(format!(
            "The floor frame itself, located from the first camera's floor boards, is placed to a heading σ of {:.3} mrad and an origin σ of {:.2} mm (x) and {:.2} mm (y): one turn and shift of every fix alike, included in each fix's σ, which a run aligned to its odometry takes up.",
            f.heading_sigma_rad() * 1e3,
            o.x * 1e3,
            o.y * 1e3
        )));
    }
    let mut ch = Chart::new(
        "The arena from above",
        "x, floor frame (m)",
        "y, floor frame (m)",
    );
    ch.equal_aspect = true;
    ch.size_px = (820, 600);
    let outlines: Vec<Vec<(f64, f64)>> = (0..a.cameras.len()).map(|k| footprint(a, k)).collect();
    // Overlaps: a grid over the cameras' footprints, the points two or more cameras see.
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for (x, y) in outlines.iter().flatten() {
        x0 = x0.min(*x);
        y0 = y0.min(*y);
        x1 = x1.max(*x);
        y1 = y1.max(*y);
    }
    let mut overlap = Vec::new();
    if x1 > x0 && y1 > y0 {
        let step = ((x1 - x0).max(y1 - y0) / 120.0).max(0.01);
        let mut y = y0;
        while y <= y1 {
            let mut x = x0;
            while x <= x1 {
                let p = Point2::new(x, y);
                if (0..a.cameras.len()).filter(|k| sees(a, *k, p)).count() >= 2 {
                    overlap.push((x, y));
                }
                x += step;
            }
            y += step;
        }
    }
    if !overlap.is_empty() {
        ch.series.push(Series::new(
            "seen by two or more cameras",
            overlap,
            Mark::Dots,
            7,
        ));
    }
    for (k, o) in outlines.into_iter().enumerate() {
        ch.series.push(Series::new(
            &format!("camera {k}'s view"),
            o,
            Mark::Line,
            k % 6,
        ));
    }
    let mut thinned = Vec::new();
    if let Some(t) = &inp.track {
        for k in 0..a.cameras.len() {
            let pts: Vec<(f64, f64)> = t
                .robots
                .iter()
                .flat_map(|r| r.rows.iter())
                .filter(|row| row.camera == k)
                .map(|row| (row.x_m, row.y_m))
                .collect();
            if !pts.is_empty() {
                let (pts, every) = every_nth(pts, MAX_DRAWN);
                if let Some(e) = every {
                    thinned.push(format!("{e} poses camera {k} weighed most"));
                }
                ch.series.push(Series::new(
                    &format!("robot poses, camera {k} weighed most"),
                    pts,
                    Mark::Markers,
                    k % 6,
                ));
            }
        }
    }
    let drawn = if thinned.is_empty() {
        String::new()
    } else {
        format!(" Drawn: {}.", thinned.join("; "))
    };
    s.blocks.push(figure(
        "arena",
        &format!("Each camera's view of the floor (its image border on the floor, metres), the floor two or more cameras see (grey), and the robots' fused poses coloured by the camera that weighed most in each.{drawn}"),
        &ch,
    )?);
    s.blocks.push(Block::Table(Table {
        caption: "Agreement of each pair of cameras over the shared boards".into(),
        header: vec![
            "cameras".into(),
            "corners".into(),
            "RMS apart (mm)".into(),
            "max apart (mm)".into(),
        ],
        rows: a
            .pairs
            .iter()
            .map(|p| {
                vec![
                    format!("{} and {}", p.cameras.0, p.cameras.1),
                    p.consistency.points.to_string(),
                    format!("{:.2}", p.consistency.rms_mm),
                    format!("{:.2}", p.consistency.max_mm),
                ]
            })
            .collect(),
    }));
    match &inp.track {
        Some(t) => {
            s.blocks.push(Block::Table(Table {
                caption: "Clock offsets (t_arena = t_camera + offset), from robots seen by two cameras at once".into(),
                header: vec!["camera".into(), "offset (ms)".into(), "σ (ms)".into()],
                rows: t
                    .offsets
                    .iter()
                    .map(|o| {
                        vec![
                            o.camera.to_string(),
                            format!("{:+.3}", o.offset_s * 1e3),
                            format!("{:.3}", o.sigma_s * 1e3),
                        ]
                    })
                    .collect(),
            }));
            s.blocks.push(Block::Table(Table {
                caption: "Robots tracked across the cameras".into(),
                header: vec![
                    "tag".into(),
                    "fused poses".into(),
                    "handoffs".into(),
                    "largest jump at a handoff (mm)".into(),
                    "largest disagreement at a handoff (mm)".into(),
                ],
                rows: t
                    .robots
                    .iter()
                    .map(|r| {
                        let max = |f: fn(&odocal_arena::HandoffEntry) -> f64| {
                            r.handoffs.iter().map(f).fold(0.0, f64::max)
                        };
                        vec![
                            r.tag_id.to_string(),
                            r.rows.len().to_string(),
                            r.handoffs.len().to_string(),
                            format!("{:.3}", max(|h| h.jump_mm)),
                            format!("{:.2}", max(|h| h.disagreement_mm)),
                        ]
                    })
                    .collect(),
            }));
        }
        None => s.blocks.push(Block::Note(
            "No tracking summary given (--arena-track from `odocal track --arena --arena-report`): no robots drawn.".into(),
        )),
    }
    Ok(s)
}
