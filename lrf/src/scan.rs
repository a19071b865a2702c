//! Laser scans (CSV `angle,range,intensity`, optionally `scan,t`) and their
//! clustering into reflector detections.

use std::path::Path;

use nalgebra::{Matrix2, Point2, Vector2};

use crate::LrfError;

/// Sensor model: Hokuyo URG-like defaults (240°, 0.352° steps, 20 mm–5.6 m, 10 Hz).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorConfig {
    /// Total field of view, radians (centred on the sensor's x axis).
    pub fov_rad: f64,
    /// Angular step between beams, radians.
    pub step_rad: f64,
    /// Minimum valid range, metres.
    pub min_range_m: f64,
    /// Maximum valid range, metres.
    pub max_range_m: f64,
    /// Scan rate, Hz (times of scans without a `t` column).
    pub rate_hz: f64,
    /// Range noise (1 sigma) per beam, metres.
    pub sigma_range_m: f64,
    /// Bearing noise (1 sigma) per beam, radians.
    pub sigma_angle_rad: f64,
    /// Returns at or above this intensity are reflector candidates.
    pub intensity_min: f64,
}

/// The latest scan time accepted, seconds from the start of the recording (a month).
pub const MAX_SCAN_TIME_S: f64 = 3.0e6;

impl SensorConfig {
    /// Checks every setting for physical sense; the message names the option to fix.
    pub fn check(&self) -> Result<(), LrfError> {
        let bad = |m: String| Err(LrfError::Config(m));
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !(pos(self.fov_rad) && self.fov_rad <= std::f64::consts::TAU) {
            return bad(format!(
                "--fov-deg {}: need 0 < fov <= 360 degrees",
                self.fov_rad.to_degrees()
            ));
        }
        if !(pos(self.max_range_m) && self.max_range_m <= 1000.0) {
            return bad(format!(
                "--max-range-m {}: need a range in (0, 1000] metres",
                self.max_range_m
            ));
        }
        if !(pos(self.sigma_range_m) && self.sigma_range_m < 1.0) {
            return bad(format!(
                "--sigma-range-m {}: need a noise in (0, 1) metres",
                self.sigma_range_m
            ));
        }
        if !(pos(self.rate_hz) && self.rate_hz <= 1000.0) {
            return bad(format!(
                "--rate-hz {}: need a scan rate in (0, 1000] Hz",
                self.rate_hz
            ));
        }
        if !self.intensity_min.is_finite() {
            return bad(format!(
                "--intensity-min {}: need a finite intensity",
                self.intensity_min
            ));
        }
        if !(pos(self.step_rad) && self.step_rad < self.fov_rad) {
            return bad(format!(
                "the scans' angle step {} rad is not a scanner's",
                self.step_rad
            ));
        }
        Ok(())
    }
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            fov_rad: 240f64.to_radians(),
            step_rad: 360f64.to_radians() / 1024.0,
            min_range_m: 0.02,
            max_range_m: 5.6,
            rate_hz: 10.0,
            sigma_range_m: 0.01,
            sigma_angle_rad: 0.0002,
            intensity_min: 0.5,
        }
    }
}

/// One sweep of the scanner, beams ordered right to left (increasing angle).
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// Scan id (from the `scan` column, else the file's index).
    pub id: u64,
    /// Time stamp, seconds (from the `t` column if present).
    pub t_s: Option<f64>,
    /// Beam angles in the sensor frame, radians, evenly spaced and increasing.
    pub angles_rad: Vec<f64>,
    /// Ranges, metres; 0 (or below the minimum range) means no return.
    pub ranges_m: Vec<f64>,
    /// Return intensities (reflectors ≥ [`SensorConfig::intensity_min`]).
    pub intensities: Vec<f64>,
}

impl Scan {
    /// The angular step of the scan, radians (0 for fewer than two beams).
    pub fn step_rad(&self) -> f64 {
        if self.angles_rad.len() < 2 {
            0.0
        } else {
            (self.angles_rad[self.angles_rad.len() - 1] - self.angles_rad[0])
                / (self.angles_rad.len() - 1) as f64
        }
    }

    /// The index of the beam nearest to `angle_rad`, if inside the scan.
    pub fn beam_at(&self, angle_rad: f64) -> Option<usize> {
        let n = self.angles_rad.len();
        let step = self.step_rad();
        if n < 2 || step <= 0.0 {
            return None;
        }
        let k = ((angle_rad - self.angles_rad[0]) / step).round();
        if k < 0.0 || k >= n as f64 {
            None
        } else {
            Some(k as usize)
        }
    }
}

/// A cluster of high-intensity returns: one reflector candidate, in the sensor frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Centre of the cluster in the sensor frame, metres.
    pub point: Point2<f64>,
    /// Range of the centre, metres.
    pub range_m: f64,
    /// Bearing of the centre, radians.
    pub bearing_rad: f64,
    /// Number of beams in the cluster.
    pub n_beams: usize,
    /// Apparent width (chord plus one beam spacing), metres.
    pub width_m: f64,
    /// Variance of the centre along the beam, m².
    pub var_radial_m2: f64,
    /// Variance of the centre across the beam, m².
    pub var_tangential_m2: f64,
}

impl Detection {
    /// Covariance of the centre in the sensor frame, m².
    pub fn cov(&self) -> Matrix2<f64> {
        let (s, c) = self.bearing_rad.sin_cos();
        let u = Vector2::new(c, s);
        let v = Vector2::new(-s, c);
        u * u.transpose() * self.var_radial_m2 + v * v.transpose() * self.var_tangential_m2
    }
}

/// Clusters consecutive high-intensity returns into detections L1..Ln, right
/// to left, rejecting clusters much wider than a reflector of `reflector_width_m`.
pub fn extract_detections(
    scan: &Scan,
    cfg: &SensorConfig,
    reflector_width_m: f64,
) -> Vec<Detection> {
    let step = scan.step_rad().abs().max(1e-6);
    let mut out = Vec::new();
    let n = scan.ranges_m.len();
    let ok = |i: usize| {
        let r = scan.ranges_m[i];
        r >= cfg.min_range_m && r <= cfg.max_range_m && scan.intensities[i] >= cfg.intensity_min
    };
    let mut i = 0;
    while i < n {
        if !ok(i) {
            i += 1;
            continue;
        }
        let mut j = i + 1;
        while j < n && ok(j) && (scan.ranges_m[j] - scan.ranges_m[j - 1]).abs() <= 0.1 {
            j += 1;
        }
        let pts: Vec<Point2<f64>> = (i..j)
            .map(|k| {
                let (s, c) = scan.angles_rad[k].sin_cos();
                Point2::new(scan.ranges_m[k] * c, scan.ranges_m[k] * s)
            })
            .collect();
        let k = pts.len() as f64;
        let centre = Point2::from(pts.iter().map(|p| p.coords).sum::<Vector2<f64>>() / k);
        let range_m = centre.coords.norm();
        let spacing = range_m * step;
        let chord = (pts[pts.len() - 1] - pts[0]).norm();
        let limit = reflector_width_m + 2.0 * spacing + 4.0 * cfg.sigma_range_m;
        if chord <= limit {
            out.push(Detection {
                point: centre,
                range_m,
                bearing_rad: centre.y.atan2(centre.x),
                n_beams: pts.len(),
                width_m: chord + spacing,
                var_radial_m2: cfg.sigma_range_m.powi(2) / k + 1e-6,
                var_tangential_m2: (range_m * cfg.sigma_angle_rad).powi(2)
                    + spacing * spacing / 3.0
                    + 1e-6,
            });
        }
        i = j;
    }
    out
}

/// Reads a scan CSV file (see [`parse_scans_csv`]).
pub fn read_scans_csv(path: &Path) -> Result<Vec<Scan>, LrfError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| LrfError::Io {
        path: name.clone(),
        source,
    })?;
    parse_scans_csv(&text, &name)
}

/// Parses scans from CSV with header `angle,range,intensity` (radians, metres,
/// unitless), optionally with `scan` (id) and `t` (seconds) columns; rows of
/// one scan must be contiguous. Rejects NaN or negative values and unevenly
/// spaced angles with the line and column at fault.
pub fn parse_scans_csv(text: &str, name: &str) -> Result<Vec<Scan>, LrfError> {
    let err = |line: usize, column: &str, message: String| LrfError::Scan {
        path: name.to_string(),
        line,
        column: column.to_string(),
        message,
    };
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let headers = rdr
        .headers()
        .map_err(|e| err(1, "-", format!("cannot read the header: {e}")))?
        .clone();
    let col = |n: &str| headers.iter().position(|h| h == n);
    let (Some(ca), Some(cr), Some(ci)) = (col("angle"), col("range"), col("intensity")) else {
        return Err(err(
            1,
            "-",
            format!(
                "header is \"{}\"; a scan file needs the columns angle,range,intensity (optionally scan,t)",
                headers.iter().collect::<Vec<_>>().join(",")
            ),
        ));
    };
    let (cs, ct) = (col("scan"), col("t"));
    let mut scans: Vec<Scan> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    let mut first_line = 0usize;
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            let line = e.position().map(|p| p.line() as usize).unwrap_or(0);
            err(line, "-", format!("malformed CSV row: {e}"))
        })?;
        let line = rec.position().map(|p| p.line() as usize).unwrap_or(0);
        let num = |c: usize, cname: &str| -> Result<f64, LrfError> {
            let s = rec.get(c).unwrap_or("");
            s.parse::<f64>()
                .map_err(|_| err(line, cname, format!("\"{s}\" is not a number")))
        };
        let angle = num(ca, "angle")?;
        let range = num(cr, "range")?;
        let intensity = num(ci, "intensity")?;
        if !angle.is_finite() {
            return Err(err(
                line,
                "angle",
                format!("angle is {angle}; give a finite angle in radians"),
            ));
        }
        if range.is_nan() || range < 0.0 {
            return Err(err(
                line,
                "range",
                format!("range is {range}; ranges must be ≥ 0 metres (use 0 for \"no return\")"),
            ));
        }
        if intensity.is_nan() || intensity < 0.0 {
            return Err(err(
                line,
                "intensity",
                format!("intensity is {intensity}; it must be ≥ 0"),
            ));
        }
        let id = match cs {
            Some(c) => {
                let s = rec.get(c).unwrap_or("");
                s.parse::<u64>().map_err(|_| {
                    err(
                        line,
                        "scan",
                        format!("scan id \"{s}\" is not a non-negative integer"),
                    )
                })?
            }
            None => 0,
        };
        let t = match ct {
            Some(c) => {
                let t = num(c, "t")?;
                if !(t.is_finite() && (0.0..=MAX_SCAN_TIME_S).contains(&t)) {
                    return Err(err(
                        line,
                        "t",
                        format!("time {t} s is not a scan time (0 to {MAX_SCAN_TIME_S:.0} s)"),
                    ));
                }
                Some(t)
            }
            None => None,
        };
        let new_scan = scans.last().is_none_or(|s| s.id != id);
        if let (true, Some(t), Some(prev)) = (new_scan, t, scans.last().and_then(|s| s.t_s)) {
            if t <= prev {
                return Err(err(
                    line,
                    "t",
                    format!("scan time {t} s does not come after the previous scan's {prev} s; scans must be in time order"),
                ));
            }
        }
        if new_scan {
            if let Some(prev) = scans.last() {
                check_steps(prev, name, first_line, scans.first().map(|s| s.step_rad()))?;
            }
            if !seen.insert(id) {
                return Err(err(
                    line,
                    "scan",
                    format!("scan {id} appears again after another scan; keep each scan's rows together"),
                ));
            }
            scans.push(Scan {
                id,
                t_s: t,
                angles_rad: Vec::new(),
                ranges_m: Vec::new(),
                intensities: Vec::new(),
            });
            first_line = line;
        }
        if let Some(s) = scans.last_mut() {
            s.angles_rad.push(angle);
            s.ranges_m.push(range);
            s.intensities.push(intensity);
        }
    }
    if let Some(last) = scans.last() {
        let first_step = if scans.len() > 1 {
            Some(scans[0].step_rad())
        } else {
            None
        };
        check_steps(last, name, first_line, first_step)?;
    } else {
        return Err(err(
            2,
            "-",
            "no scan rows; the file has only a header".into(),
        ));
    }
    Ok(scans)
}

/// Checks that a scan's angles increase by one even step (and match `expected` if given).
fn check_steps(
    s: &Scan,
    name: &str,
    first_line: usize,
    expected: Option<f64>,
) -> Result<(), LrfError> {
    let err = |line: usize, message: String| LrfError::Scan {
        path: name.to_string(),
        line,
        column: "angle".into(),
        message,
    };
    if s.angles_rad.len() < 2 {
        return Err(err(
            first_line,
            format!("scan {} has fewer than 2 beams", s.id),
        ));
    }
    let step0 = s.angles_rad[1] - s.angles_rad[0];
    if step0 <= 0.0 {
        return Err(err(
            first_line + 1,
            format!("angles must increase (right to left); step is {step0:.6} rad"),
        ));
    }
    for k in 1..s.angles_rad.len() {
        let d = s.angles_rad[k] - s.angles_rad[k - 1];
        if (d - step0).abs() > 0.05 * step0 {
            return Err(err(
                first_line + k,
                format!(
                    "mismatched angle step {d:.6} rad (this scan's step is {step0:.6} rad); beams must be evenly spaced"
                ),
            ));
        }
    }
    if let Some(e) = expected {
        if (s.step_rad() - e).abs() > 0.01 * e.abs() {
            return Err(err(
                first_line,
                format!(
                    "scan {} has angle step {:.6} rad but earlier scans have {e:.6} rad; use one sensor setting per file",
                    s.id,
                    s.step_rad()
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_multi_scan_file_and_clusters() {
        let mut text = String::from("scan,t,angle,range,intensity\n");
        for s in 0..2 {
            for k in 0..100 {
                let a = -0.5 + k as f64 * 0.01;
                let hit = (40..44).contains(&k);
                let (r, i) = if hit { (2.0, 0.9) } else { (3.0, 0.1) };
                text.push_str(&format!("{s},{},{a:.6},{r},{i}\n", s as f64 * 0.1));
            }
        }
        let scans = parse_scans_csv(&text, "x.csv").unwrap();
        assert_eq!(scans.len(), 2);
        assert_eq!(scans[1].t_s, Some(0.1));
        let cfg = SensorConfig::default();
        let d = extract_detections(&scans[0], &cfg, 0.08);
        assert_eq!(d.len(), 1);
        assert_eq!(d[0].n_beams, 4);
        assert!((d[0].bearing_rad - (-0.5 + 0.415)).abs() < 1e-3);
        // A 30-beam shiny stretch is far wider than a reflector: rejected.
        let mut wide = scans[0].clone();
        for k in 60..90 {
            wide.intensities[k] = 0.9;
        }
        assert_eq!(extract_detections(&wide, &cfg, 0.08).len(), 1);
    }

    #[test]
    fn rejects_bad_values_with_position() {
        let e = parse_scans_csv(
            "angle,range,intensity\n0.0,1.0,0.1\n0.01,NaN,0.1\n",
            "s.csv",
        )
        .unwrap_err();
        assert!(
            e.to_string().starts_with("s.csv, line 3, column range"),
            "{e}"
        );
        let e = parse_scans_csv("angle,range,intensity\n0.0,1.0,0.1\n0.01,-1,0.1\n", "s.csv")
            .unwrap_err();
        assert!(e.to_string().contains("≥ 0"), "{e}");
        let e = parse_scans_csv(
            "angle,range,intensity\n0.0,1,0\n0.01,1,0\n0.03,1,0\n",
            "s.csv",
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("line 4, column angle: mismatched angle step"),
            "{e}"
        );
        let e = parse_scans_csv("angle,rng\n", "s.csv").unwrap_err();
        assert!(e.to_string().contains("angle,range,intensity"), "{e}");
    }
}
